"""The relay's wire format: length-prefixed frames, many topics over one TLS stream.

Pure: no sockets here, so every malformed input is easy to test. A frame is

    length:u32be  kind:u8  topic:u32be  payload

where ``length`` counts the bytes after itself (kind + topic + payload). A length below the
fixed part, above :data:`MAX_FRAME`, or an unknown kind raises :class:`FrameError`; the caller
closes that one connection. Topic ids are scoped by sender: a DATA frame's id names a topic
the sender announced with OPEN.
"""

from __future__ import annotations

import enum
import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from fogiac.net.relay.errors import RelayError

HEADER = struct.Struct("!IBI")
_FIXED = HEADER.size - 4  # kind + topic, counted by ``length``
MAX_FRAME = 64 * 1024 * 1024 + 64
_STAMP = struct.Struct("!q")
_PONG = struct.Struct("!qq")

# A message's bytes as sockets hand them over and take them: passed along, never copied.
Payload = bytes | bytearray | memoryview


class FrameError(RelayError):
    """The peer sent bytes that are not a valid frame; drop its connection."""


class Kind(enum.IntEnum):
    HELLO = 1  # JSON: role, version, config (edge -> cloud)
    STATE = 2  # JSON: the sender's ROS graph, relay's own registrations left out
    SUBSCRIBE = 3  # JSON: {"topic", "compression"}: edge asks cloud to source a topic
    UNSUBSCRIBE = 4  # JSON: {"topic"}
    OPEN = 5  # topic id + JSON TopicMeta: the sender now sources this topic
    CLOSE = 6  # topic id
    DATA = 7  # topic id + stamp (sender's ns clock) + serialized message bytes
    PING = 8  # stamp
    PONG = 9  # echoed stamp + responder's stamp
    REPORT = 10  # JSON {"latency": {topic: [median_ms, p99_ms]}}: one-way latency where the sender receives
    REFUSE = 11  # JSON {"reason"}: the cloud end will not link this edge (a fleet's revoked or unknown robot);
    # sent instead of its HELLO, then it closes, so the edge backs off instead of redialling at its normal pace


@dataclass(frozen=True)
class Frame:
    kind: Kind
    topic: int
    payload: bytes | bytearray  # bytearray when read straight off a socket


def encode_header(kind: Kind, topic: int, payload_len: int) -> bytes:
    length = _FIXED + payload_len
    if length > MAX_FRAME:
        raise FrameError(f"frame of {length} bytes exceeds the maximum of {MAX_FRAME}")
    return HEADER.pack(length, int(kind), topic)


def encode(frame: Frame) -> bytes:
    return encode_header(frame.kind, frame.topic, len(frame.payload)) + frame.payload


def parse_header(header: bytes) -> tuple[Kind, int, int]:
    """``(kind, topic, payload_len)`` from the fixed header; FrameError when it is nonsense."""
    if len(header) != HEADER.size:
        raise FrameError(f"frame header must be {HEADER.size} bytes, got {len(header)}")
    length, kind, topic = HEADER.unpack(header)
    if length < _FIXED or length > MAX_FRAME:
        raise FrameError(f"frame length {length} outside {_FIXED}..{MAX_FRAME}")
    try:
        return Kind(kind), topic, length - _FIXED
    except ValueError:
        raise FrameError(f"unknown frame kind {kind}") from None


def decode_stream(data: bytes) -> Iterator[Frame]:
    """Frames in ``data``; FrameError on a bad header or a truncated tail."""
    view = memoryview(data)
    pos = 0
    while pos < len(view):
        if len(view) - pos < HEADER.size:
            raise FrameError("truncated frame header")
        kind, topic, size = parse_header(bytes(view[pos : pos + HEADER.size]))
        pos += HEADER.size
        if len(view) - pos < size:
            raise FrameError(f"truncated frame: {size} bytes announced, {len(view) - pos} present")
        yield Frame(kind, topic, bytes(view[pos : pos + size]))
        pos += size


def json_frame(kind: Kind, body: dict[str, Any], *, topic: int = 0) -> Frame:
    return Frame(kind, topic, json.dumps(body, separators=(",", ":"), sort_keys=True).encode())


def parse_json(frame: Frame) -> dict[str, Any]:
    try:
        body = json.loads(frame.payload)
    except (ValueError, UnicodeDecodeError) as err:
        raise FrameError(f"{frame.kind.name} frame carries invalid JSON: {err}") from None
    if not isinstance(body, dict):
        raise FrameError(f"{frame.kind.name} frame must carry a JSON object")
    return body


def data_prefix(topic: int, stamp_ns: int, body_len: int) -> bytes:
    """Header and stamp of a DATA frame; the body follows unchanged (no copy of big messages)."""
    return encode_header(Kind.DATA, topic, _STAMP.size + body_len) + _STAMP.pack(stamp_ns)


def split_data(payload: Payload) -> tuple[int, memoryview]:
    if len(payload) < _STAMP.size:
        raise FrameError("DATA frame shorter than its timestamp")
    view = memoryview(payload)
    return _STAMP.unpack(view[: _STAMP.size])[0], view[_STAMP.size :]


def ping(stamp_ns: int) -> Frame:
    return Frame(Kind.PING, 0, _STAMP.pack(stamp_ns))


def pong(echo_ns: int, stamp_ns: int) -> Frame:
    return Frame(Kind.PONG, 0, _PONG.pack(echo_ns, stamp_ns))


def parse_ping(frame: Frame) -> int:
    if len(frame.payload) != _STAMP.size:
        raise FrameError("PING frame must carry one 8-byte stamp")
    return _STAMP.unpack(frame.payload)[0]


def parse_pong(frame: Frame) -> tuple[int, int]:
    if len(frame.payload) != _PONG.size:
        raise FrameError("PONG frame must carry two 8-byte stamps")
    return _PONG.unpack(frame.payload)
