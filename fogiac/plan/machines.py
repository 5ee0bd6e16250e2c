"""Machines chosen by requirement: the cheapest catalogue type that fits, and the runners-up.

A node may ask for what it needs (``machine: {gpu: T4, vcpus: ">=8", memory_gib: ">=16"}``)
instead of naming a type. Compile resolves that here, against the checked-in catalogue and the
manifest's region, so the choice is the same on every machine and shows in ``fogiac plan`` with
the next alternatives and their prices, the way FogROS2-Config offers a menu. Pure: no network.

A spot node is ranked by the catalogue's spot estimate (on-demand less the Spot Instance
Advisor's saving), since that is what it is expected to cost; the saving differs by type, so the
cheapest on-demand type is not always the cheapest spot one. The choice says which price ranked it.
Ties on price go to the smaller machine (fewer vCPUs, then less memory), then to the name in
alphabetical order, so equal manifests always resolve to the same type.
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal

from fogiac.plan.catalog import InstanceType, catalog

_BOUND = re.compile(r"^\s*(>=|<=|==|>|<)?\s*(\d+(?:\.\d+)?)\s*$")
_OPS: Mapping[str, Callable[[float, float], bool]] = {
    ">=": operator.ge, "<=": operator.le, "==": operator.eq, ">": operator.gt, "<": operator.lt,
}
_STRICT_MISS = 0.01  # what a value on the wrong side of a strict bound misses by, at least
ALTERNATIVES = 2  # how many runners-up a plan shows beside the choice
RankedBy = Literal["on-demand", "spot"]  # which catalogue price put the types in order


@dataclass(frozen=True)
class Bound:
    """``>= 8`` and the like; a bare number means at least that many."""

    op: str
    value: float

    def admits(self, have: float) -> bool:
        return _OPS[self.op](have, self.value)

    def miss(self, have: float) -> float:
        """How far ``have`` is from admissible, relative to the bound (0 when it is admitted)."""
        if self.admits(have):
            return 0.0
        return _STRICT_MISS + abs(have - self.value) / max(self.value, 1.0)  # '> 2' misses 2 by a little

    def __str__(self) -> str:
        return f"{self.op} {self.value:g}"


def parse_bound(text: str | int | float) -> Bound:
    """``">=8"``, ``"< 64"``, ``16`` (at least 16); anything else fails naming the forms allowed."""
    if isinstance(text, bool):
        raise ValueError(f"{text!r} is not a bound; write a number or e.g. '>=8', '<=64', '==16'")
    if isinstance(text, int | float):
        return Bound(">=", float(text))
    match = _BOUND.match(text)
    if not match:
        raise ValueError(f"{text!r} is not a bound; write a number or e.g. '>=8', '<=64', '==16'")
    return Bound(match.group(1) or ">=", float(match.group(2)))


@dataclass(frozen=True)
class Requirement:
    """What a node needs; ``gpu`` is True (any GPU), a model such as ``"T4"``, or None (no need)."""

    gpu: bool | str | None = None
    vcpus: Bound | None = None
    memory_gib: Bound | None = None

    def describe(self) -> str:
        parts = []
        if self.gpu is True:
            parts.append("a GPU")
        elif isinstance(self.gpu, str):
            parts.append(f"gpu {self.gpu}")
        if self.vcpus is not None:
            parts.append(f"vcpus {self.vcpus}")
        if self.memory_gib is not None:
            parts.append(f"memory_gib {self.memory_gib}")
        return ", ".join(parts) or "any machine"

    def _gpu_miss(self, spec: InstanceType) -> float:
        if self.gpu is None or self.gpu is False:
            return 0.0
        if not spec.has_gpu:
            return 2.0
        if isinstance(self.gpu, str) and not _same_gpu(self.gpu, spec.gpu_model):
            return 1.0
        return 0.0

    def miss(self, spec: InstanceType) -> float:
        """0 when ``spec`` fits; otherwise a distance used to name the closest types."""
        total = self._gpu_miss(spec)
        if self.vcpus is not None:
            total += self.vcpus.miss(spec.vcpus)
        if self.memory_gib is not None:
            total += self.memory_gib.miss(spec.memory_gib)
        return total


def _same_gpu(asked: str, model: str | None) -> bool:
    """``T4`` matches ``NVIDIA T4``; case does not matter."""
    if model is None:
        return False
    asked, model = asked.strip().lower(), model.lower()
    return model == asked or model.split()[-1] == asked.split()[-1]


@dataclass(frozen=True)
class Option:
    name: str
    usd_per_hour: float  # on-demand
    spot_usd_per_hour: float | None = None  # the spot estimate, when spot prices ranked the menu


@dataclass(frozen=True)
class Choice:
    """The resolved type and the next cheapest ones that also fit."""

    machine: str
    usd_per_hour: float  # on-demand
    alternatives: tuple[Option, ...]
    chosen_for: str | None = None  # the requirement, in words; None when the manifest named the type
    ranked_by: RankedBy | None = None  # None when the manifest named the type
    spot_usd_per_hour: float | None = None  # the chosen type's spot estimate, when spot prices ranked it


class NoMachine(ValueError):
    """Nothing in the catalogue fits; the message names the closest types in one line."""


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
