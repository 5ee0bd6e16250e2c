"""On ``local`` the edge side listens on loopback only (issue 26 item 13): the edge relay's XML-RPC and
TCPROS sockets, and the roscore ``--start-edge-master`` runs, when the edge master is on loopback.
A real roscore started as ``up`` starts it, a real edge relay started with the argv ``up`` gives it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import xmlrpc.client
from pathlib import Path

import pytest

from fogiac.net.relay.deploy import EDGE_MASTER, edge_argv, prepare_edge
from fogiac.provision import supervise
from tests.net.relay.relay_support import Procs, free_port, wait_for
from tests.net.zenoh.lab import route

pytestmark = [pytest.mark.ros, pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss (iproute2)")]


def _tree(root: int) -> set[int]:
    """``root`` and every process below it."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            parents[int(entry)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, grew = {root}, True
    while grew:
        more = {pid for pid, parent in parents.items() if parent in found} - found
        found |= more
        grew = bool(more)
    return found


def _listening(pids: set[int]) -> list[str]:
    out = subprocess.run(["ss", "-Hltnp"], capture_output=True, text=True, check=True).stdout
    return [line.split()[3] for line in out.splitlines() if any(f"pid={p}," in line for p in pids)]


@pytest.fixture
def no_ros_address(monkeypatch: pytest.MonkeyPatch) -> None:
    """An operator's shell without ROS_IP or ROS_HOSTNAME, as after a plain `source setup.bash`."""
    monkeypatch.delenv("ROS_IP", raising=False)
    monkeypatch.delenv("ROS_HOSTNAME", raising=False)


@pytest.mark.usefixtures("no_ros_address")
def test_the_edge_roscore_fogiac_starts_listens_on_loopback_only(tmp_path: Path) -> None:
    port = free_port()
    prepare_edge(f"http://127.0.0.1:{port}/", folder=tmp_path, start=True)
    try:
        sup = int((tmp_path / f"{EDGE_MASTER}.pid").read_text().split()[0])  # the supervisor: roscore below it
        wait_for(lambda: f"127.0.0.1:{port}" in _listening(_tree(sup)), 30, "the edge master to listen")
        # a node registered on it is told about others over XML-RPC: a rospy node of the operator's
        state = xmlrpc.client.ServerProxy(f"http://127.0.0.1:{port}/").getSystemState("/test")
        assert state[0] == 1
        listening = _listening(_tree(sup))  # every process fogiac started for it (no rosout: see prepare_edge)
        assert all(a.startswith("127.0.0.1:") for a in listening), listening
    finally:
        supervise.stop(tmp_path, EDGE_MASTER)


@pytest.mark.usefixtures("no_ros_address")
def test_the_edge_relay_up_starts_listens_on_loopback_only(tmp_path: Path, certs: Path, procs: Procs) -> None:
    master = procs.roscore()
    argv = edge_argv(route(free_port()), stack="relaytest", connect=f"127.0.0.1:{free_port()}", master=master.uri,
                     certs=certs, stats=tmp_path / "edge.stats.json")
    env = {k: v for k, v in master.env.items() if k not in ("ROS_IP", "ROS_HOSTNAME")}
    relay = procs.spawn(argv, env)
    assert argv[0] == sys.executable
    wait_for(lambda: len(_listening({relay.popen.pid})) >= 2, 30, "the edge relay's XML-RPC and TCPROS sockets")
    listening = _listening({relay.popen.pid})
    assert all(a.startswith("127.0.0.1:") for a in listening), listening
