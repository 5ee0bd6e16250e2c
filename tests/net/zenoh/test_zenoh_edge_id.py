"""A cloud router's "edge connected" counts only the edge's own router (issue 26 item 10): a zenohd or a
bridge on the host, linked to the loopback port, must not keep the host awake forever."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogiac.net.zenoh.deploy import edge_router_id
from fogiac.procs import poll
from tests.net.zenoh.lab import STACK, ZenohLab, free_ports, route

pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytestmark = pytest.mark.zenoh


def _stats(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def test_only_the_edge_routers_own_id_counts_as_connected(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        tls_port, cloud_local, edge_local, other_local = free_ports(4)
        stats = tmp_path / "router.stats.json"
        lab.router("cloud-router", lab.cloud_config(route(tls_port), local_port=cloud_local),
                   "--stats-file", str(stats), "--edge-id", edge_router_id(STACK))
        # another router on the host (a zenohd, a bridge in router mode) linked to the loopback port
        other = {"mode": "router", "id": "123456789abcdef0123456789abcdef0",
                 "listen": {"endpoints": [f"tcp/127.0.0.1:{other_local}"]},
                 "connect": {"endpoints": [f"tcp/127.0.0.1:{cloud_local}"]},
                 "scouting": {"multicast": {"enabled": False}}}
        lab.router("host-zenohd", other)
        seen = poll(lambda: (s := _stats(stats)) and other["id"] in s["routers"] and s, timeout=20)
        assert seen, "the other router never linked"
        assert seen["connected"] is False, "a router on the host counted as the edge"
        edge = lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local)
        edge["id"] = edge_router_id(STACK)  # as fogiac's edge_up names it
        lab.router("edge-router", edge)
        assert poll(lambda: (s := _stats(stats)) and s["connected"] or None, timeout=20), "the edge never counted"
