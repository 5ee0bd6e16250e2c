"""fogiac's state directory: keys, certificates, Pulumi backend, applied plans, locks.

It lives outside any repository (``$FOGIAC_STATE_DIR``, else ``~/.fogiac``), one folder per
stack (manifest name and environment), created 0700 because it holds private keys. A
:class:`StackState` owns one stack's folder: every file fogiac keeps there is named by it, once.

::

    stack.json        the deployment record (fogiac.deployment)        applied.json   what the last up applied
    deployment.json   the edge's links as the last up made them        refreshed.json what refresh saw
    lock.json         who holds the stack now                         known_hosts    the hosts' pinned keys
    certs/            the stack's CA and the edge's certificates       edge/          the edge's processes
    <target's own>    named by the target (the aws target's outputs.json, host-keys.json, pulumi/ ...)
"""

from __future__ import annotations

import json
import os
import socket
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any

from fogiac.errors import LockHeld, StateError
from fogiac.procs import same_process, start_time


def state_root() -> Path:
    root = os.environ.get("FOGIAC_STATE_DIR")
    return Path(root).expanduser() if root else Path.home() / ".fogiac"


def stack_dir(stack: str, *, create: bool = True) -> Path:
    """The folder for one stack (``<name>-<environment>``), 0700; never a path outside the root."""
    if not stack or "/" in stack or stack.startswith(".") or any(ord(c) < 32 for c in stack):
        raise StateError(f"{stack!r} is not a stack name")
    path = state_root() / stack
    if create:
        try:
            path.mkdir(parents=True, exist_ok=True, mode=0o700)
            os.chmod(path, 0o700)
        except OSError as err:
            raise StateError(f"cannot use state directory {path}: {err.strerror}") from None
    return path


def stack_names() -> list[str]:
    """The stacks that have a folder under the state root, sorted (reads the folder, creates nothing)."""
    root = state_root()
    try:
        return sorted(entry.name for entry in root.iterdir() if entry.is_dir() and not entry.name.startswith("."))
    except FileNotFoundError:
        return []


def write_atomic(path: Path, data: bytes, *, mode: int) -> None:
    """Write ``data`` whole or not at all, with ``mode`` from the first byte.

    A crash leaves either the old file or the new one; a 0600 file is never readable by others,
    not even for a moment. Every state, key and user-facing file fogiac writes goes through here.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, mode)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_json_atomic(path: Path, data: Any, *, mode: int = 0o600) -> None:
    """State as JSON (sorted, indented), written atomically."""
    write_atomic(path, (json.dumps(data, indent=2, sort_keys=True) + "\n").encode(), mode=mode)


def write_text_atomic(path: Path, text: str, *, mode: int = 0o644) -> None:
    """A user-facing file (a manifest, a plan) whole or not at all."""
    write_atomic(path, text.encode(), mode=mode)


def read_json(path: Path) -> Any | None:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as err:
        raise StateError(f"{path}: unreadable state file ({err})") from None


class StackState:
    """One stack's folder: a typed path for each file every target shares, and the stack's lock.

    Asking for a path creates nothing; :meth:`ensure` makes the folder (0700) for a writer.
    A target's own files live here too, named in its folder (:meth:`file`).
    """

    RECORD = "stack.json"
    APPLIED = "applied.json"
    DEPLOYMENT = "deployment.json"
    REFRESHED = "refreshed.json"
    LOCK = "lock.json"
    KNOWN_HOSTS = "known_hosts"
    CERTS = "certs"
    EDGE = "edge"

    def __init__(self, stack: str) -> None:
        self.stack = stack
        self.folder = stack_dir(stack, create=False)  # checks the name; creates nothing

    def __repr__(self) -> str:
        return f"StackState({self.stack!r})"

    def exists(self) -> bool:
        return self.folder.exists()

    def ensure(self) -> Path:
        """The folder, made (0700) if it is not there yet."""
        return stack_dir(self.stack)

    def file(self, name: str) -> Path:
        return self.folder / name

    @property
    def record(self) -> Path:
        return self.folder / self.RECORD

    @property
    def applied(self) -> Path:
        return self.folder / self.APPLIED

    @property
    def deployment(self) -> Path:
        return self.folder / self.DEPLOYMENT

    @property
    def refreshed(self) -> Path:
        return self.folder / self.REFRESHED

    @property
    def known_hosts(self) -> Path:
        return self.folder / self.KNOWN_HOSTS

    @property
    def certs(self) -> Path:
        return self.folder / self.CERTS

    @property
    def edge(self) -> Path:
        return self.folder / self.EDGE

    def read(self, name: str) -> Any | None:
        """A JSON file of the stack (None when it is not there)."""
        return read_json(self.folder / name)

    def write(self, name: str, data: Any) -> Path:
        """A JSON file of the stack, 0600, atomically; the folder is made if needed."""
        self.ensure()
        write_json_atomic(self.folder / name, data)
        return self.folder / name

    def remove(self, *names: str) -> None:
        for name in names:
            (self.folder / name).unlink(missing_ok=True)

    def lock(self, *, operation: str) -> AbstractContextManager[None]:
        return stack_lock(self.stack, operation=operation)


def _said(value: object) -> str:
    """A value read from a state file, for a message: one line, escapes shown, not obeyed."""
    text = str(value)
    return text if text.isprintable() else repr(text)[1:-1]


@contextmanager
def stack_lock(stack: str, *, operation: str) -> Iterator[None]:
    """Hold the stack's lock for ``operation``; a second holder fails at once, naming the first.

    The lock is a file created with O_EXCL holding who took it: pid and start time, as the supervisor's
    pid files. A lock whose process is gone (same host), or whose pid now names another process (its start
    time differs: the pid was reused after a crash or a reboot), is stale and taken over.
    """
    path = stack_dir(stack) / StackState.LOCK
    me = {"pid": os.getpid(), "started": start_time(os.getpid()), "host": socket.gethostname(),
          "operation": operation, "since": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    for _ in range(2):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            try:
                holder = read_json(path)
            except StateError:
                holder = None  # being written this instant, or garbage: named below, never taken over
            holder = holder if isinstance(holder, dict) else {}
            same_host = holder.get("host") == me["host"]
            pid, started = holder.get("pid"), holder.get("started")
            if same_host and isinstance(pid, int) and not isinstance(pid, bool) and pid > 0 \
                    and not same_process(pid, started if isinstance(started, str) else None):
                path.unlink(missing_ok=True)
                continue
            said = {k: _said(holder.get(k, "?")) for k in ("operation", "pid", "host", "since")}
            raise LockHeld(
                f"stack {stack!r} is locked by {said['operation']} (pid {said['pid']} on {said['host']} since "
                f"{said['since']}); wait for it or remove {path} if it is gone"
            ) from None
        with os.fdopen(fd, "w") as fh:
            json.dump(me, fh)
        break
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
