"""A :class:`~fogiac.provision.host.Host` over SSH, with Fabric's ``Connection``.

Why Fabric: it wraps paramiko's channels, SFTP and command results in one small API, and its
``Connection`` is what a fleet of hosts is made of. fogiac replaces Fabric's default
accept-any-key policy with :mod:`.hostkeys` and never reads ``~/.ssh/config``.
"""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from fogiac.errors import HostKeyError, ProvisionError
from fogiac.provision import hostkeys
from fogiac.provision.host import Result, q

if TYPE_CHECKING:
    from fogiac.provision.host import SshAccess

_BACKOFF = (0.25, 0.5, 1.0, 2.0, 4.0, 5.0)


class SshHost:
    """One SSH connection; thread-confined (each provisioning thread opens its own)."""

    def __init__(self, *, name: str, access: SshAccess, known_hosts: Path, stack: str) -> None:
        self.name = name
        self.access = access
        self.known = hostkeys.KnownHosts(known_hosts)
        self.stack = stack
        self.base = access.base_dir or ""
        self.bytes_sent = 0
        self._conn: object | None = None
        self._lock = threading.Lock()

    # -- connecting -----------------------------------------------------------------------

    def connect(self) -> int:
        """Open the connection, retrying with bounded backoff until ``connect_timeout``.

        Returns the number of attempts. A refused host key or failed authentication is final.
        """
        import paramiko
        from fabric import Config, Connection

        access = self.access
        name = hostkeys.known_name(access.address, access.port)
        deadline = time.monotonic() + access.connect_timeout
        attempt = 0
        last = "no attempt made"
        while True:
            attempt += 1
            conn = Connection(
                access.address, user=access.user, port=access.port,
                config=Config(overrides={"load_ssh_configs": False}),
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
            except (OSError, socket.timeout, paramiko.SSHException, EOFError) as err:
                conn.close()
                last = _reason(err)
                pause = _BACKOFF[min(attempt - 1, len(_BACKOFF) - 1)]
                if time.monotonic() + pause >= deadline:
                    raise ProvisionError(
                        f"{self.name}: cannot reach {access.address}:{access.port} over SSH after "
                        f"{attempt} attempts in {access.connect_timeout:g}s ({last})"
                    ) from None
                time.sleep(pause)
                continue
            self._conn = conn
            break
        if not self.base:
            home = self.run("printf %s \"$HOME\"").stdout.strip()
            self.base = f"{home}/.fogiac/{self.stack}/{self.name}"
        return attempt

    @property
    def conn(self):  # type: ignore[no-untyped-def]
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
            self._conn.close()  # type: ignore[attr-defined]
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
