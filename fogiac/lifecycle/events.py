"""Progress of long work as provider-neutral events, and the per-resource timers the CLI draws.

A target's engine speaks its own event language (Pulumi's engine events on ``aws``); the target
translates each into a :class:`Progress` before it reaches the lifecycle's ``on_event``, so the
CLI shows every target's progress the same way and imports none of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

Phase = Literal["start", "done", "failed", "diagnostic"]


@dataclass(frozen=True)
class Progress:
    """One step of one resource (``key`` tells resources apart), or a diagnostic line."""

    phase: Phase
    key: str = ""
    name: str = ""
    type: str = ""
    op: str = ""
    message: str = ""


OnEvent = Callable[[Progress], None]


@dataclass
class ResourceTimer:
    key: str
    type: str
    name: str
    op: str
    started: float
    finished: float | None = None
    failed: bool = False

    def elapsed(self, now: float) -> float:
        return (self.finished if self.finished is not None else now) - self.started


class Timers:
    """Per-resource timers fed by :class:`Progress` events; rendering is the CLI's job."""

    def __init__(self, *, clock: Callable[[], float]) -> None:
        self.clock = clock
        self.rows: dict[str, ResourceTimer] = {}
        self.diagnostics: list[str] = []

    def __call__(self, event: Progress) -> None:
        now = self.clock()
        if event.phase == "start":
            self.rows[event.key] = ResourceTimer(event.key, event.type, event.name, event.op, now)
        elif event.phase == "done" and event.key in self.rows:
            self.rows[event.key].finished = now
        elif event.phase == "failed" and event.key in self.rows:
            row = self.rows[event.key]
            row.finished, row.failed = now, True
        elif event.phase == "diagnostic" and event.message:
            self.diagnostics.append(event.message)

    def running(self) -> list[ResourceTimer]:
        return [r for r in self.rows.values() if r.finished is None]
