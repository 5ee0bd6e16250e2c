"""The catalogue's words as the aws target's lifecycle and reports use them: price sources and the
Client VPN's hourly prices.

The facts themselves are :mod:`.catalogue`'s (read lazily by :data:`.manifest.CLOUD`); this is the
summary a status line, a cost note or the README's cost table names, and the per-(type, region)
prices the lifecycle charges a running instance at.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from fogiac.targets.aws.catalogue import Catalogue
from fogiac.targets.aws.manifest import CLOUD as AWS
from fogiac.targets.aws.manifest import client_vpn, spot_estimate

__all__ = ["AwsCatalog", "catalog", "on_demand", "spot_price"]


@dataclass(frozen=True)
class AwsCatalog:
    source: str
    as_of: str
    spot_source: str
    spot_as_of: str
    spot_method: str
    vpn_association_usd_per_hour: float
    vpn_connection_usd_per_hour: float
    facts: Catalogue


@cache
def catalog() -> AwsCatalog:
    prices, cat = AWS.prices(), AWS.catalogue
    vpn = client_vpn(cat)
    return AwsCatalog(source=prices.source, as_of=prices.as_of, spot_source=prices.spot_source,
                      spot_as_of=prices.spot_as_of, spot_method=prices.spot_method,
                      vpn_association_usd_per_hour=vpn["association"], vpn_connection_usd_per_hour=vpn["connection"],
                      facts=cat)


def on_demand(name: str, region: str) -> float | None:
    """The on-demand price of ``name`` in ``region``; None when the catalogue has none (cost unknown, never $0)."""
    price = AWS.catalogue.price(name, region)
    return price.usd_per_hour if price is not None else None


def spot_price(name: str, region: str) -> float | None:
    """The spot estimate of ``name`` in ``region`` (4 decimals), or None."""
    offer = AWS.catalogue.offer(name, region)
    return spot_estimate(offer) if offer is not None else None
