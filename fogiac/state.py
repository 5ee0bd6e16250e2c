"""fogiac's state directory: keys, certificates, Pulumi backend, applied plans, locks.

It lives outside any repository (``$FOGIAC_STATE_DIR``, else ``~/.fogiac``), one folder per
stack (manifest name and environment), created 0700 because it holds private keys.
"""

from __future__ import annotations

import json
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from fogiac.errors import LockHeld, StateError
from fogiac.procs import pid_alive


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


@contextmanager
def stack_lock(stack: str, *, operation: str) -> Iterator[None]:
    """Hold the stack's lock for ``operation``; a second holder fails at once, naming the first.

    The lock is a file created with O_EXCL holding who took it; a lock whose process is gone
    (same host) is stale and taken over.
    """
    path = stack_dir(stack) / "lock.json"
    me = {"pid": os.getpid(), "host": socket.gethostname(), "operation": operation,
          "since": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    for _ in range(2):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            holder = read_json(path) or {}
            same_host = holder.get("host") == me["host"]
            if same_host and isinstance(holder.get("pid"), int) and not pid_alive(holder["pid"]):
                path.unlink(missing_ok=True)
                continue
            raise LockHeld(
                f"stack {stack!r} is locked by {holder.get('operation', '?')} "
                f"(pid {holder.get('pid', '?')} on {holder.get('host', '?')} since "
                f"{holder.get('since', '?')}); wait for it or remove {path} if it is gone"
            ) from None
        with os.fdopen(fd, "w") as fh:
            json.dump(me, fh)
        break
    try:
        yield
    finally:
        path.unlink(missing_ok=True)
