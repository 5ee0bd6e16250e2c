"""What a stack is: the target it went to, the manifest that made it, and how far ``up`` got.

It is the ``deployment`` section of the stack's one record (:mod:`fogiac.state`), beside the
applied plan (:func:`read_applied`). Every target writes it on ``up``: :func:`begin` before the
first thing is created (state ``partial``), :func:`finish` when ``up`` completes (state
``complete``, with the plan digest ``plan --detailed-exitcode`` compares against, and the applied
plan in the same write), and ``down`` marks it ``removed`` once
nothing is left (so a second ``down`` still knows where to look, and says nothing is there).
The CLI reads it before it picks a target, so ``status``, ``down``, ``logs``, ``ssh`` and
``plan --detailed-exitcode`` look where the deployment is, and a second manifest with the same
stack name cannot take the stack over by accident.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from fogiac.errors import FogiacError, StateError
from fogiac.plan.model import Plan
from fogiac.state import StackState

RECORD_FILE = StackState.RECORD  # the stack's one record, whose deployment section this module keeps
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
    manifest_digest: str = ""  # sha256 of the manifest's bytes at the last up (a record of an older fogiac: "")

    @property
    def partial(self) -> bool:
        return self.state == PARTIAL

    @property
    def exists(self) -> bool:
        """Something of the stack may be there (up began and down has not removed it all)."""
        return self.state != REMOVED


def shown(text: str) -> str:
    """A path or name read from a state file, for a message: one line, control characters escaped
    (a record's manifest path with a newline or a terminal escape is printed as written, not obeyed)."""
    return text if text.isprintable() else repr(text)[1:-1]


def _kind(value: Any, want: type | tuple[type, ...]) -> bool:
    return isinstance(value, want) and not isinstance(value, bool)


def read(stack: str) -> Deployment | None:
    """The stack's deployment, or None if nothing was ever deployed (no record, or none in it).

    A section (or an older fogiac's ``stack.json``) that is not a deployment (null, a list, a field of
    the wrong type, an unknown state) is an error in one line: taking it as "no record" would send
    status and down to the manifest's target.
    """
    found = StackState(stack).section(StackState.DEPLOYMENT)
    if found is None:
        return None
    data = found.value
    bad = f"{found.where}: not a fogiac deployment record"
    hint = "; remove it if the stack is gone"
    if not isinstance(data, dict):
        raise StateError(f"{bad} (a JSON {type(data).__name__ if data is not None else 'null'}){hint}")
    want: dict[str, type | tuple[type, ...]] = {f.name: str for f in fields(Deployment)}
    want["since_epoch"] = (int, float)
    required = {f.name for f in fields(Deployment) if f.name not in ("plan_digest", "manifest_digest")}
    for name in sorted(required - set(data)):
        raise StateError(f"{bad} ({name} is missing){hint}")
    for name in sorted(data):
        if name not in want:
            raise StateError(f"{bad} (unknown field {shown(str(name))!r}){hint}")
        if not _kind(data[name], want[name]):
            raise StateError(f"{bad} ({name} should be {'a number' if name == 'since_epoch' else 'a string'}){hint}")
    if data["state"] not in (PARTIAL, COMPLETE, REMOVED):
        raise StateError(f"{bad} (state {shown(data['state'])!r}){hint}")
    if data["stack"] != stack:
        raise StateError(f"{bad} of stack {stack!r} (it names {shown(data['stack'])!r}){hint}")
    return Deployment(**data)


_APPLIED_SECTIONS = ("resources", "hosts", "nodes", "topics", "security_rules")


def read_applied(stack: str) -> dict[str, Any] | None:
    """The plan document the last complete ``up`` applied, or None when there is none.

    A section (or an older fogiac's file) that is not such a document (null, a list, a section that
    is not a list of mappings, a cost that is not a mapping) is an error in one line, not a traceback
    in the diff."""
    found = StackState(stack).section(StackState.APPLIED)
    if found is None:
        return None
    data, path = found.value, found.where
    hint = "; the next `fogiac up` writes it again, or remove it"
    if not isinstance(data, dict):
        kind = type(data).__name__ if data is not None else "null"
        raise StateError(f"{path}: not a plan document fogiac applied (a JSON {kind}){hint}")
    for name in _APPLIED_SECTIONS:
        value = data.get(name, [])
        if not isinstance(value, list) or not all(isinstance(row, Mapping) for row in value):
            raise StateError(f"{path}: not a plan document fogiac applied ({name} is not a list of mappings){hint}")
    cost = data.get("cost", {})
    if not isinstance(cost, Mapping) or not all(_kind(cost.get(k, 0.0), (int, float)) or cost.get(k) is None
                                                for k in ("hourly_usd", "spot_hourly_usd")):
        raise StateError(f"{path}: not a plan document fogiac applied (cost is not a mapping of figures){hint}")
    return data


def applied_where(stack: str) -> str:
    """Where the applied document is kept (its record section, or an older fogiac's file), for a message."""
    found = StackState(stack).section(StackState.APPLIED)
    return found.where if found is not None else StackState(stack).where(StackState.APPLIED)


def manifest_id(path: Path) -> str:
    return str(path.expanduser().resolve())


def _digest(manifest: Path) -> str:
    try:
        return hashlib.sha256(manifest.expanduser().read_bytes()).hexdigest()
    except OSError:
        return ""  # a manifest gone since it was compiled: the path still says which it was


def _begun(plan: Plan, manifest: Path) -> Deployment:
    old = read(plan.stack)
    old = old if old is not None and old.exists else None
    now = time.time()
    return Deployment(
        stack=plan.stack, target=plan.target, manifest=manifest_id(manifest), state=PARTIAL,
        since=old.since if old else time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now)),
        since_epoch=old.since_epoch if old else now, plan_digest=old.plan_digest if old else "",
        manifest_digest=_digest(manifest))


def begin(plan: Plan, manifest: Path) -> Deployment:
    """Record, before anything is created, that ``up`` of ``manifest`` to ``plan.target`` began."""
    record = _begun(plan, manifest)
    StackState(plan.stack).set(StackState.DEPLOYMENT, asdict(record))
    return record


@contextmanager
def begun(plan: Plan, manifest: Path, *, existed: bool) -> Iterator[None]:
    """Record that ``up`` of ``manifest`` began (:func:`begin`) around the check of the robot's side, which comes
    before anything is made: if that fails, the record goes back to what it was (:func:`undo_begin`; ``existed``:
    the stack's folder was there before this run). Interrupted instead, the record stays partial: a master may
    have started, and ``down`` stops it."""
    before = read(plan.stack)
    begin(plan, manifest)
    try:
        yield
    except FogiacError:
        undo_begin(plan.stack, before, existed=existed)
        raise


def finish(plan: Plan, manifest: Path, *, plan_digest: str, applied: Mapping[str, Any] | None = None) -> Deployment:
    """``up`` completed: everything the plan asks for exists; ``applied``, the plan document it applied,
    is recorded in the same write."""
    done = Deployment(**{**asdict(_begun(plan, manifest)), "state": COMPLETE, "plan_digest": plan_digest})

    def change(document: dict[str, Any]) -> None:
        document[StackState.DEPLOYMENT] = asdict(done)
        if applied is not None:
            document[StackState.APPLIED] = dict(applied)

    StackState(plan.stack).update(change)
    return done


def _mark(stack: str, state: str) -> None:
    record = read(stack)
    if record is not None:
        StackState(stack).set(StackState.DEPLOYMENT, asdict(Deployment(**{**asdict(record), "state": state,
                                                                           "plan_digest": ""})))


def cut_back(stack: str) -> None:
    """Part of the stack was removed (``down --keep-network``): it is partial, and the plan would change."""
    _mark(stack, PARTIAL)


def removed(stack: str) -> None:
    """Nothing of the stack is left: the next up starts from scratch, on any target."""
    _mark(stack, REMOVED)


def forget(stack: str) -> None:
    """Up failed before it created anything: as if it never ran."""
    StackState(stack).drop(StackState.DEPLOYMENT)


def stack_for(names: tuple[str, str | None], manifest: Path) -> str:
    """Which of a manifest's stack names (:func:`fogiac.plan.compile.stack_names`: the name, and the one of
    before ``--`` or None) its stack has: one deployed under the older naming (an environment with a '-' was
    joined with a single '-') keeps its old name while its record names ``manifest`` and nothing took the new one."""
    new, old = names
    if old is None or read(new) is not None:
        return new
    record = read(old)
    return old if record is not None and record.exists and record.manifest == manifest_id(manifest) else new


def locate(names: tuple[str, str | None], manifest: Path, requested: str | None, *, force_hint: bool,
           force: bool = False, creating: bool = False) -> tuple[str, str | None]:
    """Where a verb on ``manifest`` acts, from the records alone: its stack (:func:`stack_for`) and the target
    it must use (:func:`choose_target`), in one place."""
    stack = stack_for(names, manifest)
    return stack, choose_target(stack, manifest, requested, force_hint=force_hint, force=force, creating=creating)


def undo_begin(stack: str, before: Deployment | None, *, existed: bool) -> None:
    """``up`` failed after :func:`begin` and before anything was made (the robot's side did not answer): the
    stack's folder goes if this run made it, else the record goes back to what it was (none, or removed)."""
    if not existed:
        StackState(stack).discard()
    elif before is None:
        forget(stack)
    elif not before.exists:
        removed(stack)


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
    # a shared store's record names the path on the member's machine that wrote it: each member's checkout
    # of the lab's manifest sits elsewhere (the stack's name already says which manifest and environment)
    if record.manifest != mine and not force and StackState(stack).store.reclaims_dead_holders:
        hint = " (or pass --force to take it over)" if force_hint else ""
        raise FogiacError(f"stack {stack!r} was made by {shown(record.manifest)}, not {shown(mine)}; use that file, "
                          f"or give this one another name: or --env{hint}")
    if requested is not None and requested != record.target:
        raise FogiacError(f"stack {stack!r} is deployed to target {record.target}, not {requested}; "
                          f"drop --target, or `fogiac down` it first")
    return record.target
