"""A :class:`~fogiac.provision.host.Host` over SSH, with Fabric's ``Connection``.

Why Fabric: it wraps paramiko's channels, SFTP and command results in one small API, and its
``Connection`` is what a fleet of hosts is made of. fogiac replaces Fabric's default
accept-any-key policy with :mod:`.hostkeys` and never reads ``~/.ssh/config``. Fabric and
paramiko are the ``ssh`` extra, imported when a connection opens, not when this module loads.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from fogiac.errors import HostKeyError, ProvisionError
from fogiac.extras import need
from fogiac.procs import poll
from fogiac.provision import hostkeys
from fogiac.provision.host import Host, Result, q

if TYPE_CHECKING:
    from fabric import Connection

# Pauses between connection attempts: 0.25 s doubling to 5 s (a booting instance answers within a minute).
_FIRST_PAUSE, _GROWTH, _LONGEST_PAUSE = 0.25, 2.0, 5.0


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

    KIND: ClassVar[str] = "ssh"

    @property
    def kind(self) -> str:
        return self.KIND

    @property
    def ros_address(self) -> str:
        return self.address

    @property
    def location(self) -> str:
        return f"{self.address}:{self.port}"

    def open(self, *, name: str, known_hosts: Path, stack: str) -> Host:
        return SshHost(name=name, access=self, known_hosts=known_hosts, stack=stack)

    def describe(self) -> dict[str, object]:
        return {"kind": self.KIND, "address": self.address, "user": self.user, "port": self.port,
                "key": str(self.key), "base_dir": self.base_dir, "python": self.python}

    @classmethod
    def from_description(cls, d: Mapping[str, Any]) -> SshAccess:
        """Inverse of :meth:`describe`; a record written before the ports left the access (its
        ``master_port``/``relay_port``) reads the same: those keys are not the access's."""
        if d.get("kind") != cls.KIND:
            raise ProvisionError(f"recorded host access of kind {d.get('kind')!r} is not {cls.KIND!r}")
        return cls(address=str(d["address"]), user=str(d["user"]), port=int(d["port"]), key=Path(str(d["key"])),
                   base_dir=d.get("base_dir"), python=str(d["python"]))

    def _argv(self, known_hosts: Path, *remote: str, tty: bool) -> list[str]:
        """OpenSSH with the key and the pinned host keys provisioning used (never ~/.ssh/config's)."""
        return ["ssh", *(["-t"] if tty else []), "-i", str(self.key), "-p", str(self.port), "-o", "IdentitiesOnly=yes",
                "-o", f"UserKnownHostsFile={known_hosts}", "-o", "StrictHostKeyChecking=yes",
                f"{self.user}@{self.address}", *remote]

    def follow_argv(self, command: str, *, known_hosts: Path) -> list[str]:
        return self._argv(known_hosts, command, tty=False)

    def shell_argv(self, *, base: str, known_hosts: Path) -> tuple[list[str], str]:
        return self._argv(known_hosts, f"cd {q(base)} && exec $SHELL -l", tty=True), os.getcwd()

    def remove_base(self, host: Host) -> None:
        if host.base.count("/") >= 2:  # never "" or "/": only fogiac's own folder
            host.run(f"rm -rf -- {q(host.base)}")


class SshHost:
    """One SSH connection; thread-confined (each provisioning thread opens its own)."""

    manager_name: str | None = None  # systemd where the host runs it, else the supervisor: probed

    def __init__(self, *, name: str, access: SshAccess, known_hosts: Path, stack: str) -> None:
        self.name = name
        self.access = access
        self.known = hostkeys.KnownHosts(known_hosts)
        self.stack = stack
        self.base = access.base_dir or ""
        self.bytes_sent = 0
        self._conn: Connection | None = None
        self._lock = threading.Lock()

    # -- connecting -----------------------------------------------------------------------

    def connect(self) -> int:
        """Open the connection, retrying with bounded backoff until ``connect_timeout``.

        Returns the number of attempts. A refused host key or failed authentication is final.
        """
        fabric = need("fabric")
        paramiko = need("paramiko")
        access = self.access
        name = hostkeys.known_name(access.address, access.port)
        deadline = time.monotonic() + access.connect_timeout
        attempts = 0
        last = "no attempt made"

        def attempt() -> Connection | None:
            nonlocal attempts, last
            attempts += 1
            conn = fabric.Connection(
                access.address, user=access.user, port=access.port,
                config=fabric.Config(overrides={"load_ssh_configs": False}),
                connect_timeout=max(1.0, min(10.0, deadline - time.monotonic())),
                connect_kwargs={"key_filename": str(access.key), "look_for_keys": False,
                                "allow_agent": False, "banner_timeout": 15, "auth_timeout": 15},
            )
            hostkeys.prepare(conn.client, self.known, host=self.name, name=name, pinned=access.fingerprints)
            try:
                conn.open()
            except HostKeyError:
                conn.close()
                raise
            except paramiko.BadHostKeyException as err:
                conn.close()
                raise self.known.changed_error(host=self.name, name=name, got=err.key,
                                               expected=err.expected_key) from None
            except paramiko.AuthenticationException as err:
                conn.close()
                raise ProvisionError(
                    f"{self.name}: {access.user}@{access.address}:{access.port} refused key {access.key} ({err})"
                ) from None
            except (OSError, paramiko.SSHException, EOFError) as err:
                conn.close()
                last = _reason(err)
                return None
            return conn

        conn = poll(attempt, timeout=access.connect_timeout, interval=_FIRST_PAUSE, backoff=_GROWTH,
                    max_interval=_LONGEST_PAUSE)
        if conn is None:
            raise ProvisionError(
                f"{self.name}: cannot reach {access.address}:{access.port} over SSH after "
                f"{attempts} attempts in {access.connect_timeout:g}s ({last})"
            )
        self._conn = conn
        if not self.base:
            home = self.run("printf %s \"$HOME\"").stdout.strip()
            self.base = f"{home}/.fogiac/{self.stack}/{self.name}"
        return attempts

    @property
    def conn(self) -> Connection:
        if self._conn is None:
            self.connect()
        return self._conn

    # -- the Host interface -----------------------------------------------------------------

    def run(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        raw = self.conn.run(f"bash -c {q(command)}", hide=True, warn=True, timeout=timeout, in_stream=False)
        result = Result(command=command, exit_code=raw.exited, stdout=raw.stdout, stderr=raw.stderr)
        if check and not result.ok:
            raise ProvisionError(f"{self.name}: `{_short(command)}` failed ({result.last_line()})")
        return result

    def sudo(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        if self.access.user == "root":
            return self.run(command, check=check, timeout=timeout)
        return self.run(f"sudo -n bash -c {q(command)}", check=check, timeout=timeout)

    def put(self, data: bytes, remote: str, *, mode: int = 0o644) -> int:
        """Write via SFTP to a temporary name, chmod before any byte lands, then rename."""
        sftp = self.conn.sftp()
        tmp = f"{remote}.fogiac-tmp"
        with sftp.open(tmp, "wb") as fh:
            fh.chmod(mode)
            fh.set_pipelined(True)
            fh.write(data)
        sftp.posix_rename(tmp, remote)
        self.bytes_sent += len(data)
        return len(data)

    def get(self, remote: str, local: Path) -> Path:
        self.conn.get(remote, local=str(local))
        return local

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None


def _reason(err: BaseException) -> str:
    """The OS's words for a failed connect (paramiko wraps them as "[Errno None] Unable to ...")."""
    inner = getattr(err, "errors", None)
    if isinstance(inner, dict) and inner:
        first = next(iter(inner.values()))
        return first.strerror or str(first)
    if isinstance(err, OSError) and err.strerror:
        return err.strerror
    return str(err) or type(err).__name__


def _short(command: str, limit: int = 80) -> str:
    line = " ".join(command.split())
    return line if len(line) <= limit else line[: limit - 3] + "..."
