"""The edge's side of AWS Client VPN: its ``client.ovpn`` and the OpenVPN process running it.

Why: in ``vpn`` mode the robot joins the stack's VPC through a Client VPN endpoint with mutual
TLS (the stack's CA). The profile holds the client's private key, so it is written 0600 from the
first byte, into the stack's state folder by default, and never inside a git work tree. The
OpenVPN daemon's pid file and log sit beside the profile, which makes ``up``/``down``/``status``
idempotent and lets ``status`` say which tun device and address the tunnel has.

Pure parts (rendering the profile, reading OpenVPN's log) are separate from the parts that
touch the world (writing the file, starting and stopping ``openvpn``).
"""

from __future__ import annotations

import ipaddress
import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from fogiac import certnames, certs
from fogiac.procs import pid_alive, poll, stop_tree
from fogiac.render import render
from fogiac.state import StackState
from fogiac.store import make_private
from fogiac.targets.aws.errors import VpnError

PROFILE_NAME = "client.ovpn"
_PROTOCOLS = ("udp", "tcp")
_ROBOT_RE = re.compile(r"^[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?$")  # as fogiac.certs checks an edge's name
_HOST_RE = re.compile(r"^(?=.{1,253}$)([A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?\.)*"
                      r"[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?$")


# -- the profile (pure) -------------------------------------------------------------------------

def _remote_host(endpoint_dns: str) -> str:
    """The name to dial: AWS reports the endpoint as ``*.cvpn-endpoint-....amazonaws.com``."""
    host = endpoint_dns.strip().removeprefix("*.")
    if not _HOST_RE.match(host):
        raise VpnError(f"endpoint DNS name {endpoint_dns!r} is not a host name or address")
    return host


def _is_ip(host: str) -> bool:
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return False
    return True


def _pem(data: bytes | str, *, what: str) -> str:
    text = data.decode() if isinstance(data, bytes) else data
    text = text.strip()
    if not (text.startswith("-----BEGIN ") and text.endswith("-----")):
        raise VpnError(f"the {what} is not PEM text")
    return text


def render_client_profile(
    *, endpoint_dns: str, stack: str, ca_pem: bytes | str, cert_pem: bytes | str,
    key_pem: bytes | str, port: int = 443, proto: str = "udp",
) -> str:
    """The ``client.ovpn`` text in AWS Client VPN's format, certificates and key inline.

    ``remote-random-hostname`` makes OpenVPN prefix a random label to the endpoint's wildcard
    DNS name, as AWS profiles do; a literal address (labs, tests) has no wildcard, so no prefix.
    """
    if proto not in _PROTOCOLS:
        raise VpnError(f"VPN protocol {proto!r} is not one of: {', '.join(_PROTOCOLS)}")
    if not 0 < port < 65536:
        raise VpnError(f"VPN port {port} is not between 1 and 65535")
    host = _remote_host(endpoint_dns)
    return render(
        "vpn/client.ovpn.j2", stack=stack, proto=proto, remote=host, port=port,
        random_hostname=not _is_ip(host), server_name=certnames.server_name(stack),
        ca_pem=_pem(ca_pem, what="CA certificate"), cert_pem=_pem(cert_pem, what="client certificate"),
        key_pem=_pem(key_pem, what="client key"),
    )


def default_profile_path(stack: str, *, create: bool = True, robot: str | None = None) -> Path:
    """``client.ovpn`` in the stack's state folder (made 0700 when ``create``); a fleet's ``robot``'s in a folder
    of its own (``vpn-ROBOT/``), since OpenVPN's pid file and log sit beside the profile it runs."""
    state = StackState(stack)
    if robot is None:
        return state.target_file(PROFILE_NAME, create=create)
    if not _ROBOT_RE.fullmatch(robot):  # fullmatch: "$" alone lets a trailing newline through
        raise VpnError(f"robot {robot!r}: a robot's name is one DNS label (a-z, 0-9, '-', up to 63)")
    folder = state.target_file(f"vpn-{robot}", create=create)
    if create:
        make_private(folder)
    return folder / PROFILE_NAME


def git_work_tree(path: Path) -> Path | None:
    """The git work tree ``path`` would be inside, or None (found by walking up to ``.git``)."""
    for folder in Path(os.path.abspath(path)).parents:
        if (folder / ".git").exists():
            return folder
    return None


def write_client_profile(
    *, endpoint_dns: str, stack: str, bundle: certs.Bundle | None = None,
    ca_pem: bytes | None = None, cert_pem: bytes | None = None, key_pem: bytes | None = None,
    path: Path | None = None, port: int = 443, proto: str = "udp",
) -> Path:
    """Write the edge's profile (0600 from the first byte) and return where it went.

    Give either ``bundle`` or all of ``ca_pem``, ``cert_pem``, ``key_pem``. The default place is
    the stack's state folder; a path inside a git work tree is refused so the key is never
    committed by accident.
    """
    if bundle is not None:
        ca_pem, cert_pem, key_pem = bundle.ca.cert_pem, bundle.client.cert_pem, bundle.client.key_pem
    if ca_pem is None or cert_pem is None or key_pem is None:
        raise VpnError("a client profile needs the CA certificate and the client certificate and key")
    target = path if path is not None else default_profile_path(stack)
    repo = git_work_tree(target)
    if repo is not None:
        raise VpnError(
            f"refusing to write the VPN profile {target} inside the git work tree {repo}: "
            "it holds a private key; choose a path outside the repository"
        )
    text = render_client_profile(
        endpoint_dns=endpoint_dns, stack=stack, ca_pem=ca_pem, cert_pem=cert_pem,
        key_pem=key_pem, port=port, proto=proto,
    )
    certs.write_private(target, text.encode())
    return target


def render_server_config(
    *, bundle: certs.Bundle, client_cidr: str, listen: str, routes: tuple[str, ...],
    port: int = 443, proto: str = "udp", crl: Path | None = None,
) -> str:
    """An OpenVPN server set up the way AWS Client VPN is, for tests and on-prem labs.

    Mutual TLS with the stack's CA, ``dh none`` (ECDHE only), TLS 1.2 or newer, clients numbered
    from ``client_cidr`` and told to route ``routes`` (the VPC) through the tunnel. Source NAT of
    clients to the server's VPC-side address is the host's firewall's job, as at AWS. ``crl``: the
    stack's revocation list (a fleet's revoked robots), checked on every handshake as the endpoint
    checks the one imported into it.
    """
    if proto not in _PROTOCOLS:
        raise VpnError(f"VPN protocol {proto!r} is not one of: {', '.join(_PROTOCOLS)}")
    try:
        clients = ipaddress.ip_network(client_cidr)
        pushed = [ipaddress.ip_network(r) for r in routes]
    except ValueError as err:
        raise VpnError(f"bad VPN network: {err}") from None
    return render(
        "vpn/server.conf.j2", client_network=str(clients.network_address),
        client_netmask=str(clients.netmask), proto=proto, listen=listen, port=port,
        routes=[(str(n.network_address), str(n.netmask)) for n in pushed],
        ca_pem=_pem(bundle.ca.cert_pem, what="CA certificate"),
        cert_pem=_pem(bundle.vpn.cert_pem, what="VPN endpoint certificate"),
        key_pem=_pem(bundle.vpn.key_pem, what="VPN endpoint key"), crl=str(crl) if crl is not None else None,
    )


# -- OpenVPN's log (pure) -----------------------------------------------------------------------

_DEVICE_RE = re.compile(r"TUN/TAP device (\S+) opened")
_ADDRESS_RE = re.compile(r"net_addr_v4_add: (\S+) dev (\S+)")
_READY = "Initialization Sequence Completed"
_FAILURES = (
    "AUTH_FAILED", "VERIFY ERROR", "TLS Error", "TLS_ERROR", "Options error",
    "Cannot open TUN/TAP", "Cannot resolve host address", "Exiting due to fatal error",
    "ERROR: Cannot ioctl TUNSETIFF",
)


@dataclass(frozen=True)
class LogFacts:
    """What OpenVPN's log says about the current run."""

    device: str | None
    address: str | None
    ready: bool
    failure: str | None


def parse_log(text: str) -> LogFacts:
    device = address = failure = None
    ready = False
    for line in text.splitlines():
        if m := _DEVICE_RE.search(line):
            device = m.group(1)
        elif m := _ADDRESS_RE.search(line):
            address = m.group(1)
        elif _READY in line:
            ready = True
        elif failure is None and any(marker in line for marker in _FAILURES):
            failure = re.sub(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d ", "", line).strip()
    return LogFacts(device=device, address=address, ready=ready, failure=failure)


# -- the OpenVPN process (touches the world) ----------------------------------------------------

@dataclass(frozen=True)
class TunnelStatus:
    running: bool
    pid: int | None
    device: str | None
    address: str | None
    log: Path


@dataclass(frozen=True)
class Outcome:
    """The tunnel's status after ``up``/``down``; ``changed`` is False when nothing was to do."""

    status: TunnelStatus
    changed: bool


def runtime_paths(profile: Path) -> tuple[Path, Path]:
    """The pid file and log of the OpenVPN that runs ``profile``: beside it, in its folder."""
    return profile.parent / "openvpn.pid", profile.parent / "openvpn.log"


def _written_pid(pid_file: Path) -> int | None:
    """The pid OpenVPN wrote, or None while the file is missing or still being written."""
    try:
        return int(pid_file.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def _running_pid(pid_file: Path) -> int | None:
    """The pid in ``pid_file`` if that process is alive and is OpenVPN (not a reused pid)."""
    pid = _written_pid(pid_file)
    if pid is None:
        return None
    try:
        comm = Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return None
    return pid if comm == "openvpn" and pid_alive(pid) else None


def _read_log(log: Path) -> LogFacts:
    try:
        return parse_log(log.read_text(errors="replace"))
    except FileNotFoundError:
        return parse_log("")


def _device_address(device: str) -> str | None:
    ip = shutil.which("ip")
    if ip is None:
        return None
    out = subprocess.run([ip, "-o", "-4", "addr", "show", "dev", device],
                         capture_output=True, text=True).stdout
    m = re.search(r"\binet (\S+)", out)
    return m.group(1) if m else None


def tunnel_status(*, profile: Path) -> TunnelStatus:
    pid_file, log = runtime_paths(profile)
    pid = _running_pid(pid_file)
    if pid is None:
        return TunnelStatus(running=False, pid=None, device=None, address=None, log=log)
    facts = _read_log(log)
    address = (_device_address(facts.device) if facts.device else None) or facts.address
    return TunnelStatus(running=True, pid=pid, device=facts.device, address=address, log=log)


def _require_root(verb: str) -> None:
    if os.geteuid() != 0:
        raise VpnError(
            f"`fogiac vpn {verb}` needs root: OpenVPN creates a tun device and sets routes "
            f"(run it with sudo)"
        )


def tunnel_up(*, profile: Path, timeout: float = 30.0, openvpn: str = "openvpn") -> Outcome:
    """Start OpenVPN as a daemon on ``profile`` and wait until the tunnel is up or has failed."""
    status = tunnel_status(profile=profile)
    if status.running:
        return Outcome(status, changed=False)
    _require_root("up")
    binary = shutil.which(openvpn)
    if binary is None:
        raise VpnError(f"{openvpn} not found; install OpenVPN (Debian package: openvpn)")
    if not profile.is_file():
        raise VpnError(f"no VPN profile at {profile}; write one first (fogiac up in vpn mode)")
    pid_file, log = runtime_paths(profile)
    pid_file.unlink(missing_ok=True)
    log.unlink(missing_ok=True)  # a previous run's "Initialization Sequence Completed" must not count
    started = subprocess.run(
        [binary, "--config", str(profile), "--daemon", "fogiac-openvpn",
         "--writepid", str(pid_file), "--log", str(log)],
        capture_output=True, text=True, cwd=profile.parent,
    )
    if started.returncode != 0:
        stderr = started.stderr.strip().splitlines()
        reason = _read_log(log).failure or (stderr[-1] if stderr else "no reason given")
        raise VpnError(f"openvpn did not start: {reason}; see {log}")

    def came_up() -> bool | None:
        """True once the tunnel is up; raises once OpenVPN failed; None while it is still trying."""
        facts = _read_log(log)
        if facts.failure:
            _stop(pid_file, settle=2.0)
            raise VpnError(f"OpenVPN failed: {facts.failure}; see {log}")
        if facts.ready:
            return True
        if _written_pid(pid_file) is not None and _running_pid(pid_file) is None:
            raise VpnError(f"OpenVPN exited before the tunnel came up; see {log}")
        return None

    if poll(came_up, timeout=timeout, interval=0.1, backoff=1.0):
        return Outcome(tunnel_status(profile=profile), changed=True)
    _stop(pid_file, settle=2.0)
    raise VpnError(f"the tunnel did not come up within {timeout:g} s (stopped OpenVPN); see {log}")


def _stop(pid_file: Path, *, timeout: float = 10.0, settle: float = 0.0) -> bool:
    """Stop the OpenVPN named in ``pid_file``; ``settle``: wait that long for a new daemon's pid."""
    poll(lambda: True if pid_file.exists() else None, timeout=settle, interval=0.05, backoff=1.0)
    pid = _running_pid(pid_file)
    if pid is None:
        pid_file.unlink(missing_ok=True)
        return False
    try:
        stop_tree(pid, grace=timeout)
    except PermissionError:
        raise VpnError("`fogiac vpn down` needs root: OpenVPN runs as root (run it with sudo)") from None
    pid_file.unlink(missing_ok=True)
    return True


def tunnel_down(*, profile: Path, timeout: float = 10.0) -> Outcome:
    """Stop the OpenVPN running ``profile`` and wait for it to exit; fine if none runs."""
    pid_file, _ = runtime_paths(profile)
    changed = _stop(pid_file, timeout=timeout)
    return Outcome(tunnel_status(profile=profile), changed=changed)
