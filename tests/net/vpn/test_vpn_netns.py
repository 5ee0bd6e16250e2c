"""The generated client.ovpn against an AWS-like OpenVPN server, in network namespaces.

Three namespaces stand for the robot ("edge"), the Client VPN endpoint ("aws": public side
towards the edge, VPC side towards the cloud) and a cloud host ("cloud", VPC side only). The
endpoint source-NATs clients to its VPC address, as AWS Client VPN does, so the cloud never
sees, and cannot route to, the robot's tunnel address: the reason fogiac's relay is opened
by the edge. Everything runs through ``fogiac vpn up|status|down`` for real.
"""

from __future__ import annotations

import importlib.util
import ipaddress
import os
import select
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from cryptography import x509

from fogiac import certs
from fogiac.net.relay.tls import relay_name
from fogiac.targets.aws.robotvpn import build_crl, identity
from fogiac.targets.aws.vpn import render_server_config, write_client_profile
from tests.support.netns import Namespace, NetLab, skip_reason

pytestmark = pytest.mark.root

_REASON = skip_reason() or (None if shutil.which("openvpn") else "needs openvpn (Debian package openvpn)")
if _REASON:
    pytest.skip(_REASON, allow_module_level=True)

REPO = Path(__file__).resolve().parents[3]
STACK = "lab-test"
CLIENT_CIDR = "10.231.36.0/22"
VPC_CIDR = "10.231.32.0/24"
AWS_VPC, CLOUD = "10.231.32.1", "10.231.32.10"
AWS_PUBLIC, EDGE_PUBLIC = "10.231.33.1", "10.231.33.2"
NAT_TOOL = shutil.which("iptables")

ROS_SIDE = Path(__file__).with_name("_ros_side.py")
# Each namespace has its own loopback, so fixed ports cannot collide with other test runs.
MASTER = "http://127.0.0.1:11311"
RELAY_PORT = 11411
_WAIT_MASTER = (
    "import sys,time,xmlrpc.client as x\n"
    "for _ in range(200):\n"
    "    try: x.ServerProxy(sys.argv[1]).getPid('/probe'); sys.exit(0)\n"
    "    except OSError: time.sleep(0.1)\n"
    "sys.exit(1)\n"
)

_SERVE_ONCE = (
    "import socket,sys;s=socket.socket();s.bind((sys.argv[1],int(sys.argv[2])));s.listen();"
    "print('ready',flush=True);c,a=s.accept();c.sendall(a[0].encode());c.close()"
)
_FETCH = (
    "import socket,sys;c=socket.create_connection((sys.argv[1],int(sys.argv[2])),timeout=10);"
    "print(c.recv(100).decode())"
)


@dataclass(frozen=True)
class VpnLab:
    edge: Namespace
    aws: Namespace
    cloud: Namespace
    bundle: certs.Bundle
    profile: Path
    workdir: Path
    nat: bool


def fogiac(ns: Namespace, *args: str, check: bool = False) -> subprocess.CompletedProcess[str]:
    """Run the real CLI inside ``ns``."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    return ns.run([sys.executable, "-m", "fogiac", *args], env=env, check=check, timeout=90)


def _wait_for_line(path: Path, needle: str, *, proc: subprocess.Popen[str], timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and needle in path.read_text(errors="replace"):
            return
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    log = path.read_text(errors="replace") if path.exists() else "(no log)"
    raise AssertionError(f"{needle!r} not seen in {path}:\n{log[-3000:]}")


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[VpnLab]:
    workdir = tmp_path_factory.mktemp("vpnlab")
    bundle = certs.new_bundle(STACK)
    with NetLab() as net:
        edge, aws, cloud = net.namespace("edge"), net.namespace("aws"), net.namespace("cloud")
        net.link(edge, aws, a_addr=f"{EDGE_PUBLIC}/30", b_addr=f"{AWS_PUBLIC}/30")
        vpc = net.link(aws, cloud, a_addr=f"{AWS_VPC}/24", b_addr=f"{CLOUD}/24")
        aws.sysctl("net.ipv4.ip_forward", "1")
        if NAT_TOOL:
            aws.run([NAT_TOOL, "-t", "nat", "-A", "POSTROUTING", "-s", CLIENT_CIDR,
                     "-o", vpc.a_if, "-j", "MASQUERADE"])
        else:  # without NAT the cloud needs a route back to the clients to answer at all
            cloud.add_route(CLIENT_CIDR, via=AWS_VPC)

        server_dir = workdir / "server"
        server_conf = server_dir / "server.conf"
        crl = server_dir / "revoked.crl.pem"  # what the endpoint imports: nothing revoked yet
        certs.write_private(crl, build_crl(bundle.ca, ()))
        certs.write_private(server_conf, render_server_config(
            bundle=bundle, client_cidr=CLIENT_CIDR, listen=AWS_PUBLIC, routes=(VPC_CIDR,), crl=crl,
        ).encode())
        server_log = server_dir / "openvpn.log"
        server = aws.popen(["openvpn", "--config", str(server_conf), "--log", str(server_log)])
        _wait_for_line(server_log, "Initialization Sequence Completed", proc=server)

        profile = write_client_profile(endpoint_dns=AWS_PUBLIC, bundle=bundle, stack=STACK,
                                       path=workdir / "edge-state" / "client.ovpn")
        yield VpnLab(edge=edge, aws=aws, cloud=cloud, bundle=bundle, profile=profile,
                     workdir=workdir, nat=NAT_TOOL is not None)


def _tun_address(lab: VpnLab) -> ipaddress.IPv4Interface:
    out = lab.edge.run(["ip", "-o", "-4", "addr", "show", "dev", "tun0"]).stdout
    return ipaddress.IPv4Interface(out.split(" inet ")[1].split()[0])


def test_vpn_up_brings_the_tunnel_up_with_a_client_cidr_address(lab: VpnLab) -> None:
    assert fogiac(lab.edge, "vpn", "status", "--profile", str(lab.profile)).stdout == "VPN stopped\n"
    up = fogiac(lab.edge, "vpn", "up", "--profile", str(lab.profile))
    assert up.returncode == 0, up.stderr
    address = _tun_address(lab)
    assert address.network == ipaddress.IPv4Network(CLIENT_CIDR)
    assert up.stdout.startswith("VPN up: running (pid ")
    assert up.stdout.endswith(f") on tun0 {address}\n")
    again = fogiac(lab.edge, "vpn", "up", "--profile", str(lab.profile))
    assert (again.returncode, again.stdout) == (0, up.stdout.replace("VPN up", "VPN already up"))
    status = fogiac(lab.edge, "vpn", "status", "--profile", str(lab.profile))
    assert status.stdout == up.stdout.replace("VPN up:", "VPN")


def test_edge_reaches_the_cloud_which_sees_the_nat_address(lab: VpnLab) -> None:
    server = lab.cloud.popen([sys.executable, "-c", _SERVE_ONCE, CLOUD, "7100"], stdout=subprocess.PIPE)
    assert server.stdout is not None and server.stdout.readline().strip() == "ready"
    seen = lab.edge.run([sys.executable, "-c", _FETCH, CLOUD, "7100"]).stdout.strip()
    if not lab.nat:
        pytest.skip("no iptables here (Debian package iptables): the cloud reached the edge by a "
                    f"return route, source NAT not checked (cloud saw {seen})")
    assert seen == AWS_VPC, "the cloud must see the endpoint's VPC address, not the client's"
    assert ipaddress.ip_address(seen) not in ipaddress.ip_network(CLIENT_CIDR)
    # And the cloud cannot open a connection back to the robot's tunnel address: no route.
    route = lab.cloud.run(["ip", "route", "get", str(_tun_address(lab).ip)], check=False)
    assert route.returncode != 0 or "via" not in route.stdout


def _ros_skip_reason() -> str | None:
    if shutil.which("roscore") is None:
        return "needs roscore (Debian package ros-core)"
    if importlib.util.find_spec("rospy") is None:
        return "needs rospy (Debian package python3-rospy)"
    if not (REPO / "fogiac" / "cli" / "relay.py").exists():
        return "the relay's `fogiac relay cloud|edge` commands are not there yet"
    return None


def _ros_env(home: Path) -> dict[str, str]:
    env = {**os.environ, "ROS_MASTER_URI": MASTER, "ROS_IP": "127.0.0.1", "ROS_HOME": str(home),
           "ROS_LOG_DIR": str(home / "log"),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    env.pop("ROS_HOSTNAME", None)
    return env


def _read_lines(proc: subprocess.Popen[str], count: int, *, timeout: float) -> list[str]:
    """The first ``count`` lines ``proc`` prints, or what came before the deadline."""
    assert proc.stdout is not None
    lines: list[str] = []
    deadline = time.monotonic() + timeout
    while len(lines) < count and time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.2)
        if ready:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line.strip())
    return lines


def _tail(path: Path) -> str:
    return path.read_text(errors="replace")[-2000:] if path.exists() else "(no output)"


def test_relay_carries_topics_both_ways_through_the_tunnel(lab: VpnLab, tmp_path: Path) -> None:
    reason = _ros_skip_reason()
    if reason:
        pytest.skip(reason)
    certs_dir = tmp_path / "certs"
    certs.save_bundle(lab.bundle, certs_dir)  # one CA for the VPN and the relay, as in a stack
    name = relay_name(STACK, "cloud")  # the cloud end's own certificate, not the VPN endpoint's
    certs.save_pair(certs_dir, "server", certs.issue(lab.bundle.ca, name, server=True, dns_names=(name,)))
    started: list[tuple[Namespace, subprocess.Popen[str]]] = []
    logs: dict[str, Path] = {}

    def start(ns: Namespace, what: str, argv: list[str], *, pipe: bool = False) -> subprocess.Popen[str]:
        env = _ros_env(tmp_path / f"ros-{ns.name}")
        if pipe:
            proc = ns.popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        else:
            logs[what] = tmp_path / f"{what}.log"
            with logs[what].open("w") as out:
                proc = ns.popen(argv, env=env, stdout=out)
        started.append((ns, proc))
        return proc

    try:
        for ns in (lab.edge, lab.cloud):
            start(ns, f"roscore-{ns.name[-5:]}", ["roscore", "-p", "11311"])
            ns.run([sys.executable, "-c", _WAIT_MASTER, MASTER], timeout=30)
        start(lab.cloud, "relay-cloud", [
            sys.executable, "-m", "fogiac", "relay", "cloud", "--listen", f"{CLOUD}:{RELAY_PORT}",
            "--master", MASTER, "--certs", str(certs_dir)])
        start(lab.edge, "relay-edge", [
            sys.executable, "-m", "fogiac", "relay", "edge", "--connect", f"{CLOUD}:{RELAY_PORT}",
            "--master", MASTER, "--certs", str(certs_dir), "--topics", "auto"])
        edge_node = start(lab.edge, "edge-node", [sys.executable, str(ROS_SIDE), "edge", "/to_cloud", "/to_edge"],
                          pipe=True)
        cloud_node = start(lab.cloud, "cloud-node",
                           [sys.executable, str(ROS_SIDE), "cloud", "/to_edge", "/to_cloud"], pipe=True)
        in_cloud = _read_lines(cloud_node, 5, timeout=60)
        at_edge = _read_lines(edge_node, 5, timeout=60)
        context = "\n".join(f"--- {k}\n{_tail(v)}" for k, v in logs.items() if k.startswith("relay"))
        assert len(in_cloud) == 5 and len(at_edge) == 5, f"cloud heard {in_cloud}, edge heard {at_edge}\n{context}"
        for heard, sender in ((in_cloud, "edge"), (at_edge, "cloud")):
            assert all(line.split()[0] == sender for line in heard)
            numbers = [int(line.split()[1]) for line in heard]
            assert numbers == sorted(set(numbers)), f"out of order or repeated: {numbers}"
    finally:
        for ns, proc in reversed(started):
            ns.lab.stop(proc)


def test_a_client_from_another_ca_is_refused(lab: VpnLab) -> None:
    stranger = certs.new_bundle(STACK)
    profile = write_client_profile(endpoint_dns=AWS_PUBLIC, bundle=stranger, stack=STACK,
                                   path=lab.workdir / "stranger" / "client.ovpn")
    up = fogiac(lab.edge, "vpn", "up", "--profile", str(profile), "--timeout", "20")
    assert up.returncode == 1
    assert up.stderr.startswith("error: OpenVPN failed: VERIFY ERROR")
    assert fogiac(lab.edge, "vpn", "status", "--profile", str(profile)).stdout == "VPN stopped\n"


def test_vpn_down_stops_it_and_is_idempotent(lab: VpnLab) -> None:
    down = fogiac(lab.edge, "vpn", "down", "--profile", str(lab.profile))
    assert (down.returncode, down.stdout) == (0, "VPN down\n")
    assert lab.edge.run(["ip", "link", "show", "tun0"], check=False).returncode != 0
    assert fogiac(lab.edge, "vpn", "status", "--profile", str(lab.profile)).stdout == "VPN stopped\n"
    again = fogiac(lab.edge, "vpn", "down", "--profile", str(lab.profile))
    assert (again.returncode, again.stdout) == (0, "VPN not running\n")


def test_a_revoked_robots_certificate_is_refused_and_restored(lab: VpnLab) -> None:
    """Issue 34 on aws: each robot of a fleet dials with its own certificate; once the stack's CRL lists arm3's
    (``fogiac robot revoke arm3``), the endpoint refuses arm3 while arm1 still connects, and a CRL without it
    (``restore``) lets arm3 in again. OpenVPN re-reads ``crl-verify`` on each handshake, as the Client VPN
    endpoint applies the list imported into it."""
    server_dir = lab.workdir / "server"
    robots = {r: certs.issue(lab.bundle.ca, identity(STACK, r), server=False) for r in ("arm1", "arm3")}
    profiles = {r: write_client_profile(endpoint_dns=AWS_PUBLIC, stack=STACK, ca_pem=lab.bundle.ca.cert_pem,
                                        cert_pem=p.cert_pem, key_pem=p.key_pem,
                                        path=lab.workdir / f"vpn-{r}" / "client.ovpn") for r, p in robots.items()}
    serial = x509.load_pem_x509_certificate(robots["arm3"].cert_pem).serial_number
    certs.write_private(server_dir / "revoked.crl.pem", build_crl(lab.bundle.ca, (serial,)))
    try:
        up = fogiac(lab.edge, "vpn", "up", "--profile", str(profiles["arm1"]), "--timeout", "30")
        assert up.returncode == 0, up.stderr
        assert fogiac(lab.edge, "vpn", "down", "--profile", str(profiles["arm1"])).returncode == 0

        # OpenVPN's client is never told (TLS 1.3: the endpoint checks the client's certificate after the client's
        # side of the handshake is done), so ``vpn up`` gives up at its timeout: 10 s, for a handshake that takes
        # about one; the endpoint's own log line below is what shows arm3 was refused.
        refused = fogiac(lab.edge, "vpn", "up", "--profile", str(profiles["arm3"]), "--timeout", "10")
        assert refused.returncode == 1, refused.stdout
        assert "certificate revoked" in (server_dir / "openvpn.log").read_text(errors="replace")
        assert fogiac(lab.edge, "vpn", "status", "--profile", str(profiles["arm3"])).stdout == "VPN stopped\n"

        certs.write_private(server_dir / "revoked.crl.pem", build_crl(lab.bundle.ca, ()))  # restored
        back = fogiac(lab.edge, "vpn", "up", "--profile", str(profiles["arm3"]), "--timeout", "30")
        assert back.returncode == 0, back.stderr
    finally:
        for profile in profiles.values():
            fogiac(lab.edge, "vpn", "down", "--profile", str(profile))
