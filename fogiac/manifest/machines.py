"""What a node needs of its machine, and the choice a target's catalogue makes from it.

A node may ask for what it needs (``machine: {gpu: T4, vcpus: ">=8", memory_gib: ">=16"}``)
instead of naming a type. This module holds the provider-neutral words for that (bounds, the
requirement, the choice and its runners-up); the target whose catalogue sizes the machines
resolves it (for ``aws``: ``fogiac.targets.aws.machines``, against the checked-in catalogue and
the manifest's region), so the choice is the same on every machine and shows in ``fogiac plan``
with the next alternatives and their prices, the way FogROS2-Config offers a menu. Pure: no network.
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal, Protocol

_BOUND = re.compile(r"^\s*(>=|<=|==|>|<)?\s*(\d+(?:\.\d+)?)\s*$")
_OPS: Mapping[str, Callable[[float, float], bool]] = {
    ">=": operator.ge, "<=": operator.le, "==": operator.eq, ">": operator.gt, "<": operator.lt,
}
_STRICT_MISS = 0.01  # what a value on the wrong side of a strict bound misses by, at least
ALTERNATIVES = 2  # how many runners-up a plan shows beside the choice
RankedBy = Literal["on-demand", "spot"]  # which catalogue price put the types in order


class MachineSpec(Protocol):
    """The hardware of one catalogue type, as a requirement measures it."""

    @property
    def name(self) -> str: ...
    @property
    def vcpus(self) -> int: ...
    @property
    def gpus(self) -> int: ...
    @property
    def memory_gib(self) -> float: ...
    @property
    def gpu_model(self) -> str | None: ...
    @property
    def has_gpu(self) -> bool: ...
    @property
    def arch(self) -> str: ...
    @property
    def gpu_memory_gib(self) -> float: ...


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


MAX_BOUND = 65536.0  # beyond any machine's vCPUs, GiB of memory or of GPU memory


def parse_bound(text: str | int | float) -> Bound:
    """``">=8"``, ``"< 64"``, ``16`` (at least 16); anything else fails naming the forms allowed."""
    if isinstance(text, bool):
        raise ValueError(f"{text!r} is not a bound; write a number or e.g. '>=8', '<=64', '==16'")
    if isinstance(text, int | float):
        found = Bound(">=", float(text))
    else:
        match = _BOUND.match(text)
        if not match:
            raise ValueError(f"{text!r} is not a bound; write a number or e.g. '>=8', '<=64', '==16'")
        found = Bound(match.group(1) or ">=", float(match.group(2)))
    if not 0 <= found.value <= MAX_BOUND:  # a machine has no negative vCPUs, nor 1e30 of them
        raise ValueError(f"{text!r} is out of range: a bound is a number from 0 to {MAX_BOUND:g}")
    return found


@dataclass(frozen=True)
class Requirement:
    """What a node needs; ``gpu`` is True (any GPU), a model such as ``"T4"``, or None (no need);
    ``arch`` is ``x86_64``, ``arm64`` or None (either)."""

    gpu: bool | str | None = None
    vcpus: Bound | None = None
    memory_gib: Bound | None = None
    arch: Literal["x86_64", "arm64"] | None = None
    gpu_memory_gib: Bound | None = None  # all the machine's GPUs together

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
        if self.gpu_memory_gib is not None:
            parts.append(f"gpu_memory_gib {self.gpu_memory_gib}")
        if self.arch is not None:
            parts.append(f"arch {self.arch}")
        return ", ".join(parts) or "any machine"

    def _gpu_miss(self, spec: MachineSpec) -> float:
        if self.gpu is None or self.gpu is False:
            return 0.0
        if not spec.has_gpu:
            return 2.0
        if isinstance(self.gpu, str) and not same_gpu(self.gpu, spec.gpu_model):
            return 1.0
        return 0.0

    def miss(self, spec: MachineSpec) -> float:
        """0 when ``spec`` fits; otherwise a distance used to name the closest types."""
        total = self._gpu_miss(spec)
        if self.vcpus is not None:
            total += self.vcpus.miss(spec.vcpus)
        if self.memory_gib is not None:
            total += self.memory_gib.miss(spec.memory_gib)
        if self.gpu_memory_gib is not None:
            total += self.gpu_memory_gib.miss(spec.gpu_memory_gib)
        if self.arch is not None and spec.arch != self.arch:
            total += 1.0
        return total


def same_gpu(asked: str, model: str | None) -> bool:
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
    usd_per_hour: float | None  # on-demand; None: the catalogue has no price there (cost unknown)
    alternatives: tuple[Option, ...]
    chosen_for: str | None = None  # the requirement, in words; None when the manifest named the type
    ranked_by: RankedBy | None = None  # None when the manifest named the type
    spot_usd_per_hour: float | None = None  # the chosen type's spot estimate, when spot prices ranked it


@dataclass(frozen=True)
class PriceSource:
    """Where a target's catalogue prices come from, and what its network bills while it stands."""

    source: str
    as_of: str
    spot_source: str
    spot_as_of: str
    spot_method: str
    spot_ceiling: str = ""  # why a spot estimate is at most on-demand, in the provider's words
    network_usd_per_hour: float = 0.0  # billed while the network exists, whether or not an edge is connected
    network_item: str = ""  # that charge in words, as a status line and a cost note name it


class CostUnknown(UserWarning):
    """A machine or region the provider has but the catalogue cannot price: accepted, and said in one line."""


class NoMachine(ValueError):
    """Nothing in the catalogue fits; the message names the closest types in one line."""
