"""Every EC2 instance type in every commercial region: hardware, availability, on-demand and spot price.

The shipped table (``data/catalogue.json.gz``) is written by :mod:`fogiac.targets.aws.refresh`
and names its sources inside itself (``provenance``): each type's hardware, each region's offering
and each (type, region) price point carries the index of the source it came from, so a plan can
say where a number comes from and how old it is. ``fogiac catalog update`` rewrites the same
format from the user's own AWS account.

Loading is lazy and cheap: nothing is read until :func:`load` is first called, the file is one
gzip'd JSON document kept in compact rows, and a type's record is built only when asked for. Pure:
no network, no boto3.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from fogiac.errors import CloudError

FORMAT = 1
SHIPPED = "targets/aws/data/catalogue.json.gz"
Arch = Literal["x86_64", "arm64"]
_ROW = ("vcpus", "memory_gib", "arch", "accelerators", "accelerator_model", "accelerator_memory_gib",
        "accelerator_kind", "hardware_source", "offered", "prices")


class BadPrice(CloudError):
    """A catalogue holds a price that is not a finite number of dollars at least 0 (NaN, negative, infinite).

    Such a number poisons every comparison it meets: NaN sorts nowhere (a NaN catalogue chose a
    192-vCPU machine for ``vcpus: '>=2'``) and a negative one lowers a total under any budget."""


def checked_price(value: Any, where: str) -> float:
    """``value`` as a price in USD, or :class:`BadPrice` naming ``where`` (the entry it came from)."""
    try:
        usd = float(value)
    except (TypeError, ValueError):
        raise BadPrice(f"{where}: price {value!r} is not a number") from None
    if isinstance(value, bool) or not math.isfinite(usd) or usd < 0:
        raise BadPrice(f"{where}: price {value!r} is not a finite number of dollars at least 0") from None
    return usd


@dataclass(frozen=True)
class Source:
    """Where a fact came from: a name, what it covers, its date and licence."""

    name: str
    date: str
    detail: str
    license: str = ""
    estimate: bool = False  # a derived figure, not a published one


@dataclass(frozen=True)
class Price:
    usd_per_hour: float
    source: Source


@dataclass(frozen=True)
class InstanceType:
    name: str
    vcpus: int
    memory_gib: float
    arch: Arch
    gpus: int  # GPUs or other accelerators (Neuron, Gaudi, ...); see accelerator_kind
    gpu_model: str | None
    gpu_memory_gib: float  # all accelerators together
    accelerator_kind: str | None  # "gpu", "neuron", "fpga", "media", or None
    hardware_source: Source

    @property
    def family(self) -> str:
        return self.name.split(".", 1)[0]

    @property
    def size(self) -> str:
        return self.name.split(".", 1)[1] if "." in self.name else ""

    @property
    def has_gpu(self) -> bool:
        return self.gpus > 0 and self.accelerator_kind == "gpu"


@dataclass(frozen=True)
class Offer:
    """A type in a region, with what it costs there."""

    type: InstanceType
    region: str
    on_demand: Price | None
    spot: Price | None

    def rank_price(self, *, spot: bool = False) -> float:
        """What the type is expected to cost: spot when asked and known, else on-demand; unknown last."""
        chosen = self.spot if spot and self.spot is not None else self.on_demand
        return chosen.usd_per_hour if chosen is not None else float("inf")


class Catalogue:
    """The loaded table. Built from the raw document once; types materialise on first use."""

    def __init__(self, raw: Mapping[str, Any], *, path: str) -> None:
        if raw.get("format") != FORMAT:
            raise ValueError(f"{path}: catalogue format {raw.get('format')!r}, this fogiac reads {FORMAT}")
        self.path = path
        self.provenance: Mapping[str, Any] = raw["provenance"]
        self.sources = tuple(Source(**s) for s in raw["sources"])
        self.regions: tuple[str, ...] = tuple(raw["regions"])
        self.client_vpn_usd_per_hour: Mapping[str, float] = {
            key: (checked_price(value, f"{path}: client_vpn_usd_per_hour {key}") if key != "source" else value)
            for key, value in raw.get("client_vpn_usd_per_hour", {}).items()}
        self._rows: Mapping[str, list[Any]] = raw["types"]
        self._types: dict[str, InstanceType] = {}
        self._index = {r: i for i, r in enumerate(self.regions)}
        self._prices: dict[str, Mapping[int, tuple[float | None, int, float | None, int]]] = {}
        # type -> "region index:zone letters;..." (which zones of a region offer it); absent in older files
        self._zone_rows: Mapping[str, str] = raw.get("zones", {})
        self._zone_cache: dict[str, dict[str, tuple[str, ...]]] = {}
        # region -> its zones, gathered over every type once: zones_offering asks it for each (type, region), and
        # gathering it afresh each time made `catalog update`'s carry-over of ~900 types take half a minute
        self._region_zones: dict[str, tuple[str, ...]] = {}

    @property
    def types(self) -> tuple[str, ...]:
        return tuple(self._rows)

    def __contains__(self, name: object) -> bool:
        return name in self._rows

    def get(self, name: str) -> InstanceType | None:
        """The type's hardware, or None if the catalogue does not know it."""
        spec = self._types.get(name)
        if spec is None and name in self._rows:
            row = dict(zip(_ROW, self._rows[name], strict=True))
            spec = InstanceType(
                name=name, vcpus=row["vcpus"], memory_gib=row["memory_gib"], arch=row["arch"],
                gpus=row["accelerators"], gpu_model=row["accelerator_model"],
                gpu_memory_gib=row["accelerator_memory_gib"], accelerator_kind=row["accelerator_kind"],
                hardware_source=self.sources[row["hardware_source"]])
            self._types[name] = spec
        return spec

    def regions_offering(self, name: str) -> tuple[str, ...]:
        row = self._rows.get(name)
        if row is None:
            return ()
        mask = int(row[8])
        return tuple(r for i, r in enumerate(self.regions) if mask >> i & 1)

    def offered(self, name: str, region: str) -> bool:
        row, i = self._rows.get(name), self._index.get(region)
        return row is not None and i is not None and bool(int(row[8]) >> i & 1)

    def _zones_of(self, name: str) -> dict[str, tuple[str, ...]]:
        found = self._zone_cache.get(name)
        if found is None:
            found = {}
            for cell in filter(None, self._zone_rows.get(name, "").split(";")):
                ri, letters = cell.split(":")
                region = self.regions[int(ri)]
                found[region] = tuple(f"{region}{letter}" for letter in letters)
            self._zone_cache[name] = found
        return found

    def region_zones(self, region: str) -> tuple[str, ...]:
        """The zones of ``region`` the catalogue knows (any type offered there); () when it lists none."""
        found = self._region_zones.get(region)
        if found is None:
            found = tuple(sorted({z for name in self._zone_rows for z in self._zones_of(name).get(region, ())}))
            self._region_zones[region] = found
        return found

    def zones_offering(self, name: str, region: str) -> tuple[str, ...] | None:
        """The zones of ``region`` that offer ``name``, sorted; None when the catalogue lists no zones there."""
        if not self.region_zones(region):
            return None
        return self._zones_of(name).get(region, ())

    def _points(self, name: str) -> Mapping[int, tuple[float | None, int, float | None, int]]:
        """region index -> (on-demand, its source, spot, its source); parsed on first use."""
        points = self._prices.get(name)
        if points is None:
            points = {}
            text = self._rows[name][9] if name in self._rows else ""
            for cell in filter(None, text.split(";")):
                ri, od, ods, sp, sps = cell.split(",")
                where = f"{self.path}: {name} in {self._region_at(ri)}"
                points[int(ri)] = (checked_price(od, f"{where} (on-demand)") if od else None, int(ods or 0),
                                   checked_price(sp, f"{where} (spot)") if sp else None, int(sps or 0))
            self._prices[name] = points
        return points

    def _region_at(self, index: str) -> str:
        i = int(index) if index.isdigit() else -1
        return self.regions[i] if 0 <= i < len(self.regions) else f"region #{index}"

    def _point(self, name: str, region: str, column: int) -> Price | None:
        i = self._index.get(region)
        point = self._points(name).get(i) if i is not None else None
        if point is None:
            return None
        value, source = (point[0], point[1]) if column == 0 else (point[2], point[3])
        return None if value is None else Price(value, self.sources[source])

    def price(self, name: str, region: str) -> Price | None:
        """On-demand Linux, shared tenancy, USD per hour; None when unknown."""
        return self._point(name, region, 0)

    def spot(self, name: str, region: str) -> Price | None:
        """A spot estimate (not a quote); None when unknown."""
        return self._point(name, region, 2)

    def offer(self, name: str, region: str) -> Offer | None:
        spec = self.get(name)
        if spec is None or not self.offered(name, region):
            return None
        return Offer(spec, region, self.price(name, region), self.spot(name, region))

    def search(self, *, region: str, gpu: bool | str | None = None, arch: Arch | None = None,
               vcpus: str | float | None = None, memory: str | float | None = None,
               gpu_memory_gib: str | float | None = None, spot: bool = False,
               priced_only: bool = True) -> list[Offer]:
        """Types offered in ``region`` that meet every bound, cheapest first.

        Bounds are numbers (at least) or strings such as ``">=16"``, ``"<64"``, ``"==8"``. ``gpu``
        is True (any GPU), a model (``"L4"``, ``"A10G"``; case-insensitive) or None. Ties go to the
        smaller machine, then the name, so equal requests always give the same order.
        """
        tests = [(attr, _bound(value)) for attr, value in
                 (("vcpus", vcpus), ("memory_gib", memory), ("gpu_memory_gib", gpu_memory_gib))
                 if value is not None]
        found = []
        for name in self._rows:
            if not self.offered(name, region):
                continue
            spec = self.get(name)
            assert spec is not None
            if arch is not None and spec.arch != arch:
                continue
            if gpu and not (spec.has_gpu and (gpu is True or same_gpu(str(gpu), spec.gpu_model))):
                continue
            if not all(check(getattr(spec, attr)) for attr, check in tests):
                continue
            offer = Offer(spec, region, self.price(name, region), self.spot(name, region))
            if priced_only and offer.on_demand is None:
                continue
            found.append(offer)
        found.sort(key=lambda o: (o.rank_price(spot=spot), o.type.vcpus, o.type.memory_gib, o.type.name))
        return found

    def gpu_models(self) -> tuple[str, ...]:
        return tuple(sorted({s.gpu_model for n in self._rows if (s := self.get(n)) and s.has_gpu and s.gpu_model}))


_BOUND = re.compile(r"^\s*(>=|<=|==|>|<)?\s*(\d+(?:\.\d+)?)\s*$")


def _bound(value: str | float) -> Any:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return lambda have, v=float(value): have >= v
    match = _BOUND.match(str(value))
    if not match:
        raise ValueError(f"{value!r} is not a bound; write a number or e.g. '>=8', '<=64', '==16'")
    op, v = match.group(1) or ">=", float(match.group(2))
    return {">=": lambda h: h >= v, "<=": lambda h: h <= v, "==": lambda h: h == v,
            ">": lambda h: h > v, "<": lambda h: h < v}[op]


def same_gpu(asked: str, model: str | None) -> bool:
    """``L4`` matches ``L4`` and ``NVIDIA L4``; case does not matter."""
    if not model:
        return False
    a, m = asked.strip().lower(), model.strip().lower()
    return a == m or m.split()[-1] == a.split()[-1]


# ---------------------------------------------------------------- suggestions from the facts

_SIZES = ("nano", "micro", "small", "medium", "large", "xlarge", "2xlarge", "3xlarge", "4xlarge",
          "6xlarge", "8xlarge", "9xlarge", "10xlarge", "12xlarge", "16xlarge", "18xlarge", "24xlarge",
          "32xlarge", "48xlarge", "56xlarge", "96xlarge", "112xlarge", "metal")


def _size_rank(size: str) -> int:
    """Position on the size ladder; a misspelt size ('xlarg') takes the nearest known one's place."""
    base = size.split("-", 1)[0]
    if base not in _SIZES:
        base = min(_SIZES, key=lambda known: (_edit(base, known), known))
    return _SIZES.index(base)


def _edit(a: str, b: str) -> int:
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        cur = [i]
        for j, cb in enumerate(b, 1):
            cur.append(min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (ca != cb)))
        prev = cur
    return prev[-1]


def suggest_type(cat: Catalogue, name: str, *, region: str | None = None, limit: int = 3) -> list[str]:
    """Known types nearest to an unknown ``name``: same size in the nearest family first, then the
    nearest size in the same family; with ``region``, only types offered there."""
    family, _, size = name.strip().lower().partition(".")
    pool = [t for t in cat.types if region is None or cat.offered(t, region)]
    known = cat.get(name)
    if known is not None:  # a real type the region lacks: the nearest hardware the region has
        return sorted((t for t in pool if t != name), key=lambda t: _likeness(known, cat.get(t)))[:limit]
    families = sorted({t.split(".", 1)[0] for t in pool})
    if family in families:
        near = [family]
    else:
        ranked = sorted(families, key=lambda f: (_edit(family, f), abs(len(f) - len(family)), f))
        best = _edit(family, ranked[0]) if ranked else 99
        near = [f for f in ranked if _edit(family, f) == best][:3] if best <= max(2, len(family) // 2) else []
    rank = _size_rank(size) if size else 0
    out = sorted((t for t in pool if t.split(".", 1)[0] in near),
                 key=lambda t: (abs(_size_rank(t.split(".", 1)[1]) - rank), near.index(t.split(".", 1)[0]),
                                _edit(size, t.split(".", 1)[1]), t))
    if not out:  # the family is beyond a typo: fall back to the nearest full names
        out = sorted(pool, key=lambda t: (_edit(name, t), t))[:limit]
    return out[:limit]


def _likeness(want: InstanceType, have: InstanceType | None) -> tuple[float, ...]:
    """How far ``have`` is from ``want``: accelerator first, then vCPUs and memory on a log scale."""
    assert have is not None
    gpu = 0.0 if want.accelerator_kind == have.accelerator_kind else 2.0
    if want.gpus and have.gpus and not same_gpu(want.gpu_model or "", have.gpu_model):
        gpu = 1.0
    return (gpu, abs(math.log2(have.vcpus / want.vcpus)) + abs(math.log2(have.memory_gib / want.memory_gib))
            + abs(have.gpus - want.gpus) / max(want.gpus, 1), float(have.arch != want.arch))


def suggest_region(cat: Catalogue, region: str, *, machine: str | None = None, limit: int = 3) -> list[str]:
    """Regions to offer instead of ``region``: those that offer ``machine`` when one is named (the
    ones nearest in name first, so ``eu-west-1`` for a typo'd ``eu-wset-1``), else the nearest names."""
    pool = [r for r in (cat.regions_offering(machine) if machine and machine in cat else cat.regions)
            if r != region]
    geo = region.split("-", 1)[0]
    pool.sort(key=lambda r: (_edit(region, r) > 2, r.split("-", 1)[0] != geo, _edit(region, r), r))
    return pool[:limit]


def not_offered(cat: Catalogue, name: str, region: str) -> str:
    """The one-line refusal for a type not offered in ``region``, naming the regions that offer it."""
    where = cat.regions_offering(name)
    if not where:
        return f"{name!r} is offered in no region the catalogue knows"
    return f"{name!r} is not offered in {region}; regions that offer it: {', '.join(where)}"


# ---------------------------------------------------------------- loading


def read(path: str | Path) -> Catalogue:
    """Read a catalogue file (gzip'd JSON, or plain JSON when the name does not end in .gz)."""
    data = Path(path).read_bytes()
    if data[:2] == b"\x1f\x8b":
        data = gzip.decompress(data)
    return Catalogue(json.loads(data), path=str(path))


def digest(path: str | None = None) -> str:
    """The sha256 of the catalogue file :func:`load` reads for ``path``: a saved plan binds the catalogue its
    machines were chosen and priced from, so a refreshed one is not applied unreviewed."""
    data = Path(path).read_bytes() if path is not None else resources.files("fogiac").joinpath(SHIPPED).read_bytes()
    return hashlib.sha256(data).hexdigest()


@cache
def load(path: str | None = None) -> Catalogue:
    """The catalogue: the user's refreshed one at ``path`` when given, else the shipped one. Cached."""
    if path is not None:
        return read(path)
    shipped = resources.files("fogiac").joinpath(SHIPPED)
    raw = json.loads(gzip.decompress(shipped.read_bytes()))
    return Catalogue(raw, path=SHIPPED)


def describe(spec: InstanceType) -> str:
    gpu = f"{spec.gpus}x {spec.gpu_model} ({spec.gpu_memory_gib:g} GiB), " if spec.gpus else ""
    return f"{spec.name} ({gpu}{spec.vcpus} vCPU, {spec.memory_gib:g} GiB, {spec.arch})"


def names(offers: Iterable[Offer]) -> list[str]:
    return [o.type.name for o in offers]
