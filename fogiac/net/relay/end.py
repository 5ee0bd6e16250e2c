"""What the edge and cloud ends share: the ROS node, the monitor, the live figures."""

from __future__ import annotations

import dataclasses
import logging
import threading
from collections.abc import Mapping
from typing import Any

from fogiac.net.relay.config import EndConfig
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.graph import GraphState, from_system_state
from fogiac.net.relay.monitor import Monitor
from fogiac.net.relay.node import RelayNode
from fogiac.net.relay.session import Session
from fogiac.net.relay.stats import RelayStats, TopicStats, write_stats

log = logging.getLogger(__name__)


class RelayEnd:
    role = "end"

    def __init__(self, config: EndConfig, caller_id: str) -> None:
        self.config, self.caller_id = config, caller_id
        self.node: RelayNode | None = None
        self._monitor: Monitor | None = None
        self.session: Session | None = None
        self.reconnects = 0
        self._stopping = threading.Event()
        self._threads: list[threading.Thread] = []
        self._drops_logged: dict[str, int] = {}

    def start(self) -> None:
        """Register with the local master and begin linking; RelayError if the master is unreachable."""
        self.node = RelayNode(master_uri=self.config.master_uri, caller_id=self.caller_id, host=self.config.ros_host)
        self.node.start()
        try:
            self._monitor = Monitor(self.node)
            self._monitor.start()
            self._start_link()
        except BaseException:
            self.node.stop()
            raise
        self._spawn(self._stats_loop, "relay-stats")

    def stop(self) -> None:
        self._stopping.set()
        self._stop_link()
        sessions = self._sessions()
        for session in sessions:
            session.close("relay stopping")
        for session in sessions:
            session.closed.wait(10)
        if self._monitor is not None:
            self._monitor.stop()
        if self.node is not None:
            self.node.stop()
        for thread in self._threads:
            thread.join(timeout=5)

    def __enter__(self) -> RelayEnd:
        self.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def _sessions(self) -> list[Session]:
        """Every session this end holds: the edge's one link; the cloud end's one per edge identity."""
        session = self.session
        return [session] if session is not None else []

    def stats(self) -> RelayStats:
        """Topics, latency, throughput and drops as of the last second, over every live session (the
        clock figures are the latest session's)."""
        live = [s for s in self._sessions() if s.alive]
        latest = self.session if self.session in live else (live[-1] if live else None)
        rtt = latest.clock.rtt_ns if latest is not None else None
        return RelayStats(
            role=self.role, connected=bool(live),
            rtt_ms=None if rtt is None else round(rtt / 1e6, 3),
            clock_offset_ms=round(latest.clock.offset_ns / 1e6, 3) if latest is not None else 0.0,
            reconnects=self.reconnects, refused=sum(s.refused for s in live),
            topics=tuple(sorted((_with_peer_latency(c.snapshot(), s.peer_latency) for s in live for c in s.counters()),
                                key=lambda t: (t.topic, t.direction))),
        )

    # --- for subclasses --------------------------------------------------------------------
    def _start_link(self) -> None:
        raise NotImplementedError

    def _stop_link(self) -> None:
        raise NotImplementedError

    def _spawn(self, target: Any, name: str, *args: Any) -> threading.Thread:
        thread = threading.Thread(target=target, args=args, name=name, daemon=True)
        thread.start()
        self._threads.append(thread)
        return thread

    def local_graph(self, *, types: bool = False) -> GraphState | None:
        """This master's graph without the relay; with ``types``, the published topics' types too."""
        assert self.node is not None
        try:
            state = self.node.master.system_state()
            if not any(self.caller_id in nodes for _, nodes in state[0]):
                # Our monitor topics are always registered: the master forgot us (restarted).
                log.warning("the ROS master at %s lost the relay's registrations; registering again",
                            self.config.master_uri)
                self.node.register_all()
            known = self.node.master.topic_types() if types else None
            return from_system_state(state, exclude={self.caller_id}, types=known)
        except RelayError as err:
            log.warning("cannot read the local ROS graph: %s", err)
            return None

    def _stats_loop(self) -> None:
        while not self._stopping.wait(1.0):
            for session in self._sessions():
                for counters in session.counters():
                    counters.tick()
            stats = self.stats()
            if self._monitor is not None:
                self._monitor.publish(stats)
            for t in stats.topics:
                if t.drops > self._drops_logged.get(t.topic, 0):
                    log.info("%s: %d stale messages dropped so far (latest-wins queue)", t.topic, t.drops)
                    self._drops_logged[t.topic] = t.drops
            if self.config.stats_file is not None:
                try:
                    write_stats(self.config.stats_file, stats)
                except OSError as err:
                    log.warning("cannot write %s: %s", self.config.stats_file, err)


def _with_peer_latency(stats: TopicStats, peer: Mapping[str, tuple[float | None, float | None]]) -> TopicStats:
    """A topic this end sends shows the one-way latency the peer measured where it arrives."""
    if stats.direction != "out" or stats.latency_ms is not None or stats.topic not in peer:
        return stats
    median, p99 = peer[stats.topic]
    return dataclasses.replace(stats, latency_ms=median, latency_p99_ms=p99)
