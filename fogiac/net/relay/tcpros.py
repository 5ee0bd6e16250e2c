"""TCPROS: the connection header and the message stream of ROS 1 topics.

Codec functions are pure; the ``read_*``/``write_*`` helpers take a socket. A connection header
is ``u32le total`` then fields ``u32le len, b"key=value"``; every message after it is
``u32le len`` then the serialized bytes, which the relay never decodes.
"""

from __future__ import annotations

import socket
import struct

from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Payload

_U32 = struct.Struct("<I")
MAX_HEADER = 1024 * 1024
MAX_MESSAGE = 64 * 1024 * 1024


class TcprosError(RelayError):
    """A TCPROS peer sent a malformed header or message, or refused the handshake."""


def encode_header(fields: dict[str, str]) -> bytes:
    """The header with its 4-byte length prefix, ready to send."""
    body = bytearray()
    for key, value in fields.items():
        if "=" in key:
            raise TcprosError(f"header key {key!r} must not contain '='")
        item = f"{key}={value}".encode()
        body += _U32.pack(len(item)) + item
    return _U32.pack(len(body)) + bytes(body)


def decode_header(body: bytes) -> dict[str, str]:
    """Fields of a header body (without its outer length prefix)."""
    fields: dict[str, str] = {}
    pos = 0
    while pos < len(body):
        if len(body) - pos < 4:
            raise TcprosError("truncated field length in connection header")
        (size,) = _U32.unpack_from(body, pos)
        pos += 4
        if size > len(body) - pos:
            raise TcprosError(f"header field of {size} bytes overruns the header")
        item = body[pos : pos + size]
        pos += size
        key, sep, value = item.partition(b"=")
        if not sep:
            raise TcprosError(f"header field {item[:40]!r} has no '='")
        try:
            fields[key.decode()] = value.decode()
        except UnicodeDecodeError:
            raise TcprosError("header field is not UTF-8") from None
    return fields


def frame_message(data: Payload) -> bytes:
    return _U32.pack(len(data)) + data


def recv_exact(sock: socket.socket, size: int) -> bytearray:
    """Exactly ``size`` bytes; ConnectionError on EOF (the peer left)."""
    buf = bytearray(size)
    view = memoryview(buf)
    got = 0
    while got < size:
        n = sock.recv_into(view[got:], size - got)
        if n == 0:
            raise ConnectionError("peer closed the connection")
        got += n
    return buf


class Stream:
    """Exact-size reads from a socket. Buffered (the default), a burst of small messages costs
    one system call instead of two each; ``buffer=0`` never reads past what was asked (for a
    handshake, before the socket changes hands)."""

    def __init__(self, sock: socket.socket, *, buffer: int = 256 * 1024) -> None:
        self._sock = sock
        self._file = sock.makefile("rb", buffering=buffer) if buffer else None

    def exact(self, size: int) -> bytes | bytearray:
        if self._file is None:
            return recv_exact(self._sock, size)
        data = self._file.read(size)
        if len(data) != size:
            raise ConnectionError("peer closed the connection")
        return data

    def close(self) -> None:
        if self._file is not None:
            self._file.close()


def read_header(stream: Stream) -> dict[str, str]:
    (size,) = _U32.unpack(stream.exact(4))
    if size > MAX_HEADER:
        raise TcprosError(f"connection header of {size} bytes exceeds {MAX_HEADER}")
    fields = decode_header(bytes(stream.exact(size)))
    if "error" in fields:
        raise TcprosError(f"peer refused the connection: {fields['error']}")
    return fields


def read_message(stream: Stream) -> bytes | bytearray:
    (size,) = _U32.unpack(stream.exact(4))
    if size > MAX_MESSAGE:
        raise TcprosError(f"message of {size} bytes exceeds {MAX_MESSAGE}")
    return stream.exact(size)


def write_message(sock: socket.socket, data: Payload) -> None:
    if len(data) < 65536:
        sock.sendall(_U32.pack(len(data)) + data)
    else:  # two writes beat copying megabytes
        sock.sendall(_U32.pack(len(data)))
        sock.sendall(data)


def subscriber_header(*, caller_id: str, topic: str, type_name: str, md5sum: str = "*") -> dict[str, str]:
    return {"callerid": caller_id, "topic": topic, "type": type_name, "md5sum": md5sum, "tcp_nodelay": "1"}


def publisher_header(
    *, caller_id: str, topic: str, type_name: str, md5sum: str, definition: str, latching: bool
) -> dict[str, str]:
    return {
        "callerid": caller_id,
        "topic": topic,
        "type": type_name,
        "md5sum": md5sum,
        "message_definition": definition,
        "latching": "1" if latching else "0",
    }


def check_subscriber(request: dict[str, str], *, topic: str, md5sum: str) -> str | None:
    """Why a subscriber's header is refused, or None when it may connect."""
    for field in ("callerid", "topic", "md5sum"):
        if field not in request:
            raise TcprosError(f"subscriber header lacks '{field}'")
    if request["topic"] != topic:
        return f"topic {request['topic']} is not served here ({topic})"
    if request["md5sum"] not in ("*", md5sum):
        return f"md5sum {request['md5sum']} does not match {md5sum} on {topic}"
    return None
