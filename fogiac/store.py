"""Where stack records are kept: the :class:`StateStore` protocol and the stack-folder store.

A stack's record is one JSON document (see :mod:`fogiac.state`). A store keeps it and the stack's
lock, and nothing more than a key-value service with conditional writes can offer: ``get`` hands
back the document with a version token, ``put`` writes only if the token still matches (as S3's
``If-Match`` on an ETag, or ``If-None-Match: *`` for a record that must not exist yet), and the
lock is an object created only if absent, holding who took it. So an object store implements the
same protocol with the same guarantees: a writer that read an older version is refused, never
silently overwrites, and a crash leaves the old document or the new one.

Secret material (certificates, keys, known hosts, a target's own files) is not part of the record:
it stays as files in the stack's local folder, which the store names (:meth:`StateStore.folder`).

:class:`FolderStore` keeps each stack in ``<root>/<stack>/``: ``record.json`` and ``lock.json``. A
folder written by fogiac before the one record (four files: ``stack.json``, ``applied.json``,
``deployment.json``, ``provision.json``) is read as one document, and replaced by ``record.json``
on its first write.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import signal
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from fogiac import registry
from fogiac.errors import StateError

STATE_URL = "FOGIAC_STATE_URL"  # where a lab's shared records live (s3://BUCKET/PREFIX); unset: the folder
STATE_KMS_KEY = "FOGIAC_STATE_KMS_KEY"  # the KMS key a shared store seals key material under (else a passphrase)
STORES = "fogiac.stores"  # URL scheme -> a StateStore class with from_url(url, kms_key=...)
# Test-only: ``N`` makes the process SIGKILL itself right after its Nth write to a store (record put, lock
# taken, record or lock removed), so a test can show that a ``kill -9`` at each such point leaves a record
# that parses and a lock that names its dead holder. Unset (always, outside tests): nothing happens.
TEST_KILL_AFTER_WRITES = "FOGIAC_TEST_SIGKILL_AFTER_STORE_WRITE"
MOVED = "moved.json"  # in a stack folder whose state `fogiac state migrate` sent elsewhere
RECORD = "record.json"
LOCK = "lock.json"
# The files a stack's record was split into before it was one document: section -> file name.
LEGACY_FILES: Mapping[str, str] = {"deployment": "stack.json", "applied": "applied.json",
                                   "edges": "deployment.json", "hosts": "provision.json"}


_writes = 0


def wrote() -> None:
    """Count one write a store made; with ``$FOGIAC_TEST_SIGKILL_AFTER_STORE_WRITE`` set to this count,
    SIGKILL this process (tests of ``kill -9`` at each write; inert unless that variable is set)."""
    global _writes
    after = os.environ.get(TEST_KILL_AFTER_WRITES)
    if not after:
        return
    _writes += 1
    if str(_writes) == after.strip():
        os.kill(os.getpid(), signal.SIGKILL)


def state_root() -> Path:
    root = os.environ.get("FOGIAC_STATE_DIR")
    return Path(root).expanduser() if root else Path.home() / ".fogiac"


def check_name(stack: str) -> str:
    """A stack name is one path component of printable characters: never a path outside the store."""
    if not stack or "/" in stack or stack.startswith(".") or any(ord(c) < 32 for c in stack):
        raise StateError(f"{stack!r} is not a stack name")
    return stack


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


def make_private(path: Path) -> Path:
    """``path`` as a folder only its owner may enter (0700, also when it was there already); one line if not."""
    try:
        path.mkdir(parents=True, exist_ok=True, mode=0o700)
        os.chmod(path, 0o700)
    except OSError as err:
        raise StateError(f"cannot use state directory {path}: {err.strerror}") from None
    return path


def dumps(data: Any) -> bytes:
    """State as fogiac writes it: JSON, sorted, indented, one trailing newline."""
    return (json.dumps(data, indent=2, sort_keys=True) + "\n").encode()


def read_json(path: Path) -> Any | None:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as err:
        raise StateError(f"{path}: unreadable state file ({err})") from None


class StaleRecord(StateError):
    """``put`` was given a version the store no longer holds: another writer came first."""


@dataclass(frozen=True)
class Snapshot:
    """A record as read: the document (None: the stack has none), its version token for ``put``, and
    where each section was read from when that is not the record itself (an older layout's file)."""

    document: dict[str, Any] | None
    version: str | None  # opaque; None only when there is no record
    origin: Mapping[str, str] = field(default_factory=dict)


class StateStore(Protocol):
    """What fogiac asks of wherever stack records live. Each call is one request to the store.

    ``put(..., expected=None)`` creates and fails if a record exists; ``expected=<version>`` replaces
    and fails (:class:`StaleRecord`) unless the record is still that version. ``acquire`` creates the
    lock only if there is none and returns None, else returns the holder it found (``{}`` if unreadable);
    ``release`` drops the lock its holder took; ``break_lock`` removes a lock only while it still names the
    holder given (a dead one, by the caller's judgement). ``where`` names the record (or the lock) for a
    message; ``folder`` is the local folder for the stack's files that are not record: keys, certificates.
    """

    #: a lock whose holder is a process gone from this very machine may be broken without asking
    reclaims_dead_holders: bool

    def get(self, stack: str) -> Snapshot: ...

    def put(self, stack: str, document: Mapping[str, Any], *, expected: str | None) -> str: ...

    def delete(self, stack: str) -> None: ...

    def list(self) -> list[str]: ...

    def acquire(self, stack: str, holder: Mapping[str, Any]) -> dict[str, Any] | None: ...

    def release(self, stack: str, holder: Mapping[str, Any]) -> None: ...

    def break_lock(self, stack: str, holder: Mapping[str, Any]) -> None: ...

    def where(self, stack: str, name: str = RECORD) -> str: ...

    def folder(self, stack: str, *, create: bool = False) -> Path: ...


def _digest(*parts: bytes) -> str:
    hashed = hashlib.sha256()
    for part in parts:
        hashed.update(len(part).to_bytes(8, "big") + part)
    return hashed.hexdigest()


class FolderStore:
    """Stack records in folders under ``root`` (0700, as they sit beside private keys).

    The version token is the record's SHA-256, as an object store's ETag is its content's digest;
    ``put`` compares and replaces under an exclusive ``flock`` of the stack's folder, so two
    processes on this machine cannot both replace the version they read.
    """

    reclaims_dead_holders = True

    def __init__(self, root: Path | None = None) -> None:
        self._root = root

    @property
    def root(self) -> Path:
        return self._root if self._root is not None else state_root()

    def __repr__(self) -> str:
        return f"FolderStore({str(self.root)!r})"

    def folder(self, stack: str, *, create: bool = False) -> Path:
        path = self.root / check_name(stack)
        return make_private(path) if create else path

    def where(self, stack: str, name: str = RECORD) -> str:
        return str(self.folder(stack) / name)

    # -- the record ------------------------------------------------------------------------------------

    def _read(self, folder: Path) -> tuple[dict[str, Any] | None, str | None, dict[str, str]]:
        path = folder / RECORD
        try:
            raw = path.read_bytes()
        except FileNotFoundError:
            return self._read_legacy(folder)
        except OSError as err:
            raise StateError(f"{path}: unreadable state file ({err.strerror})") from None
        try:
            document = json.loads(raw)
        except ValueError as err:
            raise StateError(f"{path}: unreadable state file ({err})") from None
        if not isinstance(document, dict):
            kind = type(document).__name__ if document is not None else "null"
            raise StateError(f"{path}: not a fogiac stack record (a JSON {kind}); remove it if the stack is gone")
        return document, "sha256:" + _digest(raw), {}

    def _read_legacy(self, folder: Path) -> tuple[dict[str, Any] | None, str | None, dict[str, str]]:
        """The four files of an older fogiac as one document (each section as its file held it)."""
        document: dict[str, Any] = {}
        origin: dict[str, str] = {}
        raws: list[bytes] = []
        for section, name in LEGACY_FILES.items():
            path = folder / name
            try:
                raw = path.read_bytes()
            except FileNotFoundError:
                raws.append(b"")
                continue
            except OSError as err:
                raise StateError(f"{path}: unreadable state file ({err.strerror})") from None
            raws.append(raw)
            data = read_json(path)
            origin[section] = str(path)
            if section == "edges":  # today's one edge, named after the stack, as a list of one
                data = [{"name": folder.name, **data}] if isinstance(data, dict) else data
            elif section == "hosts":
                data = data.get("hosts") if isinstance(data, dict) else data
            document[section] = data
        if not origin:
            return None, None, {}
        return document, "legacy:" + _digest(*raws), origin

    def get(self, stack: str) -> Snapshot:
        folder = self.folder(stack)
        document, version, origin = self._read(folder)
        if document is None and (folder / MOVED).exists():
            raise StateError(moved_line(stack, folder / MOVED))
        return Snapshot(document, version, origin)

    @contextlib.contextmanager
    def _exclusive(self, folder: Path) -> Iterator[None]:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)  # closing releases the flock

    def put(self, stack: str, document: Mapping[str, Any], *, expected: str | None) -> str:
        """Write the record if it is still ``expected``; an older layout's files go once it is written."""
        folder = self.folder(stack, create=True)
        data = dumps(document)
        with self._exclusive(folder):
            _, current, _ = self._read(folder)
            if current != expected:
                raise StaleRecord(f"{folder / RECORD}: the stack's record changed since it was read "
                                  "(another fogiac wrote it); nothing was written, run the command again")
            write_atomic(folder / RECORD, data, mode=0o600)
            (folder / MOVED).unlink(missing_ok=True)  # migrated back here
            for name in LEGACY_FILES.values():  # migrated (or left by a crash right after migrating)
                (folder / name).unlink(missing_ok=True)
        wrote()
        return "sha256:" + _digest(data)

    def delete(self, stack: str) -> None:
        folder = self.folder(stack)
        if not folder.exists():
            return
        with self._exclusive(folder):
            for name in (RECORD, *LEGACY_FILES.values()):
                (folder / name).unlink(missing_ok=True)
        wrote()

    def list(self) -> list[str]:
        """The stacks that have a folder, sorted (reads the root, creates nothing)."""
        try:
            return sorted(entry.name for entry in self.root.iterdir()
                          if entry.is_dir() and not entry.name.startswith("."))
        except FileNotFoundError:
            return []

    # -- the lock --------------------------------------------------------------------------------------

    def acquire(self, stack: str, holder: Mapping[str, Any]) -> dict[str, Any] | None:
        path = self.folder(stack, create=True) / LOCK
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            try:
                found = read_json(path)
            except StateError:
                found = None  # being written this instant, or garbage: named as unknown, never taken over
            return found if isinstance(found, dict) else {}
        with os.fdopen(fd, "w") as fh:
            json.dump(dict(holder), fh)
        wrote()
        return None

    def release(self, stack: str, holder: Mapping[str, Any]) -> None:
        """Drop the lock ``holder`` took (on this machine nobody else can have taken over a live holder's)."""
        (self.folder(stack) / LOCK).unlink(missing_ok=True)
        wrote()

    def break_lock(self, stack: str, holder: Mapping[str, Any]) -> None:
        """Remove the lock if it still names ``holder`` (one that took it over meanwhile keeps it)."""
        path = self.folder(stack) / LOCK
        try:
            found = read_json(path)
        except StateError:
            return
        if found == dict(holder):
            path.unlink(missing_ok=True)


def moved_line(stack: str, note_file: Path) -> str:
    """The one line a stack folder says once ``fogiac state migrate`` sent its state elsewhere."""
    try:
        note = json.loads(note_file.read_text())
    except (OSError, ValueError):
        note = {}
    to = str(note.get("moved_to", "?")) if isinstance(note, dict) else "?"
    return (f"stack {stack!r}: its state moved to {to} (fogiac state migrate); "
            f"set {STATE_URL}={to} to use it there")


# -- which store ---------------------------------------------------------------------------------------

_manifest_state: dict[str, str | None] = {}  # the loaded manifest's `state:` block, when it has one
_opened: dict[tuple[str, ...], StateStore] = {}


def configure(url: str | None, kms_key: str | None = None) -> None:
    """The manifest's ``state: {url, kms_key}`` (the CLI calls this once it loaded the manifest);
    ``$FOGIAC_STATE_URL`` still wins. ``url=None`` forgets it."""
    _manifest_state.clear()
    if url:
        _manifest_state.update(url=url, kms_key=kms_key)


def configured_url() -> str | None:
    """Where records live, as configured now: the environment, else the manifest; None: the folder."""
    return os.environ.get(STATE_URL) or _manifest_state.get("url") or None


def open_store(url: str | None = None, *, kms_key: str | None = None) -> StateStore:
    """The store for ``url`` (default: :func:`configured_url`): the stack folder when none is set, else the
    store its scheme's ``fogiac.stores`` entry point names (``s3://``: the aws target's), one per process
    and configuration (a store keeps its client and what it pulled). ``kms_key`` (default: ``$FOGIAC_STATE_KMS_KEY``,
    else the manifest's ``state.kms_key`` when ``url`` is the manifest's) seals the stack's key material."""
    env_url = os.environ.get(STATE_URL)
    if url is None:
        url = configured_url()
    if kms_key is None:  # a URL named outright (`state migrate --to`, `--url`) seals under the member's key too
        kms_key = os.environ.get(STATE_KMS_KEY) or (
            _manifest_state.get("kms_key") if not env_url and url == _manifest_state.get("url") else None)
    if not url or url == "folder":
        return FolderStore()
    scheme, sep, _ = url.partition("://")
    if not sep or not scheme:
        raise StateError(f"state url {url!r}: expected s3://BUCKET/PREFIX (or unset for the stack folder)")
    key = (url, kms_key or "", str(state_root()), *(os.environ.get(v, "") for v in (
        "AWS_ENDPOINT_URL", "AWS_PROFILE", "AWS_ACCESS_KEY_ID", "AWS_DEFAULT_REGION", "AWS_REGION")))
    if key not in _opened:
        if not registry.known(STORES, scheme):
            known = ", ".join(f"{name}://" for name in registry.names(STORES)) or "none"
            raise StateError(f"state url {url!r}: no state store for {scheme}:// (known: {known})")
        _opened[key] = registry.load(STORES, scheme).from_url(url, kms_key=kms_key)
    return _opened[key]
