"""Handshake slots (issue 26 item 7): a source holding idle, unauthenticated connections, re-opened as soon
as they are closed, does not keep the real edge out, and the cloud end's log says so in a few lines, not one
per refusal. A real cloud end and a real edge end on real roscores; the attacker is plain TCP on loopback,
the same source as the edge (the hardest case: a per-source limit alone cannot tell them apart)."""

from __future__ import annotations

import logging
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.net.relay import CloudConfig, CloudRelay, EdgeConfig, EdgeRelay, TopicPolicy
from tests.net.relay.relay_support import Master, wait_for

pytestmark = pytest.mark.ros

IDLE = 16


class Squatter:
    """Keeps ``count`` idle TCP connections open to ``address``, re-opening each the server closes."""

    def __init__(self, address: tuple[str, int], count: int) -> None:
        self.address, self.count = address, count
        self.opened = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _open(self) -> socket.socket | None:
        try:
            sock = socket.create_connection(self.address, timeout=2)
        except OSError:
            return None
        sock.setblocking(False)
        self.opened += 1
        return sock

    def _run(self) -> None:
        socks: list[socket.socket | None] = [self._open() for _ in range(self.count)]
        while not self._stop.wait(0.01):
            for i, sock in enumerate(socks):
                if sock is not None:
                    try:
                        if sock.recv(1) != b"":
                            continue
                    except BlockingIOError:
                        continue  # still open, still idle
                    except OSError:
                        pass
                    sock.close()
                socks[i] = self._open()
        for sock in socks:
            if sock is not None:
                sock.close()

    def __enter__(self) -> Squatter:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(10)


@pytest.fixture
def cloud(masters: tuple[Master, Master], certs: Path) -> Iterator[CloudRelay]:
    end = CloudRelay(CloudConfig(master_uri=masters[1].uri, certs=certs, ros_host="127.0.0.1",
                                 listen=("127.0.0.1", 0), poll_interval=0.1, policy=TopicPolicy(auto=True)))
    end.start()
    try:
        yield end
    finally:
        end.stop()


def test_idle_connections_from_the_edges_own_source_do_not_keep_it_out(
        cloud: CloudRelay, masters: tuple[Master, Master], certs: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="fogiac.net.relay")
    with Squatter(cloud.address, IDLE) as squatter:
        wait_for(lambda: squatter.opened >= IDLE, 10, "the idle connections")
        edge = EdgeRelay(EdgeConfig(master_uri=masters[0].uri, certs=certs, ros_host="127.0.0.1",
                                    connect=cloud.address, poll_interval=0.1, backoff_max=1.0))
        edge.start()
        try:
            wait_for(lambda: cloud.stats().connected, 20, "the real edge to get through")
            wait_for(lambda: squatter.opened >= 4 * IDLE, 20, "the squatter to keep trying")
            assert cloud.stats().connected  # still: the squatter's churn never evicts an edge past its hello
        finally:
            edge.stop()
    lines = [r for r in caplog.records if r.name == "fogiac.net.relay.cloud" and r.levelno >= logging.WARNING]
    assert cloud.turned_away >= 2 * IDLE  # many refusals ...
    assert len(lines) <= 10, [r.getMessage() for r in lines]  # ... said in a few lines
