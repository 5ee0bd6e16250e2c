"""The relay pair between two real roscores with rospy publishers and subscribers."""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
import socket
import ssl
import struct
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.net.relay import CloudConfig, CloudRelay, EdgeConfig, EdgeRelay, TopicPolicy, read_stats
from fogiac.net.relay.tls import client_context, expected_server_name, write_relay_lab
from tests.net.relay.relay_support import Master, Procs, free_port, indices, string_msg, wait_for

pytestmark = pytest.mark.ros


@contextlib.contextmanager
def relay_pair(masters: tuple[Master, Master], certs: Path, **edge: object) -> Iterator[tuple[EdgeRelay, CloudRelay]]:
    edge_master, cloud_master = masters
    # Both ends enforce the same policy, as provisioning starts them.
    cloud = CloudRelay(CloudConfig(master_uri=cloud_master.uri, certs=certs, ros_host="127.0.0.1",
                                   listen=("127.0.0.1", 0), poll_interval=0.1,
                                   policy=edge.get("policy", TopicPolicy(auto=True))))  # type: ignore[arg-type]
    cloud.start()
    try:
        edge_end = EdgeRelay(EdgeConfig(master_uri=edge_master.uri, certs=edge.pop("edge_certs", certs),  # type: ignore[arg-type]
                                        ros_host="127.0.0.1", connect=cloud.address, poll_interval=0.1,
                                        backoff_max=1.0, **edge))  # type: ignore[arg-type]
        edge_end.start()
        try:
            yield edge_end, cloud
        finally:
            edge_end.stop()
    finally:
        cloud.stop()


def consecutive(values: list[int]) -> bool:
    return values == list(range(values[0], values[0] + len(values)))


def test_messages_cross_byte_identical_and_in_order_both_ways(masters: tuple[Master, Master], certs: Path,
                                                                procs: Procs) -> None:
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)):
        procs.node(edge_m, "pub", "/up", "--forever", "--rate", "50", "--size", "300")
        procs.node(cloud_m, "pub", "/down", "--forever", "--rate", "50")
        up = procs.node(cloud_m, "sub", "/up", "--count", "40")
        down = procs.node(edge_m, "sub", "/down", "--count", "40")
        wait_for(lambda: len(up.data()) >= 40 and len(down.data()) >= 40, 30, "40 messages each way")
    assert consecutive(indices(up.data())) and consecutive(indices(down.data()))
    assert all(len(raw) == 304 for raw in up.data())


def test_auto_discovery_adds_and_removes_topics(masters: tuple[Master, Master], certs: Path, procs: Procs) -> None:
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)) as (edge, cloud):
        pub = procs.node(edge_m, "pub", "/disc", "--forever")
        wait_for(lambda: cloud.session is not None, 10, "link")
        # A publisher alone is not enough: nobody on the cloud side wants it.
        assert "/fogiac_relay_edge" not in edge_m.subscribers("/disc")
        sub = procs.node(cloud_m, "sub", "/disc", "--count", "1000")
        wait_for(lambda: len(sub.data()) >= 5, 20, "messages after the subscriber appeared")
        assert cloud_m.publishers("/disc") == ["/fogiac_relay_cloud"]
        assert [t.topic for t in edge.stats().topics] == ["/disc"]
        procs.kill(sub)
        wait_for(lambda: not cloud_m.publishers("/disc"), 10, "the cloud registration to go")
        wait_for(lambda: "/fogiac_relay_edge" not in edge_m.subscribers("/disc"), 10, "the edge registration to go")
        # The route went, its totals stay: status still counts what crossed (a request whose client
        # has already gone, for one), on both ends.
        (sent,) = edge.stats().topics
        (got,) = cloud.stats().topics
        assert (sent.topic, sent.direction, got.topic, got.direction) == ("/disc", "out", "/disc", "in")
        assert sent.msgs >= 5 and got.msgs >= 5, (sent, got)
        sub2 = procs.node(cloud_m, "sub", "/disc", "--count", "3")
        wait_for(lambda: len(sub2.data()) >= 3, 20, "relaying to resume for a new subscriber")
        (again,) = edge.stats().topics  # one line for the topic, counting on from where it stopped
        assert again.msgs >= sent.msgs + 3, (sent, again)
        procs.kill(pub)
        wait_for(lambda: not cloud_m.publishers("/disc"), 10, "the route to go with the publisher")


def test_latched_topic_stays_latched_for_late_subscribers(masters: tuple[Master, Master], certs: Path,
                                                          procs: Procs) -> None:
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(topics=("/map",))):
        procs.node(edge_m, "pub", "/map", "--count", "3", "--latch", "--rate", "100")
        wait_for(lambda: cloud_m.publishers("/map") == ["/fogiac_relay_cloud"], 20, "the relay to advertise /map")
        late = procs.node(cloud_m, "sub", "/map", "--count", "1")
        wait_for(lambda: late.data(), 20, "the latched message")
        assert late.data()[-1] == string_msg("msg 2")


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_compressed_topics_round_trip(masters: tuple[Master, Master], certs: Path, procs: Procs,
                                      compression: str) -> None:
    edge_m, cloud_m = masters
    topic = f"/img_{compression}"
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True), topic_compression=((topic, compression),)) as (edge, _):
        procs.node(edge_m, "pub", topic, "--forever", "--rate", "50", "--size", "20000")
        sub = procs.node(cloud_m, "sub", topic, "--count", "100000")  # stays subscribed: the route stays up
        wait_for(lambda: len(sub.data()) >= 10, 20, "compressed messages")
        (stats,) = edge.stats().topics
        assert stats.compression == compression
    assert consecutive(indices(sub.data()))


def test_wrong_client_certificate_is_refused(masters: tuple[Master, Master], certs: Path, tmp_path: Path,
                                             caplog: pytest.LogCaptureFixture) -> None:
    rogue = tmp_path / "rogue"
    write_relay_lab("rogue", rogue)
    shutil.copy(certs / "ca.pem", rogue / "ca.pem")  # trusts the real cloud, shows a foreign client cert
    shutil.copy(certs / "server.pem", rogue / "server.pem")
    caplog.set_level(logging.INFO, logger="fogiac.net.relay")
    with relay_pair(masters, certs, edge_certs=rogue, policy=TopicPolicy(auto=True)) as (edge, cloud):
        wait_for(lambda: edge.last_error is not None, 15, "the edge to fail")
        assert not edge.connected.is_set() and cloud.session is None
    assert any("refused TLS connection" in r.getMessage() and "certificate verify failed" in r.getMessage()
               for r in caplog.records)


def _raw_client(certs: Path, address: tuple[str, int]) -> ssl.SSLSocket:
    sock = socket.create_connection(address, timeout=5)
    return client_context(certs).wrap_socket(sock, server_hostname=expected_server_name(certs))


def test_garbage_from_a_peer_closes_only_that_connection(masters: tuple[Master, Master], certs: Path,
                                                         procs: Procs) -> None:
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)) as (edge, cloud):
        procs.node(edge_m, "pub", "/steady", "--forever", "--rate", "50")
        sub = procs.node(cloud_m, "sub", "/steady", "--count", "100000")
        wait_for(lambda: len(sub.data()) >= 5, 20, "flow")
        for garbage in (struct.pack("!IBI", 0xFFFFFFF0, 7, 1), b"\x00\x00\x00\x05\xee\x00\x00\x00\x00"):
            with _raw_client(certs, cloud.address) as intruder:
                intruder.sendall(garbage)
                assert intruder.recv(100) == b""  # closed by the cloud end
        before = len(sub.data())
        wait_for(lambda: len(sub.data()) >= before + 10, 10, "the flow to go on")
        assert edge.reconnects == 0 and cloud.reconnects == 0
        assert consecutive(indices(sub.data()))


def test_edge_drops_a_peer_sending_an_absurd_length_and_redials(masters: tuple[Master, Master], certs: Path) -> None:
    """A fake cloud end completes TLS and HELLO, then sends a 4 GiB length prefix."""
    from fogiac.net.relay import framing
    from fogiac.net.relay.framing import Kind
    from fogiac.net.relay.session import read_frame
    from fogiac.net.relay.tls import server_context

    ctx = server_context(certs)
    listener = socket.create_server(("127.0.0.1", 0))
    accepted: list[bool] = []
    edge = EdgeRelay(EdgeConfig(master_uri=masters[0].uri, certs=certs, ros_host="127.0.0.1",
                                connect=listener.getsockname()[:2], backoff_initial=0.1, backoff_max=0.5))
    edge.start()
    try:
        for _ in range(2):
            raw, _ = listener.accept()
            with ctx.wrap_socket(raw, server_side=True) as conn:
                assert read_frame(conn).kind is Kind.HELLO
                conn.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "cloud"})))
                conn.sendall(struct.pack("!IBI", 0xFFFFFFFF, 7, 1))
                conn.settimeout(5)
                try:
                    while conn.recv(65536):  # pings until the edge hangs up
                        pass
                except (ssl.SSLError, OSError):
                    pass
                accepted.append(True)
        assert len(accepted) == 2 and edge.reconnects >= 1
    finally:
        edge.stop()
        listener.close()


def test_cloud_restart_resumes_the_flow(masters: tuple[Master, Master], certs: Path, procs: Procs,
                                        tmp_path: Path) -> None:
    edge_m, cloud_m = masters
    port = free_port()
    cloud_argv = ["-m", "fogiac", "relay", "cloud", "--listen", f"127.0.0.1:{port}", "--master", cloud_m.uri,
                  "--certs", str(certs), "--ros-host", "127.0.0.1"]
    first = procs.spawn([sys.executable, *cloud_argv], cloud_m.env)
    stats_file = tmp_path / "edge.json"
    edge = procs.spawn([sys.executable, "-m", "fogiac", "relay", "edge", "--connect", f"127.0.0.1:{port}",
                        "--master", edge_m.uri, "--certs", str(certs), "--ros-host", "127.0.0.1",
                        "--stats-file", str(stats_file)], edge_m.env)
    procs.node(edge_m, "pub", "/resume", "--forever", "--rate", "50")
    sub = procs.node(cloud_m, "sub", "/resume", "--count", "100000")
    wait_for(lambda: len(sub.data()) >= 5, 30, "flow through the first cloud end")
    procs.kill(first, 9)
    procs.spawn([sys.executable, *cloud_argv], cloud_m.env)
    before = len(sub.data())
    wait_for(lambda: len(sub.data()) >= before + 20, 40, "flow through the restarted cloud end")
    wait_for(lambda: stats_file.exists() and read_stats(stats_file).reconnects >= 1, 10, "stats to show a reconnect")
    assert edge.popen.poll() is None


def test_monitoring_publishes_only_while_subscribed(masters: tuple[Master, Master], certs: Path,
                                                    procs: Procs) -> None:
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)) as (edge, cloud):
        procs.node(edge_m, "pub", "/mon", "--forever", "--rate", "20", "--size", "1000")
        sub = procs.node(cloud_m, "sub", "/mon", "--count", "100000")
        wait_for(lambda: len(sub.data()) >= 30, 20, "flow")
        assert cloud._monitor is not None and cloud._monitor.published == 0
        assert cloud_m.publishers("/fogros/latency") == ["/fogiac_relay_cloud"]
        lat = procs.node(cloud_m, "sub", "/fogros/latency", "--count", "3")
        thr = procs.node(edge_m, "sub", "/fogros/throughput", "--count", "3")
        wait_for(lambda: len(lat.data()) >= 3 and len(thr.data()) >= 3, 20, "monitoring messages")
        assert cloud._monitor.published > 0
        latency = json.loads(lat.data()[-1][4:])
        throughput = json.loads(thr.data()[-1][4:])
    assert latency["role"] == "cloud" and latency["connected"] is True
    mon = latency["topics"]["/mon"]
    assert mon["direction"] == "in" and 0 < mon["median_ms"] < 1000
    assert 0 < latency["rtt_ms"] < 1000
    out = throughput["topics"]["/mon"]
    assert throughput["role"] == "edge" and out["direction"] == "out"
    assert 5 < out["msgs_per_s"] < 40 and 5 * 1004 < out["bytes_per_s"] < 40 * 1004 and out["drops"] == 0


def test_edge_refuses_a_cloud_with_another_name(masters: tuple[Master, Master], certs: Path) -> None:
    with relay_pair(masters, certs, server_name="impostor.fogiac", policy=TopicPolicy(auto=True)) as (edge, cloud):
        wait_for(lambda: edge.last_error is not None, 15, "the edge to fail")
        assert "Hostname mismatch" in edge.last_error and not edge.connected.is_set()


def test_publishers_joining_later_are_followed(masters: tuple[Master, Master], certs: Path, procs: Procs) -> None:
    """The master's publisherUpdate reaches the relay: a second publisher's messages cross too."""
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)):
        procs.node(edge_m, "pub", "/multi", "--forever", "--rate", "20")
        sub = procs.node(cloud_m, "sub", "/multi", "--count", "100000")
        wait_for(lambda: len(sub.data()) >= 3, 20, "the first publisher's messages")
        second = procs.node(edge_m, "pub", "/multi", "--forever", "--rate", "20", "--prefix", "other")
        wait_for(lambda: any(raw[4:].startswith(b"other") for raw in sub.data()), 20, "the second publisher's")
        procs.kill(second)
        wait_for(lambda: len(edge_m.publishers("/multi")) == 1, 10, "the second publisher to leave")
        count = len(sub.data())
        wait_for(lambda: len(sub.data()) >= count + 5, 10, "the first publisher to keep flowing")


def test_relay_registers_again_after_its_master_restarts(certs: Path, procs: Procs, ros_ready: None) -> None:
    edge_m, cloud_m = procs.roscore(), procs.roscore()
    with relay_pair((edge_m, cloud_m), certs, policy=TopicPolicy(topics=("/again",))):
        procs.node(edge_m, "pub", "/again", "--forever", "--rate", "20")
        sub = procs.node(cloud_m, "sub", "/again", "--count", "100000")
        wait_for(lambda: len(sub.data()) >= 3, 20, "flow")
        assert cloud_m.proc is not None
        procs.kill(cloud_m.proc)
        procs.kill(sub)
        cloud_m = procs.roscore(int(cloud_m.uri.rsplit(":", 1)[1].strip("/")))
        wait_for(lambda: "/fogiac_relay_cloud" in cloud_m.publishers("/again"), 20, "the relay to register again")
        assert cloud_m.publishers("/fogros/latency") == ["/fogiac_relay_cloud"]
        late = procs.node(cloud_m, "sub", "/again", "--count", "3")
        wait_for(lambda: len(late.data()) >= 3, 20, "flow on the new master")


def test_first_message_reaches_a_subscriber_already_waiting_on_the_far_side(
        masters: tuple[Master, Master], certs: Path, procs: Procs) -> None:
    """One request, published the moment the relay connects: the cloud advertises the topic only
    then, and its waiting subscriber dials in a moment later; the message must still arrive."""
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(out_topics=("/once",))):
        sub = procs.node(cloud_m, "sub", "/once", "--count", "1")
        wait_for(lambda: cloud_m.subscribers("/once"), 10, "the cloud subscriber")
        procs.node(edge_m, "pub", "/once", "--count", "1", "--wait-subs", "--prefix", "only")
        wait_for(lambda: len(sub.data()) >= 1, 20, "the single message")
    assert indices(sub.data()) == [0]


def test_the_sending_end_shows_the_latency_its_peer_measured(masters: tuple[Master, Master], certs: Path,
                                                              procs: Procs) -> None:
    """A topic the robot sends (camera images) is timed where it arrives, on the cloud end; the cloud
    reports it back each ping interval, so the edge's stats (what ``fogiac status`` reads) show it too."""
    edge_m, cloud_m = masters
    with relay_pair(masters, certs, policy=TopicPolicy(auto=True)) as (edge, cloud):
        procs.node(edge_m, "pub", "/camera", "--forever", "--rate", "50", "--size", "2000")
        sub = procs.node(cloud_m, "sub", "/camera", "--count", "100000")
        wait_for(lambda: len(sub.data()) >= 20, 20, "images on the cloud side")

        def sent() -> object:
            (mine,) = [t for t in edge.stats().topics if t.topic == "/camera"]
            return mine if mine.latency_ms is not None else None

        wait_for(sent, 20, "the cloud's latency report")
        mine = sent()
        (theirs,) = [t for t in cloud.stats().topics if t.topic == "/camera"]
        assert mine.direction == "out" and theirs.direction == "in"
        assert 0 <= mine.latency_ms <= mine.latency_p99_ms
        assert theirs.latency_ms is not None
