"""Pulumi engine events as the lifecycle's neutral :class:`~fogiac.lifecycle.events.Progress`.

The Automation API streams one event per step; ``up`` and ``down`` show a row per resource that
changes (not the stack itself, not what stays the same) with its timer, and the last error line.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fogiac.lifecycle.events import OnEvent, Progress
from fogiac.lifecycle.events import Timers as _Timers


def progress(event: Any) -> Progress | None:
    """A Pulumi engine event as the lifecycle's neutral :class:`Progress` (None: nothing to show)."""
    pre = getattr(event, "resource_pre_event", None)
    done = getattr(event, "res_outputs_event", None)
    failed = getattr(event, "res_op_failed_event", None)
    diag = getattr(event, "diagnostic_event", None)
    if pre is not None and not pre.planning and _shown(pre.metadata):
        meta = pre.metadata
        return Progress("start", meta.urn, meta.urn.rsplit("::", 1)[-1], meta.type,
                        str(getattr(meta.op, "value", meta.op)))
    if done is not None:
        return Progress("done", done.metadata.urn)
    if failed is not None:
        return Progress("failed", failed.metadata.urn)
    if diag is not None and diag.severity == "error" and diag.message.strip():
        return Progress("diagnostic", message=diag.message.strip().splitlines()[-1])
    return None


def translated(on_event: OnEvent | None) -> Callable[[Any], None] | None:
    """The engine's ``on_event``: each Pulumi event handed on as :class:`Progress`."""
    if on_event is None:
        return None

    def hand_on(event: Any) -> None:
        found = progress(event)
        if found is not None:
            on_event(found)
    return hand_on


class Timers(_Timers):
    """The neutral timers fed straight from Pulumi engine events (tests and tools that hold raw events)."""

    def __call__(self, event: Any) -> None:
        found = event if isinstance(event, Progress) else progress(event)
        if found is not None:
            super().__call__(found)


def _shown(meta: Any) -> bool:
    """Real changes to real resources (not the stack itself, not 'same')."""
    op = str(getattr(meta.op, "value", meta.op))
    return op not in {"same", "read"} and not meta.type.startswith("pulumi:")
