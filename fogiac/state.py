"""fogiac's state: one record per stack, its lock, and the stack's secret files.

A stack (manifest name and environment) has one record: a versioned JSON document that says what
is deployed, so every verb reads the same facts and a write replaces all of them at once.

::

    format_version, serial, lineage, stack, written_at   what the document is, which write, which stack's history
    deployment   target, manifest (path and digest), state partial/complete/removed, since (fogiac.deployment)
    applied      the plan document the last complete ``up`` applied (fogiac.plan.document)
    edges        a list of edges, each with its name, edge master, links host -> HOST:PORT and nodes
    hosts        each provisioned host: how it is reached (its access description), its base folder, its nodes

:class:`StackState` owns it: it reads and writes the record through a :class:`~fogiac.store.StateStore`
(get, compare-and-swap put, lock with holder, list, delete), so a second store (an object store
with conditional writes) changes where records live and nothing else. The only store today is
the stack folder (:class:`~fogiac.store.FolderStore`): ``$FOGIAC_STATE_DIR``, else ``~/.fogiac``,
one folder per stack, 0700 because it holds private keys. A folder an older fogiac wrote (four
files: ``stack.json``, ``applied.json``, ``deployment.json``, ``provision.json``) is read as one
record and migrated on the first write.

What is not record stays as files under the store's folder, each named once, here::

    record.json   the record                                 lock.json      who holds the stack now
    certs/        the stack's CA and the edge's certificates  known_hosts    the hosts' pinned keys
    edge/         the edge's processes                        ssh/           the stack's SSH key
    refreshed.json what refresh saw                           <target's own> named by the target
                                                              (aws: outputs.json, host-keys.json, pulumi/ ...)

Nothing outside this module and the store builds a path inside a stack's folder (a test checks).
"""

from __future__ import annotations

import getpass
import os
import shutil
import socket
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.errors import LockHeld, StateError
from fogiac.procs import same_process, start_time
from fogiac.store import (
    LEGACY_FILES,
    LOCK,
    MOVED,
    RECORD,
    FolderStore,
    Snapshot,
    StaleRecord,
    StateStore,
    check_name,
    dumps,
    open_store,
    read_json,
    state_root,
    write_atomic,
)

__all__ = ["FORMAT_VERSION", "LEGACY_FILES", "Section", "StackState", "StaleRecord", "StateStore", "changing",
           "read_json", "stack_dir", "stack_lock", "stack_names", "state_root", "untouched_on_failure", "write_atomic",
           "write_json_atomic", "write_text_atomic"]

FORMAT_VERSION = 1  # of the record document; a newer one is refused, never half-read


def default_store() -> StateStore:
    """The store records live in now: ``$FOGIAC_STATE_URL`` or the manifest's ``state:`` block, else the
    stack folder (see :func:`fogiac.store.open_store`)."""
    return open_store()


def stack_dir(stack: str, *, create: bool = True) -> Path:
    """The folder for one stack (``<name>-<environment>``), 0700; never a path outside the root."""
    return default_store().folder(stack, create=create)


def stack_names() -> list[str]:
    """The stacks the store holds, sorted (reads, creates nothing)."""
    return default_store().list()


def write_json_atomic(path: Path, data: Any, *, mode: int = 0o600) -> None:
    """State as JSON (sorted, indented), written atomically."""
    write_atomic(path, dumps(data), mode=mode)


def write_text_atomic(path: Path, text: str, *, mode: int = 0o644) -> None:
    """A user-facing file (a manifest, a plan) whole or not at all."""
    write_atomic(path, text.encode(), mode=mode)


@dataclass(frozen=True)
class Section:
    """One section of a record as read, and where it was read from (for a message naming the file)."""

    value: Any
    where: str


def _beside(name: str) -> str:
    """A file's name beside the record: never the record, the lock or an older layout's record file, which
    only the store writes (a section is written with :meth:`StackState.set`)."""
    if not name or "/" in name or name in (*LEGACY_FILES.values(), RECORD, LOCK):
        raise ValueError(f"{name!r} is not a name for a file beside the stack's record")
    return name


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


class StackState:
    """One stack: its record's sections, a typed path for each file every target shares, and its lock.

    Asking for a path creates nothing; :meth:`ensure` makes the folder (0700) for a writer.
    A target's own files live there too, named by the target (:meth:`target_file`).
    """

    RECORD = RECORD
    LOCK = LOCK
    # the record's sections
    DEPLOYMENT = "deployment"
    APPLIED = "applied"
    EDGES = "edges"
    HOSTS = "hosts"
    SECTIONS = (DEPLOYMENT, APPLIED, EDGES, HOSTS)
    # Beside the sections, never keeping a record alive alone: a fleet's robots revoked by hand (``fogiac robot
    # revoke``), refused by every cloud end until restored or dropped from the manifest.
    REVOKED = "revoked"
    # the files beside it
    REFRESHED = "refreshed.json"
    KNOWN_HOSTS = "known_hosts"
    CERTS = "certs"
    EDGE = "edge"
    SSH = "ssh"

    def __init__(self, stack: str, *, store: StateStore | None = None) -> None:
        self.stack = check_name(stack)
        self.store = store if store is not None else default_store()

    @classmethod
    def at(cls, folder: Path) -> StackState:
        """The stack whose folder is ``folder`` (provisioning is handed a folder, in tests any folder): the
        configured store's when that is its folder (a shared store's files are worked on in a local one)."""
        store = default_store()
        if not isinstance(store, FolderStore) and store.folder(folder.name) == folder:
            return cls(folder.name, store=store)
        return cls(folder.name, store=FolderStore(folder.parent))

    def __repr__(self) -> str:
        return f"StackState({self.stack!r})"

    # -- files -----------------------------------------------------------------------------------------

    @property
    def folder(self) -> Path:
        return self.store.folder(self.stack)

    def exists(self) -> bool:
        return self.folder.exists()

    def ensure(self) -> Path:
        """The folder, made (0700) if it is not there yet."""
        return self.store.folder(self.stack, create=True)

    def target_file(self, name: str, *, create: bool = False) -> Path:
        """A file (or folder) a target keeps for the stack, by the target's own name for it; ``create``
        makes the stack's folder first."""
        return (self.ensure() if create else self.folder) / _beside(name)

    @property
    def known_hosts(self) -> Path:
        return self.folder / self.KNOWN_HOSTS

    @property
    def certs(self) -> Path:
        return self.folder / self.CERTS

    @property
    def edge(self) -> Path:
        return self.folder / self.EDGE

    @property
    def ssh_dir(self) -> Path:
        return self.folder / self.SSH

    def read(self, name: str) -> Any | None:
        """A JSON file of the stack beside the record (None when it is not there)."""
        return read_json(self.folder / name)

    def write(self, name: str, data: Any) -> Path:
        """A JSON file of the stack beside the record, 0600, atomically; the folder is made if needed."""
        self.ensure()
        write_json_atomic(self.folder / _beside(name), data)
        return self.folder / name

    def remove(self, *names: str) -> None:
        for name in names:
            (self.folder / _beside(name)).unlink(missing_ok=True)

    def discard(self) -> None:
        """The whole stack: record, lock and files (an ``up`` that made the folder and failed at once)."""
        self.store.delete(self.stack)
        shutil.rmtree(self.folder, ignore_errors=True)

    def files(self) -> dict[str, Path]:
        """The files beside the record by path in the folder (not the record, lock, a moved note or scratch)."""
        out: dict[str, Path] = {}
        if not self.folder.is_dir():
            return out
        for path in sorted(self.folder.rglob("*")):
            rel = path.relative_to(self.folder)
            if path.is_file() and not path.is_symlink() and not any(p.startswith(".") for p in rel.parts) \
                    and rel.as_posix() not in (RECORD, LOCK, MOVED, *LEGACY_FILES.values()):
                out[rel.as_posix()] = path
        return out

    def copy_files(self, into: Path) -> int:
        """The files beside the record, copied under ``into`` (0600, folders 0700); how many."""
        for rel, path in self.files().items():
            target = into.joinpath(*rel.split("/"))
            target.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
            write_atomic(target, path.read_bytes(), mode=(path.stat().st_mode & 0o700) | 0o600)
        return len(self.files())

    def leave_for(self, note: dict[str, Any]) -> None:
        """The stack's state went elsewhere (``fogiac state migrate``): its files go, a note says where."""
        for path in sorted(self.folder.iterdir()) if self.folder.is_dir() else ():
            if path.name != LOCK:
                shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()
        write_atomic(self.folder / MOVED, dumps(note), mode=0o600)

    def clear_moved(self) -> None:
        """Forget the note that the state went elsewhere (``fogiac state migrate`` brings it back here)."""
        shared = getattr(self.store, "clear_moved", None)
        if shared is not None:
            shared(self.stack)
        else:
            (self.folder / MOVED).unlink(missing_ok=True)

    def lock_holder(self) -> dict[str, Any] | None:
        """Who holds the stack's lock now (``{}``: unreadable), or None; read without taking it."""
        reader = getattr(self.store, "lock_holder", None)
        if reader is not None:
            found: dict[str, Any] | None = reader(self.stack)
            return found
        path = self.folder / LOCK
        if not path.exists():
            return None
        try:
            data = read_json(path)
        except StateError:
            return {}
        return data if isinstance(data, dict) else {}

    # -- the record ------------------------------------------------------------------------------------

    def where(self, section: str | None = None) -> str:
        """Where the record (or one section of it) is kept, for a message."""
        where = self.store.where(self.stack)
        return where if section is None else f"{where} (section {section})"

    def snapshot(self) -> Snapshot:
        """The record and its version, as the store holds it now (an older layout's files read as one)."""
        snap = self.store.get(self.stack)
        if snap.document is not None and not snap.origin:
            version = snap.document.get("format_version")
            where = self.store.where(self.stack)
            if not isinstance(version, int) or isinstance(version, bool):
                raise StateError(f"{where}: not a fogiac stack record (format_version is "
                                 f"{'missing' if version is None else 'not a number'}); remove it if the stack is gone")
            if version > FORMAT_VERSION:
                raise StateError(f"{where}: written by a newer fogiac (record format {version}, this one reads "
                                 f"{FORMAT_VERSION}); upgrade fogiac")
        return snap

    def section(self, name: str) -> Section | None:
        """One section of the record, or None when the record has none (a JSON null is a value, not none)."""
        snap = self.snapshot()
        if snap.document is None or name not in snap.document:
            return None
        return Section(snap.document[name], snap.origin.get(name) or self.where(name))

    def get(self, name: str) -> Any | None:
        """One section's value, unchecked (None when absent)."""
        found = self.section(name)
        return found.value if found is not None else None

    def update(self, change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
        """Read the record, let ``change`` edit its sections, and write it back if nobody wrote meanwhile.

        Every write goes through here: the serial counts writes, the lineage (made once) tells this
        stack's history from another of the same name, and an older layout is migrated by the write.
        A record left with no section is deleted. Another writer between the read and the write: the
        store refuses the put (:class:`~fogiac.store.StaleRecord`), nothing is lost.
        """
        snap = self.snapshot()
        document = dict(snap.document or {})
        change(document)
        if not any(name in document for name in self.SECTIONS):
            if snap.version is not None:
                self.store.delete(self.stack)
            return document
        document.update(format_version=FORMAT_VERSION, stack=self.stack,
                        lineage=str(document.get("lineage") or uuid.uuid4()),
                        serial=int(document.get("serial") or 0) + 1, written_at=_now())
        if not self.store.reclaims_dead_holders:  # a shared store: which member wrote it
            document["written_by"] = f"{_user()}@{socket.gethostname()}"
        self.store.put(self.stack, document, expected=snap.version)
        return document

    def set(self, name: str, value: Any) -> None:
        """Replace one section."""
        if name not in self.SECTIONS:
            raise ValueError(f"{name!r} is not a section of a stack record")
        self.update(lambda document: document.__setitem__(name, value))

    def drop(self, *names: str) -> None:
        """Remove sections (the record goes with the last one)."""
        def change(document: dict[str, Any]) -> None:
            for name in names:
                document.pop(name, None)

        if self.section_names() & frozenset(names):
            self.update(change)

    def section_names(self) -> frozenset[str]:
        """The sections the record has now."""
        snap = self.snapshot()
        return frozenset(name for name in self.SECTIONS if snap.document is not None and name in snap.document)

    # -- the lock --------------------------------------------------------------------------------------

    @contextmanager
    def lock(self, *, operation: str) -> Iterator[None]:
        """Hold the stack's lock for ``operation``; a second holder fails at once, naming the first.

        The lock holds who took it: pid and start time, as the supervisor's pid files. Where the store
        allows it, a lock whose process is gone (same host), or whose pid now names another process (its
        start time differs: the pid was reused after a crash or a reboot), is stale and taken over.
        """
        me = {"pid": os.getpid(), "started": start_time(os.getpid()), "host": socket.gethostname(),
              "operation": operation, "since": _now()}
        if not self.store.reclaims_dead_holders:  # a shared store: say who, from where, doing what
            me.update(user=_user(), cwd=os.getcwd(), command=" ".join(["fogiac", *sys.argv[1:]])[:300])
        holder = self.store.acquire(self.stack, me)
        if holder is not None and self.store.reclaims_dead_holders and _gone(holder, host=str(me["host"])):
            self.store.break_lock(self.stack, holder)
            holder = self.store.acquire(self.stack, me)  # another may have taken it meanwhile: named below
        if holder is not None and not self.store.reclaims_dead_holders:
            raise LockHeld(f"stack {self.stack!r} is locked: {held_by(holder)}; wait for it, or if that process is "
                           f"gone, `fogiac state unlock {self.stack}` breaks the lock") from None
        if holder is not None:
            said = {k: _said(holder.get(k, "?")) for k in ("operation", "pid", "host", "since")}
            raise LockHeld(
                f"stack {self.stack!r} is locked by {said['operation']} (pid {said['pid']} on {said['host']} since "
                f"{said['since']}); wait for it or remove {self.store.where(self.stack, LOCK)} if it is gone"
            ) from None
        try:
            yield
        finally:
            self.store.release(self.stack, me)


def _gone(holder: dict[str, Any], *, host: str) -> bool:
    """The holder is a process of this machine that no longer runs (or its pid now names another)."""
    pid, started = holder.get("pid"), holder.get("started")
    return holder.get("host") == host and isinstance(pid, int) and not isinstance(pid, bool) and pid > 0 \
        and not same_process(pid, started if isinstance(started, str) else None)


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return str(os.getuid())


def held_by(holder: dict[str, Any]) -> str:
    """A lock's holder in one line: who (user@host), which command, since when, where (pid, folder)."""
    if not holder:
        return "by an unreadable lock"
    said = {k: _said(holder.get(k, "?")) for k in ("user", "host", "operation", "since", "pid", "cwd", "command")}
    who = f"{said['user']}@{said['host']}" if "user" in holder else said["host"]
    return (f"{said['operation']} by {who} since {said['since']} (pid {said['pid']}"
            + (f", in {said['cwd']}: {said['command']}" if "command" in holder else "") + ")")


def _said(value: object) -> str:
    """A value read from a state file, for a message: one line, escapes shown, not obeyed."""
    text = str(value)
    return text if text.isprintable() else repr(text)[1:-1]


def stack_lock(stack: str, *, operation: str) -> AbstractContextManager[None]:
    """Hold ``stack``'s lock for ``operation`` (see :meth:`StackState.lock`)."""
    return StackState(stack).lock(operation=operation)


@contextmanager
def untouched_on_failure(stack: str) -> Iterator[Callable[[], None]]:
    """Remove the stack folder again if this run created it and fails before ``commit()``."""
    existed = StackState(stack).exists()
    committed = False

    def commit() -> None:
        nonlocal committed
        committed = True

    try:
        yield commit
    except BaseException:
        path = StackState(stack).folder
        if not existed and not committed and path.exists():
            shutil.rmtree(path, ignore_errors=True)
        raise


@contextmanager
def changing(stack: str, *, operation: str) -> Iterator[Callable[[], None]]:
    """Change ``stack`` for ``operation`` (``up``, ``down``): under its lock (:func:`stack_lock`), and if this
    run made the stack's folder and fails before it calls the ``commit()`` it is handed, the folder goes
    again (:func:`untouched_on_failure`), so a refused first ``up`` leaves nothing behind."""
    with untouched_on_failure(stack) as commit, stack_lock(stack, operation=operation):
        yield commit
