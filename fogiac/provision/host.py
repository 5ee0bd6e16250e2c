"""The one interface every provisioning step talks to: run, sudo, put, get on a host.

Why: steps must not care whether a host is a lab machine over SSH (:mod:`.ssh`) or a sandbox
directory on this machine (:mod:`.local`). Both implement :class:`Host`; how to reach a host is
described by a frozen access record (:class:`SshAccess`, :class:`LocalAccess`) that opens it.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass, field
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


@dataclass(frozen=True)
class SshAccess:
    """How to reach a machine over SSH.

    ``fingerprints`` pins the host key (``SHA256:...`` as the instance's console prints them,
    used on ``aws``); empty means trust on first contact and record it (``hosts``). ``base_dir``
    is fogiac's folder on the host (default ``$HOME/.fogiac/<stack>/<host>``); ``python`` runs
    fogiac's own code there (the relay, shipped workloads).
    """

    address: str
    user: str
    key: Path
    port: int = 22
    fingerprints: tuple[str, ...] = ()
    base_dir: str | None = None
    python: str = "python3"
    connect_timeout: float = 60.0
    ship_code: bool = True

    @property
    def kind(self) -> str:
        return "ssh"

    @property
    def ros_address(self) -> str:
        return self.address

    @property
    def master_port(self) -> int:
        from fogiac.plan import ROS_MASTER_PORT

        return ROS_MASTER_PORT

    @property
    def relay_port(self) -> int:
        from fogiac.plan import RELAY_PORT

        return RELAY_PORT

    def open(self, *, name: str, known_hosts: Path, stack: str) -> Host:
        from fogiac.provision.ssh import SshHost

        return SshHost(name=name, access=self, known_hosts=known_hosts, stack=stack)

    def describe(self) -> dict[str, object]:
        return {"kind": "ssh", "address": self.address, "user": self.user, "port": self.port,
                "key": str(self.key), "base_dir": self.base_dir, "python": self.python}


@dataclass(frozen=True)
class LocalAccess:
    """A sandbox folder on this machine standing in for a host (the ``local`` target).

    Each sandbox has its own ROS master port and relay port so sandboxes never share a graph.
    """

    sandbox: Path
    master_port: int
    relay_port: int
    python: str = field(default_factory=lambda: __import__("sys").executable)
    ros_address: str = "127.0.0.1"
    ship_code: bool = False
    fingerprints: tuple[str, ...] = ()

    @property
    def kind(self) -> str:
        return "local"

    def open(self, *, name: str, known_hosts: Path, stack: str) -> Host:
        from fogiac.provision.local import LocalHost

        return LocalHost(name=name, base=str(self.sandbox))

    def describe(self) -> dict[str, object]:
        return {"kind": "local", "sandbox": str(self.sandbox), "master_port": self.master_port,
                "relay_port": self.relay_port, "python": self.python}


HostAccess = SshAccess | LocalAccess


def access_from_dict(data: dict[str, object]) -> HostAccess:
    """Inverse of ``describe()``: how ``fogiac logs``/``ssh`` find a provisioned host again."""
    kinds = {
        "ssh": lambda d: SshAccess(address=str(d["address"]), user=str(d["user"]), port=int(d["port"]),  # type: ignore[arg-type]
                                   key=Path(str(d["key"])), base_dir=d.get("base_dir"),  # type: ignore[arg-type]
                                   python=str(d["python"])),
        "local": lambda d: LocalAccess(sandbox=Path(str(d["sandbox"])), master_port=int(d["master_port"]),  # type: ignore[arg-type]
                                       relay_port=int(d["relay_port"]), python=str(d["python"])),  # type: ignore[arg-type]
    }
    try:
        return kinds[str(data["kind"])](data)
    except KeyError:
        raise ProvisionError(f"unknown host access kind {data.get('kind')!r}; valid: {', '.join(kinds)}") from None


def q(value: object) -> str:
    """Shell-quote one word for a remote command line."""
    return shlex.quote(str(value))
