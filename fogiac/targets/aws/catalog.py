"""The checked-in catalogue of EC2 instance types fogiac knows, and the Client VPN's prices.

The table (``data/instance_types.json``) names its sources and dates; its format, reader and the
machine choice over it are provider-neutral (:mod:`fogiac.catalogue`), so ``validate`` checks
machine names without loading this target. What only AWS has, the Client VPN's hourly prices
(association and connection), is read here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from fogiac.catalogue import Catalog, InstanceType, raw
from fogiac.targets.aws.manifest import CLOUD as AWS

__all__ = ["AwsCatalog", "InstanceType", "catalog"]


@dataclass(frozen=True)
class AwsCatalog(Catalog):
    vpn_association_usd_per_hour: float = 0.0
    vpn_connection_usd_per_hour: float = 0.0


@cache
def catalog() -> AwsCatalog:
    vpn = raw(AWS.resource)["client_vpn_usd_per_hour"]
    return AwsCatalog(**vars(AWS.catalog), vpn_association_usd_per_hour=vpn["association"],
                      vpn_connection_usd_per_hour=vpn["connection"])
