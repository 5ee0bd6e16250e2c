"""A machine catalogue: a checked-in table of machine types (hardware, on-demand and spot price per
region), read from a target's folder, and the ``cloud:`` variant that answers from it.

The format is provider-neutral; the data is the target's (the ``aws`` target's table is
``fogiac/targets/aws/data/instance_types.json``, which names its sources and dates). A table is
what makes ``fogiac plan`` show a cost offline and what ``validate`` checks machine names against.
Spot prices move hourly and no provider publishes a dated table of them; a table keeps the
published saving over on-demand per type and region, and derives the spot price from it, so both
prices carry a date and a source and neither is a quote.

Reading a table imports no target's package: ``fogiac validate --target local`` of a manifest
that names the default provider loads neither that target's code nor a cloud SDK.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources
from types import MappingProxyType
from typing import Any

from fogiac.manifest.machines import ALTERNATIVES, Choice, NoMachine, Option, PriceSource, RankedBy, Requirement
from fogiac.manifest.problems import FieldProblem


@dataclass(frozen=True)
class InstanceType:
    name: str
    vcpus: int
    memory_gib: float
    gpus: int
    gpu_model: str | None
    usd_per_hour: Mapping[str, float]
    spot_savings_pct: Mapping[str, int]  # region -> the published saving of spot over on-demand

    def spot_usd_per_hour(self, region: str) -> float | None:
        """The spot estimate in ``region`` (on-demand less the saving), or None if unknown."""
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
    spot_source: str
    spot_as_of: str
    spot_method: str


@cache
def raw(resource: str) -> Mapping[str, Any]:
    """The table at ``resource`` (a path inside the ``fogiac`` package), as JSON."""
    found: Mapping[str, Any] = json.loads(resources.files("fogiac").joinpath(resource).read_text())
    return found


@cache
def read(resource: str) -> Catalog:
    table = raw(resource)
    types = {
        name: InstanceType(
            name=name, vcpus=spec["vcpus"], memory_gib=spec["memory_gib"], gpus=spec["gpus"],
            gpu_model=spec["gpu_model"], usd_per_hour=MappingProxyType(dict(spec["usd_per_hour"])),
            spot_savings_pct=MappingProxyType(dict(spec.get("spot_savings_pct", {}))),
        )
        for name, spec in table["types"].items()
    }
    return Catalog(source=table["source"], as_of=table["as_of"], regions=tuple(table["regions"]),
                   types=MappingProxyType(types), spot_source=table["spot"]["source"],
                   spot_as_of=table["spot"]["as_of"], spot_method=table["spot"]["method"])


# The cheapest fitting type. A spot node is ranked by the spot estimate, since that is what it is
# expected to cost; the saving differs by type, so the cheapest on-demand type is not always the
# cheapest spot one. Ties on price go to the smaller machine (fewer vCPUs, then less memory), then
# to the name in alphabetical order, so equal manifests always resolve to the same type.

def offered(cat: Catalog, region: str) -> list[InstanceType]:
    """Types with a price in ``region`` (a table lists only what the region offers)."""
    return [spec for spec in cat.types.values() if region in spec.usd_per_hour]


def _spot(spec: InstanceType, region: str, by: RankedBy) -> float | None:
    return spec.spot_usd_per_hour(region) if by == "spot" else None


def price(spec: InstanceType, region: str, by: RankedBy) -> float:
    """The price ``by`` ranks with; a type without a spot estimate ranks at on-demand, the most spot costs."""
    spot = _spot(spec, region, by)
    return spec.usd_per_hour[region] if spot is None else spot


def _rank(spec: InstanceType, region: str, by: RankedBy) -> tuple[float, int, float, str]:
    return (price(spec, region, by), spec.vcpus, spec.memory_gib, spec.name)


def _label(spec: InstanceType, region: str, by: RankedBy) -> str:
    gpu = f"{spec.gpus}x {spec.gpu_model}, " if spec.has_gpu else ""
    spot = _spot(spec, region, by)
    cost = f"${spec.usd_per_hour[region]:g}/h" + (f", spot about ${spot:g}/h" if spot is not None else "")
    return f"{spec.name} ({gpu}{spec.vcpus} vCPU, {spec.memory_gib:g} GiB, {cost})"


def cheapest(cat: Catalog, req: Requirement, region: str, *, spot: bool = False) -> Choice:
    """The cheapest type of ``cat`` in ``region`` that meets ``req``, at the spot estimate when
    ``spot``; raises :class:`NoMachine` naming the closest types if none fits."""
    by: RankedBy = "spot" if spot else "on-demand"
    types = offered(cat, region)
    fits = sorted((s for s in types if req.miss(s) == 0.0), key=lambda s: _rank(s, region, by))
    if not fits:
        closest = sorted(types, key=lambda s: (req.miss(s),) + _rank(s, region, by))[:3]
        raise NoMachine(f"no instance type in {region} has {req.describe()}; closest: "
                        + ", ".join(_label(s, region, by) for s in closest))
    best, rest = fits[0], fits[1:1 + ALTERNATIVES]
    return Choice(machine=best.name, usd_per_hour=best.usd_per_hour[region],
                  alternatives=tuple(Option(s.name, s.usd_per_hour[region], _spot(s, region, by)) for s in rest),
                  chosen_for=req.describe(), ranked_by=by, spot_usd_per_hour=_spot(best, region, by))


class CatalogueCloud:
    """A ``cloud:`` variant (:class:`fogiac.manifest.clouds.CloudVariant`) answered from the table at
    ``resource``: its regions, zones (the region and one letter) and types, and its words."""

    def __init__(self, resource: str) -> None:
        self.resource = resource

    @property
    def catalog(self) -> Catalog:
        return read(self.resource)

    def regions(self) -> Sequence[str]:
        return self.catalog.regions

    def check_region(self, region: str) -> None:
        regions = self.catalog.regions
        if region not in regions:
            raise FieldProblem(f"{region!r} is not a supported region", choices=regions)

    def check_zone(self, zone: str, region: str) -> None:
        if not (zone.startswith(region) and len(zone) == len(region) + 1):
            raise FieldProblem(f"{zone!r} is not a zone of {region}", field="zone")

    def check_edge_vpn_range(self, cidr: str, prefix: int) -> None:
        """The range the edge's VPN hands out: within the limits the table names (its VPN's)."""
        limits = raw(self.resource).get("edge_vpn_prefix")
        if limits and not limits["shortest"] <= prefix <= limits["longest"]:
            raise ValueError(f"{cidr} must be between /{limits['shortest']} and /{limits['longest']} ({limits['why']})")

    def machine_names(self) -> Sequence[str]:
        return tuple(self.catalog.types)

    def machine(self, name: str) -> InstanceType | None:
        return self.catalog.types.get(name)

    def check_machine(self, name: str) -> None:
        if name not in self.catalog.types:
            raise FieldProblem(f"{name!r} is not a known instance type", choices=tuple(self.catalog.types))

    def check_gpu(self, name: str) -> None:
        if not self.catalog.types[name].has_gpu:
            raise FieldProblem(f"{name!r} has no GPU but the node sets gpu: true; pick a GPU type such as "
                               f"{raw(self.resource)['gpu_example']!r}", field="machine")

    def choose(self, named: str | None, need: Requirement | None, region: str, *, spot: bool) -> Choice:
        if named is not None:
            return Choice(machine=named, usd_per_hour=self.catalog.types[named].usd_per_hour.get(region, 0.0),
                          alternatives=())
        assert need is not None
        return cheapest(self.catalog, need, region, spot=spot)

    def prices(self) -> PriceSource:
        cat, charge = self.catalog, raw(self.resource).get("network_charge")
        standing: Any = raw(self.resource)
        for key in charge["usd_per_hour"] if charge else ():
            standing = standing[key]
        return PriceSource(source=cat.source, as_of=cat.as_of, spot_source=cat.spot_source, spot_as_of=cat.spot_as_of,
                           spot_method=cat.spot_method, spot_ceiling=raw(self.resource)["spot"].get("ceiling", ""),
                           network_usd_per_hour=float(standing) if charge else 0.0,
                           network_item=charge["item"] if charge else "")

