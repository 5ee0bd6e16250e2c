"""The ``local`` target's :class:`~fogiac.provision.host.Host`: a sandbox folder on this machine.

Why: demos and CI deploy the same manifest without any machine. Each planned host becomes a
folder under the stack's state directory with its own ROS master port and relay port
(:func:`local_ports`, handed to provisioning beside the access), so the steps run unchanged and
``teardown`` leaves nothing outside the state directory.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from fogiac.errors import ProvisionError
from fogiac.plan.model import Plan
from fogiac.procs import free_port
from fogiac.provision.host import Host, HostPorts, Result
from fogiac.state import StackState, read_json, write_json_atomic


@dataclass(frozen=True)
class LocalAccess:
    """A sandbox folder on this machine standing in for a host (the ``local`` target).

    ``location`` is what the edge dials (the sandbox's folder is in ``describe()`` and ``fogiac
    ssh``); the ports each sandbox's services listen on are the target's (:func:`local_ports`).
    """

    sandbox: Path
    location: str = "127.0.0.1"
    python: str = field(default_factory=lambda: sys.executable)
    ros_address: str = "127.0.0.1"
    ship_code: bool = False

    KIND: ClassVar[str] = "local"

    @property
    def kind(self) -> str:
        return self.KIND

    @property
    def user(self) -> str:
        """The ``User=`` of rendered systemd units; never installed here (a sandbox uses the supervisor)."""
        return "root"

    def open(self, *, name: str, known_hosts: Path, stack: str) -> Host:
        return LocalHost(name=name, base=str(self.sandbox))

    def describe(self) -> dict[str, object]:
        return {"kind": self.KIND, "sandbox": str(self.sandbox), "location": self.location, "python": self.python}

    @classmethod
    def from_description(cls, d: Mapping[str, Any]) -> LocalAccess:
        """Inverse of :meth:`describe`; a record written while the ports were the access's has no
        ``location`` but its ``relay_port``, which is what the edge dialed."""
        if d.get("kind") != cls.KIND:
            raise ProvisionError(f"recorded host access of kind {d.get('kind')!r} is not {cls.KIND!r}")
        location = d.get("location") or f"127.0.0.1:{int(d['relay_port'])}"
        return cls(sandbox=Path(str(d["sandbox"])), location=str(location), python=str(d["python"]))

    def follow_argv(self, command: str, *, known_hosts: Path) -> list[str]:
        return ["bash", "-c", command]

    def shell_argv(self, *, base: str, known_hosts: Path) -> tuple[list[str], str]:
        folder = base or str(self.sandbox)
        return ["bash", "--rcfile", f"{folder}/env/ros.sh", "-i"], folder

    def remove_base(self, host: Host) -> None:
        shutil.rmtree(self.sandbox, ignore_errors=True)


# A sandbox is handed an allowlisted environment, not the operator's: its services (and what they log: roslaunch
# writes its environment to its log) see only what running ROS, Python, pip and a container engine needs. A
# variable holding a secret's value (`{secret: env:NAME}`) has any name, so only an allowlist keeps it out; a
# node gets its own secrets from its 0600 file. Names that say they hold a credential are dropped even when
# allowlisted (a `PIP_PASSWORD`, a `ROS_AUTH_TOKEN`).
_ALLOWED = frozenset((
    "PATH", "HOME", "USER", "LOGNAME", "SHELL", "LANG", "LANGUAGE", "TZ", "TMPDIR", "TERM",
    "PYTHONPATH", "PYTHONHOME", "PYTHONDONTWRITEBYTECODE", "PYTHONUNBUFFERED", "VIRTUAL_ENV",
    "LD_LIBRARY_PATH", "CMAKE_PREFIX_PATH", "AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH", "PKG_CONFIG_PATH",
    "SSL_CERT_FILE", "SSL_CERT_DIR", "REQUESTS_CA_BUNDLE", "CURL_CA_BUNDLE",
    "HTTP_PROXY", "HTTPS_PROXY", "NO_PROXY", "http_proxy", "https_proxy", "no_proxy",
    "XDG_RUNTIME_DIR", "DBUS_SESSION_BUS_ADDRESS", "DOCKER_HOST", "CONTAINER_HOST",
))
_ALLOWED_PREFIXES = ("LC_", "ROS_", "RMW_", "PIP_", "CONTAINERS_")
_CREDENTIAL = re.compile(r"TOKEN|SECRET|PASSW|PASSPHRASE|CREDENTIAL|ACCESS_KEY|PRIVATE_KEY|API_KEY|AUTH", re.I)
# What a sandbox's services write (roslaunch's logs, which hold their environment; a node's own files) is
# the operator's alone, as a host's files are its service user's.
SANDBOX_UMASK = 0o077


def sandbox_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if (k in _ALLOWED or k.startswith(_ALLOWED_PREFIXES)) and not _CREDENTIAL.search(k)}


class LocalHost:
    """Runs commands with bash in the sandbox folder; ``put`` writes files directly."""

    manager_name = "supervisor"  # never systemd units: a sandbox leaves nothing outside its folder

    def __init__(self, *, name: str, base: str) -> None:
        self.name = name
        self.base = base
        self.bytes_sent = 0

    def connect(self) -> int:
        Path(self.base).mkdir(parents=True, exist_ok=True, mode=0o700)
        return 1

    def run(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        try:
            done = subprocess.run(
                ["bash", "-c", command], cwd=self.base, capture_output=True, text=True,
                timeout=timeout, stdin=subprocess.DEVNULL, env=sandbox_env(), umask=SANDBOX_UMASK,
            )
        except subprocess.TimeoutExpired:
            raise ProvisionError(f"{self.name}: `{command[:60]}` timed out after {timeout}s") from None
        result = Result(command=command, exit_code=done.returncode, stdout=done.stdout, stderr=done.stderr)
        if check and not result.ok:
            raise ProvisionError(f"{self.name}: `{' '.join(command.split())[:80]}` failed ({result.last_line()})")
        return result

    def sudo(self, command: str, *, check: bool = True, timeout: float | None = None) -> Result:
        """The local target never escalates: a sandbox is owned by whoever runs fogiac."""
        return self.run(command, check=check, timeout=timeout)

    def put(self, data: bytes, remote: str, *, mode: int = 0o644) -> int:
        path = Path(remote)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.fogiac-tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
        self.bytes_sent += len(data)
        return len(data)

    def get(self, remote: str, local: Path) -> Path:
        shutil.copyfile(remote, local)
        return local

    def close(self) -> None:
        pass


PORTS_FILE = "ports.json"


SANDBOXES = "local"  # the local target's own folder in the stack's: one sandbox per host, and the ports


def sandbox_root(state_dir: Path) -> Path:
    return StackState.at(state_dir).target_file(SANDBOXES)


def local_ports(plan: Plan, *, state_dir: Path) -> dict[str, HostPorts]:
    """Each sandbox's own ROS master port and relay port, chosen once and kept in ``local/ports.json``.

    Keeping the ports makes a second ``up`` a no-op: the services' rendered commands match.
    """
    root = sandbox_root(state_dir)
    root.mkdir(parents=True, exist_ok=True, mode=0o700)
    ports_file = root / PORTS_FILE
    ports: dict[str, dict[str, int]] = read_json(ports_file) or {}
    out: dict[str, HostPorts] = {}
    for host in plan.hosts:
        chosen = ports.get(host.name) or {"master": free_port(), "relay": free_port()}
        ports[host.name] = chosen
        out[host.name] = HostPorts(master_port=chosen["master"], relay_port=chosen["relay"])
    write_json_atomic(ports_file, ports)
    return out


def local_access(plan: Plan, *, state_dir: Path) -> Mapping[str, LocalAccess]:
    """One sandbox per planned host, shown at the address the edge dials it (its relay port)."""
    root = sandbox_root(state_dir)
    return {name: LocalAccess(sandbox=root / name, location=f"127.0.0.1:{ports.relay_port}")
            for name, ports in local_ports(plan, state_dir=state_dir).items()}
