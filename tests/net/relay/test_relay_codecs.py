"""Pure codecs of the relay: frames, TCPROS headers, compression, discovery, queues."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fogiac.net.relay import framing, tcpros
from fogiac.net.relay.compression import codec, parse_spec
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Frame, FrameError, Kind
from fogiac.net.relay.graph import GraphState, Route, TopicPolicy, from_system_state, may_cross, select_routes
from fogiac.net.relay.queues import Outbox
from fogiac.net.relay.stats import ClockSync


@given(st.sampled_from(list(Kind)), st.integers(0, 2**32 - 1), st.binary(max_size=2000))
def test_frames_round_trip(kind: Kind, topic: int, payload: bytes) -> None:
    frame = Frame(kind, topic, payload)
    assert list(framing.decode_stream(framing.encode(frame) * 2)) == [frame, frame]


def test_absurd_length_is_refused_before_reading_it() -> None:
    header = struct.pack("!IBI", 0xFFFFFFFF, int(Kind.DATA), 1)
    with pytest.raises(FrameError, match=r"frame length 4294967295 outside 5\.\.67108928"):
        framing.parse_header(header)


def test_length_shorter_than_header_is_refused() -> None:
    with pytest.raises(FrameError, match=r"frame length 2 outside"):
        framing.parse_header(struct.pack("!IBI", 2, int(Kind.PING), 0))


def test_unknown_kind_is_refused() -> None:
    with pytest.raises(FrameError, match="unknown frame kind 200"):
        framing.parse_header(struct.pack("!IBI", 5, 200, 0))


def test_truncated_stream_is_refused() -> None:
    data = framing.encode(Frame(Kind.PING, 0, b"12345678"))
    with pytest.raises(FrameError, match="truncated frame: 8 bytes announced, 3 present"):
        list(framing.decode_stream(data[:-5]))
    with pytest.raises(FrameError, match="truncated frame header"):
        list(framing.decode_stream(data[:4]))


def test_oversized_frame_cannot_be_encoded() -> None:
    with pytest.raises(FrameError, match="exceeds the maximum"):
        framing.encode_header(Kind.DATA, 1, framing.MAX_FRAME)


def test_data_frame_carries_stamp_and_bytes_unchanged() -> None:
    body = bytes(range(256)) * 10
    wire = framing.data_prefix(7, 123456789, len(body)) + body
    (frame,) = framing.decode_stream(wire)
    stamp, view = framing.split_data(frame.payload)
    assert (frame.kind, frame.topic, stamp, bytes(view)) == (Kind.DATA, 7, 123456789, body)


def test_json_frames_must_hold_objects() -> None:
    assert framing.parse_json(framing.json_frame(Kind.HELLO, {"role": "edge"})) == {"role": "edge"}
    with pytest.raises(FrameError, match="HELLO frame must carry a JSON object"):
        framing.parse_json(Frame(Kind.HELLO, 0, b"[1]"))
    with pytest.raises(FrameError, match="STATE frame carries invalid JSON"):
        framing.parse_json(Frame(Kind.STATE, 0, b"\xff{"))


def test_ping_pong_sizes_are_checked() -> None:
    assert framing.parse_pong(framing.pong(1, 2)) == (1, 2)
    with pytest.raises(FrameError, match="PING frame must carry one 8-byte stamp"):
        framing.parse_ping(Frame(Kind.PING, 0, b"123"))


@given(st.dictionaries(st.text(min_size=1).filter(lambda k: "=" not in k), st.text(), max_size=8))
def test_tcpros_headers_round_trip(fields: dict[str, str]) -> None:
    wire = tcpros.encode_header(fields)
    (size,) = struct.unpack("<I", wire[:4])
    assert size == len(wire) - 4
    assert tcpros.decode_header(wire[4:]) == fields


def test_tcpros_header_with_equals_in_value_keeps_it() -> None:
    wire = tcpros.encode_header({"message_definition": "a=b\nc=d"})
    assert tcpros.decode_header(wire[4:]) == {"message_definition": "a=b\nc=d"}


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (b"\x05\x00", "truncated field length"),
        (b"\xff\x00\x00\x00abc", "header field of 255 bytes overruns the header"),
        (b"\x03\x00\x00\x00abc", "header field b'abc' has no '='"),
        (b"\x03\x00\x00\x00a=\xff", "header field is not UTF-8"),
    ],
)
def test_malformed_tcpros_headers_are_refused(body: bytes, message: str) -> None:
    with pytest.raises(tcpros.TcprosError, match=message):
        tcpros.decode_header(body)


def test_subscriber_check() -> None:
    ok = {"callerid": "/n", "topic": "/a", "md5sum": "*"}
    assert tcpros.check_subscriber(ok, topic="/a", md5sum="abc") is None
    assert tcpros.check_subscriber({**ok, "md5sum": "x"}, topic="/a", md5sum="abc") == (
        "md5sum x does not match abc on /a"
    )
    with pytest.raises(tcpros.TcprosError, match="subscriber header lacks 'md5sum'"):
        tcpros.check_subscriber({"callerid": "/n", "topic": "/a"}, topic="/a", md5sum="abc")


@pytest.mark.parametrize("name", ["none", "zstd", "lz4"])
def test_compression_round_trips(name: str) -> None:
    data = bytes(range(256)) * 400
    c = codec(name)
    packed = c.compress(data)
    assert c.decompress(memoryview(packed)) == data
    if name != "none":
        assert len(packed) < len(data) / 10


@pytest.mark.parametrize("name", ["zstd", "lz4"])
def test_decompression_stops_at_the_frame_limit(name: str) -> None:
    c = codec(name)
    bomb = c.compress(bytes(framing.MAX_FRAME + 1))  # a few KB that claim more than a frame may hold
    with pytest.raises(FrameError, match=f"expands beyond {framing.MAX_FRAME} bytes"):
        c.decompress(bomb)
    assert len(c.decompress(c.compress(bytes(framing.MAX_FRAME)))) == framing.MAX_FRAME


@pytest.mark.parametrize("name", ["zstd", "lz4"])
def test_corrupt_compressed_data_is_a_frame_error(name: str) -> None:
    with pytest.raises(FrameError, match=f"invalid {name} data"):
        codec(name).decompress(b"\x28\xb5\x2f\xfd\x04\x22\x4d\x18garbage")


def test_cloud_policy_accepts_only_listed_or_discovered_directions() -> None:
    graph = _graph({"/map": ["/mapper"]}, {"/scan": ["/slam"]})
    listed = TopicPolicy(out_topics=("/goal",), in_topics=("/path",))
    assert may_cross("/goal", "out", listed, graph) and may_cross("/path", "in", listed, graph)
    assert not may_cross("/goal", "in", listed, graph) and not may_cross("/cmd_vel", "in", listed, graph)
    auto = TopicPolicy(auto=True)
    assert may_cross("/map", "in", auto, graph) and may_cross("/scan", "out", auto, graph)
    assert not may_cross("/map", "out", auto, graph) and not may_cross("/cmd_vel", "in", auto, graph)
    assert not may_cross("/rosout", "out", auto, _graph({}, {"/rosout": ["/rosout"]}))


def test_unknown_compression_lists_valid_ones() -> None:
    with pytest.raises(RelayError, match=r"unknown compression 'gzip'; valid: lz4, none, zstd"):
        codec("gzip")
    assert parse_spec("zstd,/depth=lz4") == ("zstd", {"/depth": "lz4"})


def _graph(pubs: dict[str, list[str]], subs: dict[str, list[str]]) -> GraphState:
    return from_system_state([list(pubs.items()), list(subs.items()), []], exclude={"/fogiac_relay_edge"})


def test_auto_relays_publisher_to_subscriber_across_sides_only() -> None:
    edge = _graph({"/scan": ["/lidar"], "/rosout": ["/lidar"], "/local": ["/a"]}, {"/cmd": ["/base"], "/local": ["/b"]})
    cloud = _graph({"/cmd": ["/planner"]}, {"/scan": ["/planner"], "/rosout": ["/rosout"]})
    assert select_routes(edge, cloud, TopicPolicy(auto=True)) == {Route("/scan", "out"), Route("/cmd", "in")}


def test_relay_registrations_do_not_count() -> None:
    edge = _graph({"/scan": ["/fogiac_relay_edge"]}, {})
    cloud = _graph({}, {"/scan": ["/planner"]})
    assert select_routes(edge, cloud, TopicPolicy(auto=True)) == frozenset()


def test_explicit_topics() -> None:
    edge = _graph({"/a": ["/n"]}, {})
    cloud = _graph({"/b": ["/m"]}, {})
    policy = TopicPolicy(topics=("/a", "/b", "/c"), out_topics=("/x",), in_topics=("/y",))
    assert select_routes(edge, cloud, policy) == {
        Route("/a", "out"), Route("/b", "in"), Route("/x", "out"), Route("/y", "in")
    }


def test_graph_state_json_round_trips() -> None:
    state = _graph({"/a": ["/n", "/m"]}, {"/b": ["/k"]})
    assert GraphState.from_json(state.to_json()) == state


def test_outbox_drops_oldest_and_serves_control_first() -> None:
    box = Outbox()
    assert [box.put(1, (bytes([i]),), depth=2) for i in range(4)] == [0, 0, 1, 1]
    box.put(2, (b"b",), depth=2)
    box.put_control((b"ctl",))
    got = [box.get(timeout=0) for _ in range(4)]
    assert got == [(b"ctl",), (b"\x02",), (b"b",), (b"\x03",)]
    assert box.get(timeout=0) is None and box.empty()
    box.put(3, (b"x" * 10,), depth=9)
    box.put(3, (b"y" * 10,), depth=9)
    assert box.take_batch(max_bytes=5) == [(b"x" * 10,)]
    assert box.take_batch() == [(b"y" * 10,)] and box.take_batch() == []
    box.close()
    assert box.get() is None and not box.wait()


def test_clock_sync_keeps_the_shortest_round_trip() -> None:
    clock = ClockSync()
    clock.add(0, 1_000_500, 1_000)  # rtt 1 us, peer ahead by 1 ms
    clock.add(0, 9_000_000, 50_000)  # a slow sample must not win
    assert (clock.rtt_ns, clock.offset_ns) == (1_000, 1_000_000)
