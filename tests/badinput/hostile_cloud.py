"""A fake cloud end that completes mutual TLS and HELLO like the real one, then sends whatever
a peer case file says. It plays the attacker the edge must survive."""

from __future__ import annotations

import json
import socket
import ssl
from pathlib import Path
from typing import Any

import lz4.frame
import zstandard

from fogiac.net.relay import framing
from fogiac.net.relay.framing import Frame, Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import server_context

STRING_META = {"type": "std_msgs/String", "md5sum": "992ce8a1687cec8c8bd883ec73ca41d1",
               "definition": "string data", "latching": False}


class HostileCloud:
    def __init__(self, certs: Path) -> None:
        self._ctx = server_context(certs)
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(10)
        self.conn: ssl.SSLSocket | None = None

    @property
    def address(self) -> tuple[str, int]:
        host, port = self.listener.getsockname()[:2]
        return host, port

    def accept(self) -> ssl.SSLSocket:
        """The edge's next connection, past TLS and HELLO; socket.timeout if it never dials."""
        raw, _ = self.listener.accept()
        conn = self._ctx.wrap_socket(raw, server_side=True)
        conn.settimeout(10)
        assert read_frame(conn).kind is Kind.HELLO
        conn.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "cloud", "version": 1})))
        self.conn = conn
        return conn

    def await_subscribe(self, topics: set[str]) -> None:
        """Read the edge's frames until it has asked for every topic in ``topics``."""
        assert self.conn is not None
        wanted = set(topics)
        while wanted:
            frame = read_frame(self.conn)
            if frame.kind is Kind.SUBSCRIBE:
                wanted.discard(framing.parse_json(frame)["topic"])

    def send(self, data: bytes) -> None:
        assert self.conn is not None
        self.conn.sendall(data)

    def hung_up(self, within: float = 5.0) -> bool:
        """Whether the edge closes this connection within ``within`` seconds (well before it would
        give up on a silent peer); its pings are read and ignored."""
        assert self.conn is not None
        self.conn.settimeout(within)
        try:
            while self.conn.recv(65536):
                pass
        except TimeoutError:
            return False
        except (ssl.SSLError, OSError):
            pass
        return True

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
        self.listener.close()


def frame_bytes(step: dict[str, Any]) -> bytes:
    """One step of a peer case: ``open``, ``data`` or ``raw`` (hex), as bytes on the wire."""
    if "raw" in step:
        return bytes.fromhex(step["raw"])
    if "open" in step:
        spec = dict(step["open"])
        body = {**STRING_META, "compression": "none", **spec}
        topic_id = int(body.pop("id", 1))
        return framing.encode(Frame(Kind.OPEN, topic_id, json.dumps(body).encode()))
    spec = dict(step["data"])
    topic_id = int(spec.get("id", 1))
    if "zstd_zeros" in spec:  # bytes(n) is calloc'd: zero pages cost the test no memory
        body = zstandard.ZstdCompressor().compress(bytes(int(spec["zstd_zeros"])))  # size in the header
    elif "lz4_zeros" in spec:
        body = lz4.frame.compress(bytes(int(spec["lz4_zeros"])))
    else:
        body = bytes.fromhex(spec.get("hex", ""))
    return framing.data_prefix(topic_id, 0, len(body)) + body
