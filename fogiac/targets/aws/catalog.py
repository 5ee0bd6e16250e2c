"""The checked-in catalogue of EC2 instance types fogiac knows: hardware, on-demand and spot price.

The table (``fogiac/targets/aws/data/instance_types.json``) names its sources and dates. It is what makes
``fogiac plan`` show a cost offline and what ``validate`` checks machine names against. Spot
prices move hourly and AWS publishes no dated table of them; the catalogue keeps what the Spot
Instance Advisor published, the saving over on-demand per type and region, and derives the spot
price from it, so both prices carry a date and a source and neither is a quote.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from types import MappingProxyType


@dataclass(frozen=True)
class InstanceType:
    name: str
    vcpus: int
    memory_gib: float
    gpus: int
    gpu_model: str | None
    usd_per_hour: Mapping[str, float]
    spot_savings_pct: Mapping[str, int]  # region -> the Spot Instance Advisor's saving over on-demand

    def spot_usd_per_hour(self, region: str) -> float | None:
        """The spot estimate in ``region`` (on-demand less the advisor's saving), or None if unknown."""
        saving = self.spot_savings_pct.get(region)
        if saving is None or region not in self.usd_per_hour:
            return None
        return round(self.usd_per_hour[region] * (100 - saving) / 100, 4)

    @property
    def has_gpu(self) -> bool:
        return self.gpus > 0


@dataclass(frozen=True)
class Catalog:
    source: str
    as_of: str
    regions: tuple[str, ...]
    types: Mapping[str, InstanceType]
    vpn_association_usd_per_hour: float
    vpn_connection_usd_per_hour: float
    spot_source: str
    spot_as_of: str
    spot_method: str


@lru_cache(maxsize=1)
def catalog() -> Catalog:
    raw = json.loads(resources.files("fogiac").joinpath("targets/aws/data/instance_types.json").read_text())
    types = {
        name: InstanceType(
            name=name,
            vcpus=spec["vcpus"],
            memory_gib=spec["memory_gib"],
            gpus=spec["gpus"],
            gpu_model=spec["gpu_model"],
            usd_per_hour=MappingProxyType(dict(spec["usd_per_hour"])),
            spot_savings_pct=MappingProxyType(dict(spec.get("spot_savings_pct", {}))),
        )
        for name, spec in raw["types"].items()
    }
    return Catalog(
        source=raw["source"],
        as_of=raw["as_of"],
        regions=tuple(raw["regions"]),
        types=MappingProxyType(types),
        vpn_association_usd_per_hour=raw["client_vpn_usd_per_hour"]["association"],
        vpn_connection_usd_per_hour=raw["client_vpn_usd_per_hour"]["connection"],
        spot_source=raw["spot"]["source"],
        spot_as_of=raw["spot"]["as_of"],
        spot_method=raw["spot"]["method"],
    )
