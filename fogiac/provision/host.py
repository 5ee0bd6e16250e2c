"""The two interfaces every provisioning step talks to: a :class:`Host` and the :class:`HostAccess` that opens it.

Why: steps must not care whether a host is a lab machine over SSH (:mod:`.ssh`) or a sandbox
directory on this machine (:mod:`.local`). Both implement :class:`Host`; how to reach a host is
described by a frozen access record (``SshAccess`` in :mod:`.ssh`, ``LocalAccess`` in
:mod:`.local`, or a target's own) that satisfies :class:`HostAccess`. This module names no kind,
so the kinds import it and never the other way round; each target reads back the descriptions of
the kinds it makes, so there is no table of kinds either.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

from fogiac.errors import ProvisionError
from fogiac.plan.model import RELAY_PORT, Plan


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
    """How to reach one host: the command runner a target hands back for it (as SkyPilot's clouds hand
    back ``get_command_runners``); frozen, so it can be recorded.

    ``describe()`` is what the stack's record keeps, a plain dict whose ``kind`` the target that made
    the access reads back (:meth:`fogiac.lifecycle.driver.Target.access_from`); ``location`` is the one
    line a report shows; ``ship_code`` says whether fogiac's own code is pushed to the host or already
    there (a sandbox on this machine runs this checkout). What runs on the host (its ROS master's and
    the middleware's ports) is not the access's business: the target says it beside the access
    (:class:`HostPorts`). The three questions at the end are asked by ``fogiac logs``, ``fogiac ssh``
    and teardown, so nothing outside an access class branches on which kind it is.
    """

    @property
    def kind(self) -> str: ...

    @property
    def python(self) -> str: ...

    @property
    def user(self) -> str: ...

    @property
    def ros_address(self) -> str: ...

    @property
    def ship_code(self) -> bool: ...

    @property
    def location(self) -> str: ...

    def open(self, *, name: str, known_hosts: Path, stack: str) -> Host: ...

    def describe(self) -> dict[str, object]: ...

    def follow_argv(self, command: str, *, known_hosts: Path) -> list[str]:
        """The argv that runs ``command`` on the host from this machine, its output streamed (``logs -f``)."""
        ...

    def shell_argv(self, *, base: str, known_hosts: Path) -> tuple[list[str], str]:
        """An interactive shell in ``base`` on the host: its argv, and the folder here to run it from."""
        ...

    def remove_base(self, host: Host) -> None:
        """Remove fogiac's folder on the host (``host`` is open on this access): teardown's last act."""
        ...


@dataclass(frozen=True)
class HostPorts:
    """What a host's services listen on: its ROS master and the middleware's end the edge dials.

    The plan says them (:func:`planned_ports`); a target whose hosts share one machine picks its own
    (the ``local`` sandboxes) and hands them back beside the access.
    """

    master_port: int
    relay_port: int


def planned_ports(plan: Plan) -> dict[str, HostPorts]:
    """host -> the ports its plan says: the host's master port and its route's port (the middleware's,
    unless the host has one of its own)."""
    routes = {r.host: r.port for r in plan.routes}
    return {h.name: HostPorts(master_port=h.master_port, relay_port=routes.get(h.name, h.relay_port or RELAY_PORT))
            for h in plan.hosts}


def q(value: object) -> str:
    """Shell-quote one word for a remote command line."""
    return shlex.quote(str(value))
