"""The two interfaces every provisioning step talks to: a :class:`Host` and the :class:`HostAccess` that opens it.

Why: steps must not care whether a host is a lab machine over SSH (:mod:`.ssh`) or a sandbox
directory on this machine (:mod:`.local`). Both implement :class:`Host`; how to reach a host is
described by a frozen access record (``SshAccess`` in :mod:`.ssh`, ``LocalAccess`` in
:mod:`.local`) that satisfies :class:`HostAccess`. This module names neither kind, so the kinds
import it and never the other way round.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

from fogiac.errors import ProvisionError


@dataclass(frozen=True)
class Result:
    """What one command did on a host."""

    command: str
    exit_code: int
    stdout: str
    stderr: str

    @property
    def ok(self) -> bool:
        return self.exit_code == 0

    def last_line(self) -> str:
        """The most telling line for an error message: stderr's last, else stdout's."""
        for text in (self.stderr, self.stdout):
            lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
            if lines:
                return lines[-1]
        return f"exit code {self.exit_code}"


def command_failed(host: str, result: Result, *, what: str) -> ProvisionError:
    return ProvisionError(f"{host}: {what} failed ({result.last_line()})")


@runtime_checkable
class Host(Protocol):
    """A machine the steps provision. ``base`` is the absolute folder fogiac owns there."""

    name: str
    base: str
    bytes_sent: int

    @property
    def manager_name(self) -> str | None:
        """The service manager this host must use (``supervisor``, ``systemd``); None: probe the host."""
        ...

    def connect(self) -> int:
        """Make the host reachable (and ``base`` known); returns the number of attempts it took."""
        ...

    def run(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        """Run a shell command (bash) as the login user."""
        ...

    def sudo(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        """Run a shell command as root (no password prompt: ``sudo -n``)."""
        ...

    def put(self, data: bytes, remote: str, *, mode: int = 0o644) -> int:
        """Write ``data`` to ``remote`` with ``mode`` from the first byte; returns bytes sent."""
        ...

    def get(self, remote: str, local: Path) -> Path:
        """Copy ``remote`` to ``local``."""
        ...

    def close(self) -> None:
        ...


@runtime_checkable
class HostAccess(Protocol):
    """How to reach one host, and what its services need to know about it; frozen, so it can be recorded.

    ``describe()`` is what ``provision.json`` keeps (``kind`` says which record reads it back);
    ``location`` is the one line a report shows; ``ship_code`` says whether fogiac's own code is
    pushed to the host or already there (a sandbox on this machine runs this checkout).
    """

    @property
    def kind(self) -> str: ...

    @property
    def python(self) -> str: ...

    @property
    def fingerprints(self) -> tuple[str, ...]: ...

    @property
    def user(self) -> str: ...

    @property
    def ros_address(self) -> str: ...

    @property
    def master_port(self) -> int: ...

    @property
    def relay_port(self) -> int: ...

    @property
    def ship_code(self) -> bool: ...

    @property
    def location(self) -> str: ...

    def open(self, *, name: str, known_hosts: Path, stack: str) -> Host: ...

    def describe(self) -> dict[str, object]: ...


def q(value: object) -> str:
    """Shell-quote one word for a remote command line."""
    return shlex.quote(str(value))
