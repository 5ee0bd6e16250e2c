"""Nimbus's machines and regions, and its part of the manifest's ``cloud:`` block, in its own words."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from fogiac.manifest.machines import Choice, NoMachine, Option, PriceSource, Requirement
from fogiac.manifest.problems import FieldProblem

REGIONS = ("moon-1", "mars-2")


@dataclass(frozen=True)
class Shape:
    name: str
    vcpus: int
    memory_gib: float
    gpus: int
    gpu_model: str | None
    usd_per_hour: float

    @property
    def has_gpu(self) -> bool:
        return self.gpus > 0


SHAPES = {s.name: s for s in (Shape("n1.small", 2, 4.0, 0, None, 0.02), Shape("n1.large", 16, 64.0, 0, None, 0.31),
                              Shape("n1.tensor", 8, 32.0, 1, "Q1", 0.95))}


class NimbusCloud:
    """:class:`fogiac.manifest.clouds.CloudVariant` for ``provider: nimbus``."""

    def regions(self) -> Sequence[str]:
        return REGIONS

    def check_region(self, region: str) -> None:
        if region not in REGIONS:
            raise FieldProblem(f"{region!r} is not a nimbus region", choices=REGIONS)

    def check_zone(self, zone: str, region: str) -> None:
        raise FieldProblem("nimbus has no zones", field="zone")

    def check_edge_vpn_range(self, cidr: str, prefix: int) -> None:
        return None  # nimbus has no VPN: the edge reaches its machines through the relay

    def machine_names(self) -> Sequence[str]:
        return tuple(SHAPES)

    def machine(self, name: str) -> Shape | None:
        return SHAPES.get(name)

    def check_machine(self, name: str) -> None:
        if name not in SHAPES:
            raise FieldProblem(f"{name!r} is not a nimbus shape", choices=tuple(SHAPES))

    def check_gpu(self, name: str) -> None:
        if not SHAPES[name].has_gpu:
            raise FieldProblem(f"nimbus shape {name!r} has no GPU; n1.tensor has one", field="machine")

    def choose(self, named: str | None, need: Requirement | None, region: str, *, spot: bool) -> Choice:
        if named is not None:
            return Choice(machine=named, usd_per_hour=SHAPES[named].usd_per_hour, alternatives=())
        assert need is not None
        fits = sorted((s for s in SHAPES.values() if need.miss(s) == 0.0), key=lambda s: s.usd_per_hour)
        if not fits:
            raise NoMachine(f"no nimbus shape has {need.describe()}")
        return Choice(machine=fits[0].name, usd_per_hour=fits[0].usd_per_hour,
                      alternatives=tuple(Option(s.name, s.usd_per_hour) for s in fits[1:3]),
                      chosen_for=need.describe(), ranked_by="on-demand")

    def prices(self) -> PriceSource:
        return PriceSource(source="nimbus price sheet (test data)", as_of="2026-11", spot_source="none",
                           spot_as_of="-", spot_method="nimbus has no spot market")


CLOUD = NimbusCloud()
