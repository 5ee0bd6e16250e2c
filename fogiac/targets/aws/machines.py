"""The cheapest EC2 catalogue type that fits a node's requirement, and the runners-up.

Compile resolves a requirement (:class:`fogiac.manifest.machines.Requirement`) here, against the
checked-in catalogue and the manifest's region. Pure: no network.

A spot node is ranked by the catalogue's spot estimate (on-demand less the Spot Instance
Advisor's saving), since that is what it is expected to cost; the saving differs by type, so the
cheapest on-demand type is not always the cheapest spot one. The choice says which price ranked it.
Ties on price go to the smaller machine (fewer vCPUs, then less memory), then to the name in
alphabetical order, so equal manifests always resolve to the same type.
"""

from __future__ import annotations

from fogiac.manifest.machines import ALTERNATIVES, Choice, NoMachine, Option, RankedBy, Requirement
from fogiac.targets.aws.catalog import InstanceType, catalog


def offered(region: str) -> list[InstanceType]:
    """Catalogue types with a price in ``region`` (the catalogue lists only what the region offers)."""
    return [spec for spec in catalog().types.values() if region in spec.usd_per_hour]


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


def choose(req: Requirement, region: str, *, spot: bool = False) -> Choice:
    """The cheapest type in ``region`` that meets ``req``, at the spot estimate when ``spot``;
    raises :class:`NoMachine` if none fits."""
    by: RankedBy = "spot" if spot else "on-demand"
    types = offered(region)
    fits = sorted((s for s in types if req.miss(s) == 0.0), key=lambda s: _rank(s, region, by))
    if not fits:
        closest = sorted(types, key=lambda s: (req.miss(s),) + _rank(s, region, by))[:3]
        raise NoMachine(f"no instance type in {region} has {req.describe()}; closest: "
                        + ", ".join(_label(s, region, by) for s in closest))
    best, rest = fits[0], fits[1:1 + ALTERNATIVES]
    return Choice(machine=best.name, usd_per_hour=best.usd_per_hour[region],
                  alternatives=tuple(Option(s.name, s.usd_per_hour[region], _spot(s, region, by)) for s in rest),
                  chosen_for=req.describe(), ranked_by=by, spot_usd_per_hour=_spot(best, region, by))
