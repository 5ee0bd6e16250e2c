"""The checked-in catalogue of EC2 instance types fogiac knows: hardware and on-demand price.

The table (``fogiac/plan/data/instance_types.json``) names its source and date. It is what makes
``fogiac plan`` show a cost offline and what ``validate`` checks machine names against.
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


@lru_cache(maxsize=1)
def catalog() -> Catalog:
    raw = json.loads(resources.files("fogiac").joinpath("plan/data/instance_types.json").read_text())
    types = {
        name: InstanceType(
            name=name,
            vcpus=spec["vcpus"],
            memory_gib=spec["memory_gib"],
            gpus=spec["gpus"],
            gpu_model=spec["gpu_model"],
            usd_per_hour=MappingProxyType(dict(spec["usd_per_hour"])),
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
    )
