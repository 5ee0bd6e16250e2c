"""SSH host-key verification: pinned fingerprints (``aws``) or trust on first use (``hosts``).

Why: a provisioner pushes certificates and runs code as root, so it must know it talks to the
machine it means. Keys are recorded in the stack's own ``known_hosts`` (0600, in the state
directory), never the user's ``~/.ssh``; a host whose key changed is refused until the user
removes its line, and the refusal says which line. Pins win over the record: a cloud instance's
console reports the keys of the instance now at that address, so a recorded key outside the
pins belongs to an earlier instance (public addresses are reused) and is forgotten. paramiko
(the ``ssh`` extra) is imported when a key is first handled, so importing this module costs nothing.
"""

from __future__ import annotations

import base64
import hashlib
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from fogiac.certs import write_private
from fogiac.errors import HostKeyError
from fogiac.extras import need

if TYPE_CHECKING:
    import paramiko


def fingerprint(key: paramiko.PKey) -> str:
    """OpenSSH's ``SHA256:...`` fingerprint (what ``ssh-keygen -lf`` and cloud consoles print)."""
    digest = hashlib.sha256(key.asbytes()).digest()
    return "SHA256:" + base64.b64encode(digest).decode().rstrip("=")


def known_name(address: str, port: int) -> str:
    """The known_hosts name OpenSSH and paramiko use: ``addr`` on 22, else ``[addr]:port``."""
    return address if port == 22 else f"[{address}]:{port}"


_LOCKS: dict[Path, threading.Lock] = {}
_LOCKS_GUARD = threading.Lock()


def _lock_for(path: Path) -> threading.Lock:
    """One lock per file, however many KnownHosts objects (one per host thread) point at it."""
    with _LOCKS_GUARD:
        return _LOCKS.setdefault(path.resolve(), threading.Lock())


class KnownHosts:
    """One stack's known_hosts file, safe to share between provisioning threads."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._lock = _lock_for(path)

    def _load(self) -> paramiko.HostKeys:
        keys = need("paramiko").HostKeys()
        if self.path.exists():
            keys.load(str(self.path))
        return keys

    def keys_for(self, name: str) -> dict[str, paramiko.PKey]:
        with self._lock:
            return dict(self._load().lookup(name) or {})

    def record(self, name: str, key: paramiko.PKey) -> None:
        with self._lock:
            keys = self._load()
            keys.add(name, key.get_name(), key)
            self._save(keys)

    def forget(self, name: str) -> None:
        with self._lock:
            keys = self._load()
            if name in keys:
                del keys[name]
                self._save(keys)

    def _save(self, keys: paramiko.HostKeys) -> None:
        lines = [f"{host} {kind} {k.get_base64()}\n"
                 for host, entry in sorted(keys.items()) for kind, k in sorted(entry.items())]
        write_private(self.path, "".join(lines).encode())

    def changed_error(self, *, host: str, name: str, got: paramiko.PKey, expected: paramiko.PKey) -> HostKeyError:
        return HostKeyError(
            f"{host} ({name}) presented host key {fingerprint(got)} but {self.path} records "
            f"{fingerprint(expected)}; refusing to connect (if the machine was rebuilt, delete its "
            f"line from {self.path})"
        )


class VerifyPolicy:
    """Decides about a host whose key is not yet recorded: check the pins, then record it.

    paramiko's ``MissingHostKeyPolicy`` is only an interface (``missing_host_key``); not
    subclassing it keeps paramiko out of this module's import.
    """

    def __init__(self, known: KnownHosts, *, host: str, pinned: tuple[str, ...]) -> None:
        self.known = known
        self.host = host
        self.pinned = pinned

    def missing_host_key(self, client: paramiko.SSHClient, hostname: str, key: paramiko.PKey) -> None:
        got = fingerprint(key)
        if self.pinned and got not in self.pinned:
            raise HostKeyError(
                f"{self.host} ({hostname}) presented host key {got}, which is not among the "
                f"{len(self.pinned)} pinned fingerprint(s) the instance reported; refusing to connect"
            )
        self.known.record(hostname, key)


def prepare(client: paramiko.SSHClient, known: KnownHosts, *, host: str, name: str,
            pinned: tuple[str, ...]) -> None:
    """Make ``client`` trust only the stack's known_hosts and ``pinned``, never ~/.ssh."""
    client.get_host_keys().clear()
    recorded = known.keys_for(name)
    if pinned and any(fingerprint(key) not in pinned for key in recorded.values()):
        known.forget(name)  # an earlier instance's key at a reused address; the pins decide
        recorded = {}
    for kind, key in recorded.items():
        client.get_host_keys().add(name, kind, key)
    client.set_missing_host_key_policy(VerifyPolicy(known, host=host, pinned=pinned))
