"""A cloud end's REFUSE frame and its REPORT's reply counts are read as untrusted bytes by the edge.

The edge trusts the cloud end's certificate, not what it says: a refusal reason full of terminal escapes, ten
kilobytes long or not text at all ends up printable and short in the edge's stats (which ``fogiac status``
prints), and the edge still backs off; reply counts that are not counts are dropped, not written.
"""

from __future__ import annotations

import json
import ssl
from pathlib import Path

import pytest

from fogiac.net.relay import EdgeConfig, EdgeRelay, framing
from fogiac.net.relay.framing import Kind
from fogiac.net.relay.session import read_frame
from tests.badinput.hostile_cloud import HostileCloud
from tests.net.relay.relay_support import Master, wait_for

pytestmark = pytest.mark.ros


def _handshake(fake: HostileCloud) -> ssl.SSLSocket:
    raw, _ = fake.listener.accept()
    conn = fake._ctx.wrap_socket(raw, server_side=True)
    conn.settimeout(10)
    assert read_frame(conn).kind is Kind.HELLO
    return conn


@pytest.mark.parametrize("reason", ["revoked\x1b[2J\x1b]0;pwned\x07", "r" * 10_000, 42, None])
def test_a_hostile_refusal_is_shown_printable_and_short(reason: object, masters: tuple[Master, Master],
                                                        certs: Path, tmp_path: Path) -> None:
    fake = HostileCloud(certs)
    stats = tmp_path / "edge.stats.json"
    edge = EdgeRelay(EdgeConfig(master_uri=masters[0].uri, certs=certs, ros_host="127.0.0.1", connect=fake.address,
                                poll_interval=0.1, backoff_initial=0.1, backoff_max=0.5,
                                refused_backoff_initial=0.2, refused_backoff_max=0.4, stats_file=stats))
    edge.start()
    try:
        with _handshake(fake) as conn:
            conn.sendall(framing.encode(framing.json_frame(Kind.REFUSE, {"reason": reason})))
        wait_for(lambda: edge.link_refused is not None, 10, "the edge to take the refusal")
        shown = edge.link_refused
        assert shown is not None and shown.isprintable() and len(shown) <= 120
        assert shown == ("revoked?[2J?]0;pwned?" if isinstance(reason, str) and reason.startswith("revoked")
                         else "r" * 120 if isinstance(reason, str) else "no reason given")
        with _handshake(fake):  # it dials again after its wait (never gives up)
            pass
        wait_for(lambda: stats.exists() and json.loads(stats.read_text()).get("link_refused") == shown, 10,
                 "the stats file")
        assert not edge.connected.is_set()
    finally:
        edge.stop()


def test_reply_counts_that_are_not_counts_are_dropped(masters: tuple[Master, Master], certs: Path) -> None:
    fake = HostileCloud(certs)
    edge = EdgeRelay(EdgeConfig(master_uri=masters[0].uri, certs=certs, ros_host="127.0.0.1", connect=fake.address,
                                poll_interval=0.1, backoff_initial=0.1, backoff_max=0.5))
    edge.start()
    try:
        fake.accept()
        fake.send(framing.encode(framing.json_frame(Kind.REPORT, {"latency": {}, "replies": {
            "served": "lots", "undelivered": -3, "evil": 7}})))
        fake.send(framing.encode(framing.json_frame(Kind.REPORT, {"latency": {}, "replies": {"served": True}})))
        fake.send(framing.encode(framing.json_frame(Kind.REPORT, {"latency": {}, "replies": {"served": 5}})))
        wait_for(lambda: edge.stats().routed == {"served": 5}, 10, "the one real count")
        assert edge.connected.is_set() and edge.reconnects == 0  # odd counts are dropped, the link stays
    finally:
        edge.stop()
