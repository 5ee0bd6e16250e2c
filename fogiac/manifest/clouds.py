"""The ``cloud:`` block's variants: each target contributes the checks only it can make.

Where machines come from decides what a region, a zone and a machine name mean, so the schema
does not know: it asks the variant the manifest's ``provider`` names, through the plug-in registry
(group ``fogiac.clouds``), for its region and zone checks, whether a machine name exists and has
a GPU, and which machine a node's requirement resolves to. A variant raises
:class:`~fogiac.manifest.problems.FieldProblem` with its own words; the schema places them.

A node's machine is checked where the node is, before the ``cloud:`` block's own checks: the
schema passes the provider it read from the raw manifest as validation context, and a model
built without one (in code, or the checks across fields) names machines in :data:`DEFAULT`'s
terms (targets without a catalogue of their own size and price their machines in the default's).

What a manifest leaves out is the default variant's to fill in: its region, and the keys it adds to
the ``network:`` block (``network``, read by :mod:`fogiac.manifest.blocks`). What a cloud allows
(tags per resource, nodes per stack) is each variant's :class:`Limits`; a variant that names none
is held to the default's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from fogiac import defaults, registry
from fogiac.manifest.machines import Choice, MachineSpec, PriceSource, Requirement

GROUP = "fogiac.clouds"
DEFAULT = defaults.PROVIDER  # the provider a manifest without ``provider:`` names


@dataclass(frozen=True)
class Limits:
    """What a cloud allows, checked at ``validate`` rather than found at ``up``; None: no limit."""

    tags: int | None = None  # tags one resource holds, fogiac's own among them
    tag_key: int | None = None  # characters in a tag's key
    tag_value: int | None = None  # characters in a tag's value
    reserved: tuple[str, ...] = ()  # tag key prefixes the cloud keeps for itself
    nodes: int | None = None  # nodes one stack holds


NO_LIMITS = Limits()


class CloudVariant(Protocol):
    """What a target answers about its part of the manifest's ``cloud:`` block.

    Optional attributes, read where present: ``limits`` (:class:`Limits`), ``network`` (the model
    of the ``network:`` block with the variant's own keys, a subclass of
    :class:`~fogiac.manifest.network.NetworkBlock`, asked of the default variant) and
    ``catalogue_sha256()`` (the digest of the machine catalogue it reads, which a saved plan binds).
    """

    @property
    def default_region(self) -> str:
        """The region of a manifest that names none (asked of the default variant)."""

    def regions(self) -> Sequence[str]: ...

    def check_region(self, region: str) -> None:
        """Raise :class:`FieldProblem` when ``region`` is not one the target serves."""

    def check_zone(self, zone: str, region: str) -> None:
        """Raise :class:`FieldProblem` (field ``zone``) when ``zone`` is not in ``region``."""

    def check_edge_vpn_range(self, cidr: str, prefix: int) -> None:
        """Raise ``ValueError`` when the edge's VPN address range (``network.client_cidr``) is outside
        what the target's VPN allows."""

    def machine_names(self) -> Sequence[str]: ...

    def machine(self, name: str) -> MachineSpec | None:
        """The named machine type's hardware, or None."""

    def check_machine(self, name: str) -> None:
        """Raise :class:`FieldProblem` when ``name`` is not a known machine type."""

    def check_gpu(self, name: str) -> None:
        """Raise :class:`FieldProblem` (field ``machine``) when ``name`` has no GPU but one is asked for."""

    def choose(self, named: str | None, need: Requirement | None, region: str, *, spot: bool) -> Choice:
        """The named type at its price in ``region``, or the cheapest that meets ``need``; raises
        :class:`~fogiac.manifest.machines.NoMachine` when none does."""

    def prices(self) -> PriceSource:
        """Where the machine prices come from, and the network's standing charge."""


def providers(*, own: bool = False) -> tuple[str, ...]:
    """Every provider a manifest may name: fogiac's and those of other installed packages (``own``: fogiac's)."""
    return registry.names(GROUP, own=own)


def known(provider: object) -> bool:
    """Whether ``provider`` names a variant."""
    return isinstance(provider, str) and registry.known(GROUP, provider)


def variant(provider: str | None = None) -> CloudVariant:
    """The ``cloud:`` variant of ``provider`` (default: :data:`DEFAULT`)."""
    found: CloudVariant = registry.load(GROUP, provider or DEFAULT)
    return found


def sizing(provider: object) -> CloudVariant:
    """The variant that names and prices machines for ``provider``: its own where it names one, else the
    default's. One decision for every lenient reader: a manifest whose provider is wrong (its own error
    says so) still has its nodes' machines checked, and a target without a ``cloud:`` variant of its own
    (one registered in code only) sizes and prices its machines in the default's terms."""
    found: CloudVariant | None = registry.find(GROUP, provider) if isinstance(provider, str) else None
    return found if found is not None else variant()


def prices(target: str | None = None) -> PriceSource:
    """Where ``target``'s prices come from (:func:`sizing`: the default's for a target without a variant)."""
    return sizing(target).prices()


def catalogue_digest(target: str | None = None) -> str | None:
    """The digest of the machine catalogue ``target`` chooses and prices machines from (as :func:`prices`, the
    default's for a target without a variant of its own); None for a variant that keeps none."""
    found = getattr(sizing(target), "catalogue_sha256", None)
    return str(found()) if callable(found) else None


def limits(provider: object = None) -> Limits:
    """What ``provider``'s cloud allows (:func:`sizing`: a provider that names no variant, the default's); a
    variant naming none is held to the default's, as its machines are sized in the default's terms (a manifest
    valid for one target stays valid for the others)."""
    found: Limits | None = getattr(sizing(provider), "limits", None)
    return found if found is not None else getattr(variant(), "limits", NO_LIMITS)


def default_region() -> str:
    """The region of a manifest without one: the default variant's."""
    return variant().default_region
