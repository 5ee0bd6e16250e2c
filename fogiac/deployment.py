"""What a stack is: the target it went to, the manifest that made it, and how far ``up`` got.

Every target writes this record on ``up``: :func:`begin` before the first thing is created
(state ``partial``), :func:`finish` when ``up`` completes (state ``complete``, with the plan
digest ``plan --detailed-exitcode`` compares against), and ``down`` marks it ``removed`` once
nothing is left (so a second ``down`` still knows where to look, and says nothing is there).
The CLI reads it before it picks a target, so ``status``, ``down``, ``logs``, ``ssh`` and
``plan --detailed-exitcode`` look where the deployment is, and a second manifest with the same
stack name cannot take the stack over by accident.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

from fogiac.errors import FogiacError
from fogiac.plan.model import Plan
from fogiac.state import StackState, read_json, write_json_atomic

RECORD_FILE = StackState.RECORD
PARTIAL = "partial"  # up started and did not finish (interrupted or failed): things may exist
COMPLETE = "complete"
REMOVED = "removed"  # down removed everything; the stack is free for any target or manifest


@dataclass(frozen=True)
class Deployment:
    stack: str
    target: str
    manifest: str  # absolute path of the manifest (or FogROS launch file) that made the stack
    state: str  # PARTIAL | COMPLETE | REMOVED
    since: str  # when the first up began, UTC ISO 8601
    since_epoch: float
    plan_digest: str = ""  # the plan document's digest at the last complete up

    @property
    def partial(self) -> bool:
        return self.state == PARTIAL

    @property
    def exists(self) -> bool:
        """Something of the stack may be there (up began and down has not removed it all)."""
        return self.state != REMOVED


def _path(stack: str) -> Path:
    return StackState(stack).record


def read(stack: str) -> Deployment | None:
    """The stack's record, or None if nothing was ever deployed (or all of it was removed)."""
    data = read_json(_path(stack))
    if not isinstance(data, dict):
        return None
    try:
        return Deployment(**data)
    except TypeError:
        raise FogiacError(f"{_path(stack)}: not a fogiac deployment record; remove it if the stack is gone") from None


def manifest_id(path: Path) -> str:
    return str(path.expanduser().resolve())


def begin(plan: Plan, manifest: Path) -> Deployment:
    """Record, before anything is created, that ``up`` of ``manifest`` to ``plan.target`` began."""
    old = read(plan.stack)
    old = old if old is not None and old.exists else None
    now = time.time()
    record = Deployment(
        stack=plan.stack, target=plan.target, manifest=manifest_id(manifest), state=PARTIAL,
        since=old.since if old else time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now)),
        since_epoch=old.since_epoch if old else now, plan_digest=old.plan_digest if old else "")
    StackState(plan.stack).write(RECORD_FILE, asdict(record))
    return record


def finish(plan: Plan, manifest: Path, *, plan_digest: str) -> Deployment:
    """``up`` completed: everything the plan asks for exists."""
    record = begin(plan, manifest)
    done = Deployment(**{**asdict(record), "state": COMPLETE, "plan_digest": plan_digest})
    StackState(plan.stack).write(RECORD_FILE, asdict(done))
    return done


def _mark(stack: str, state: str) -> None:
    record = read(stack)
    if record is not None:
        write_json_atomic(_path(stack), asdict(Deployment(**{**asdict(record), "state": state, "plan_digest": ""})))


def cut_back(stack: str) -> None:
    """Part of the stack was removed (``down --keep-network``): it is partial, and the plan would change."""
    _mark(stack, PARTIAL)


def removed(stack: str) -> None:
    """Nothing of the stack is left: the next up starts from scratch, on any target."""
    _mark(stack, REMOVED)


def forget(stack: str) -> None:
    """Up failed before it created anything: as if it never ran."""
    _path(stack).unlink(missing_ok=True)


def choose_target(stack: str, manifest: Path, requested: str | None, *, force_hint: bool,
                  force: bool = False, creating: bool = False) -> str | None:
    """The target a verb on ``stack`` must use: the recorded one, if the stack exists.

    A ``--target`` that disagrees with the deployment is refused, and so is a manifest other
    than the one that made the stack (unless ``force``; ``force_hint`` says the verb has
    ``--force``). Nothing deployed: ``requested`` (None: the manifest's own), except that a
    removed stack is still looked for where it was, by every verb but one that creates.
    """
    record = read(stack)
    if record is None:
        return requested
    if not record.exists:
        return requested if creating or requested else record.target
    mine = manifest_id(manifest)
    if record.manifest != mine and not force:
        hint = " (or pass --force to take it over)" if force_hint else ""
        raise FogiacError(f"stack {stack!r} was made by {record.manifest}, not {mine}; use that file, "
                          f"or give this one another name: or --env{hint}")
    if requested is not None and requested != record.target:
        raise FogiacError(f"stack {stack!r} is deployed to target {record.target}, not {requested}; "
                          f"drop --target, or `fogiac down` it first")
    return record.target
