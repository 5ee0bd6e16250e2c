"""Drift: what the cloud reported at the last ``fogiac refresh`` that the applied plan document does not say.

A target that can ask its cloud (``aws``) compares, on ``refresh``, what it finds with the
stack's applied document and records the result here, beside the applied document, together
with what it observed. ``fogiac plan`` reads the record without touching the cloud, so a
reviewer sees resources changed or deleted outside fogiac next to the diff. The record only
describes the cloud between the last apply and the next one: ``up`` and ``down`` drop it.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from fogiac.state import StackState

REFRESHED_FILE = StackState.REFRESHED
Status = Literal["changed", "deleted", "added"]
VERB = {"changed": "changed outside fogiac", "deleted": "deleted outside fogiac", "added": "made outside fogiac"}


@dataclass(frozen=True)
class Drift:
    """One resource whose cloud state no longer matches the applied document."""

    stack: str  # the layer (network, compute), as in the plan document
    type: str
    name: str  # the applied resource's name; for one made outside fogiac, its cloud id
    status: Status
    changes: tuple[tuple[str, Any, Any], ...] = ()  # (input, as applied, as the cloud reports it)
    detail: str = ""  # one line: what an added resource is (e.g. the rule it opens)

    def to_dict(self) -> dict[str, Any]:
        return {"stack": self.stack, "type": self.type, "name": self.name, "status": self.status,
                "changes": [{"input": p, "applied": a, "cloud": c} for p, a, c in self.changes],
                "detail": self.detail}

    @classmethod
    def from_dict(cls, row: Mapping[str, Any]) -> Drift:
        return cls(stack=str(row["stack"]), type=str(row["type"]), name=str(row["name"]), status=row["status"],
                   changes=tuple((c["input"], c["applied"], c["cloud"]) for c in row.get("changes", ())),
                   detail=str(row.get("detail", "")))


@dataclass(frozen=True)
class Refresh:
    """The last refresh of a stack: when, and what differed from the applied document."""

    at: str  # UTC ISO 8601
    drift: tuple[Drift, ...]


def record(stack: str, *, outputs: Mapping[str, Any], observed: Mapping[str, Any],
           drift: list[Drift], now: float | None = None) -> Refresh:
    """Write what a refresh saw (the engine's refreshed outputs, the cloud's objects) and the drift."""
    at = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(time.time() if now is None else now))
    StackState(stack).write(REFRESHED_FILE, {
        "refreshed_at": at, "outputs": dict(outputs), "observed": dict(observed),
        "drift": [d.to_dict() for d in drift]})
    return Refresh(at, tuple(drift))


def load(stack: str) -> Refresh | None:
    """The stack's last refresh, or None when there was none since the last apply."""
    data = StackState(stack).read(REFRESHED_FILE)
    if not isinstance(data, dict):
        return None
    return Refresh(str(data.get("refreshed_at", "")), tuple(Drift.from_dict(r) for r in data.get("drift", ())))


def clear(stack: str) -> None:
    """An apply or destroy is about to change the cloud: the last refresh no longer describes it."""
    StackState(stack).remove(REFRESHED_FILE)
