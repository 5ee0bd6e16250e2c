"""Hostile relay peers: each file in ``peers/`` is a case a reviewer can add without code.

A case lists the topics the edge asks for (``ask``), the frames a fake cloud end sends after
the handshake (``open``, ``data`` with ``hex``/``zstd_zeros``/``lz4_zeros``, or ``raw`` hex), and
what must happen: ``redial`` (the edge drops that link and dials again) or ``refused`` (the edge
refuses and counts, the link stays up). ``never_published`` topics must not appear on the
robot's master; ``max_rss_growth_mib`` bounds this process's peak memory growth.
"""

from __future__ import annotations

import resource
from pathlib import Path
from typing import Any

import pytest
import yaml

from fogiac.net.relay import EdgeConfig, EdgeRelay, TopicPolicy
from tests.badinput.hostile_cloud import HostileCloud, frame_bytes
from tests.net.relay.relay_support import Master, wait_for

pytestmark = pytest.mark.ros
CASES = sorted(Path(__file__).with_name("peers").glob("*.yaml"))


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_edge_survives_a_hostile_cloud(case: Path, masters: tuple[Master, Master], certs: Path) -> None:
    spec: dict[str, Any] = yaml.safe_load(case.read_text())
    assert spec["expect"] in ("redial", "refused"), f"{case.name}: expect must be redial or refused"
    ask = tuple(spec.get("ask", ()))
    wire = [frame_bytes(step) for step in spec["frames"]]
    fake = HostileCloud(certs)
    edge = EdgeRelay(EdgeConfig(master_uri=masters[0].uri, certs=certs, ros_host="127.0.0.1", connect=fake.address,
                                policy=TopicPolicy(in_topics=ask), poll_interval=0.1,
                                backoff_initial=0.1, backoff_max=0.5))
    peak = _peak_mib()
    edge.start()
    try:
        fake.accept()
        fake.await_subscribe(set(ask))
        for data in wire:
            fake.send(data)
        if spec["expect"] == "redial":
            assert fake.hung_up()
            fake.accept()  # times out (and fails) if the edge never dials again
            wait_for(lambda: edge.reconnects >= 1, 10, "the edge to count a reconnect")
        else:
            wait_for(lambda: edge.stats().refused >= spec.get("refused", 1), 10, "the edge to refuse")
            assert edge.connected.is_set() and edge.reconnects == 0
        for topic in spec.get("never_published", ()):
            assert "/fogiac_relay_edge" not in masters[0].publishers(topic)
        if "max_rss_growth_mib" in spec:
            assert _peak_mib() - peak < spec["max_rss_growth_mib"]
    finally:
        edge.stop()
        fake.close()
