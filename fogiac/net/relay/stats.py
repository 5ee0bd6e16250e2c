"""Live relay figures: per-topic rates, drops, latency, and the link's clock offset.

Counters are bumped from I/O threads and read by the monitor once a second. One-way latency
uses an NTP-style estimate of the peer's clock offset (ping/pong over the link, keeping the
sample with the smallest round trip), so two hosts' clocks need not agree.
"""

from __future__ import annotations

import json
import os
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any


class ClockSync:
    """Offset of the peer's clock from ours (peer - local, ns) and the link's round trip.

    The best sample is found when one is added (once a ping), not when read: every message
    that arrives reads the offset."""

    def __init__(self, window: int = 16) -> None:
        self._samples: deque[tuple[int, int]] = deque(maxlen=window)
        self._best: tuple[int, int] | None = None
        self.offset_ns = 0

    def add(self, t0: int, peer: int, t3: int) -> None:
        """``t0`` ping sent (local), ``peer`` pong stamped (peer), ``t3`` pong received (local)."""
        self._samples.append((t3 - t0, peer - (t0 + t3) // 2))
        self._best = best = min(self._samples)
        self.offset_ns = best[1]

    @property
    def rtt_ns(self) -> int | None:
        best = self._best
        return None if best is None else best[0]

    def reset(self) -> None:
        self._samples.clear()
        self._best, self.offset_ns = None, 0


@dataclass(frozen=True)
class TopicStats:
    topic: str
    direction: str  # "out": this end sends it over the link; "in": this end publishes it
    msgs_per_s: float
    bytes_per_s: float
    msgs: int
    bytes: int
    drops: int
    latency_ms: float | None  # median one-way over the last second that carried messages (measured where
    # a message arrives: an "out" topic shows what the peer reported, Kind.REPORT)
    latency_p99_ms: float | None
    compression: str


@dataclass(frozen=True)
class RelayStats:
    role: str
    connected: bool
    rtt_ms: float | None
    clock_offset_ms: float
    reconnects: int
    topics: tuple[TopicStats, ...] = field(default_factory=tuple)
    refused: int = 0  # the peer's requests for topics outside this end's policy, this link
    link_refused: str | None = None  # edge: why the cloud end refused the link at the last dial ("revoked")
    # A fleet's cloud end: per shared request/reply node, its routing figures (:meth:`ReplyRouter.stats`: the
    # replies each robot was served, those lost with its link, the strays no robot asked for: ``unmatched``...)
    replies: dict[str, dict[str, Any]] | None = None
    routed: dict[str, int] | None = None  # a fleet robot's edge: the cloud end's count of its replies (served...)

    def to_json(self) -> str:
        return json.dumps(asdict(self), separators=(",", ":"))

    @classmethod
    def from_json(cls, text: str) -> RelayStats:
        body = json.loads(text)
        body["topics"] = tuple(TopicStats(**t) for t in body["topics"])
        return cls(**body)


class TopicCounters:
    """Running totals of one topic on one end; ``tick`` turns them into per-second rates."""

    def __init__(self, topic: str, direction: str, compression: str) -> None:
        self.topic, self.direction, self.compression = topic, direction, compression
        self.more_drops: Callable[[], int] | None = None  # drops counted elsewhere (a slow local subscriber)
        self.msgs = self.bytes = self.drops = 0
        self._latencies: deque[int] = deque(maxlen=1000)
        self._last = (time.monotonic(), 0, 0)
        self._rates = (0.0, 0.0)
        self._lat: tuple[float | None, float | None] = (None, None)
        self._lock = threading.Lock()

    def count(self, size: int, latency_ns: int | None = None) -> None:
        self.msgs += 1
        self.bytes += size
        if latency_ns is not None:
            self._latencies.append(latency_ns)

    def drop(self, n: int = 1) -> None:
        self.drops += n

    def tick(self) -> None:
        with self._lock:
            now = time.monotonic()
            then, msgs, nbytes = self._last
            span = max(now - then, 1e-6)
            self._rates = ((self.msgs - msgs) / span, (self.bytes - nbytes) / span)
            self._last = (now, self.msgs, self.bytes)
            taken, self._latencies = self._latencies, deque(maxlen=1000)
            lat = sorted(taken)
            if lat:  # kept through quiet seconds: a request every few seconds still shows its latency
                p99 = lat[min(len(lat) - 1, int(len(lat) * 0.99))]
                self._lat = (statistics.median(lat) / 1e6, p99 / 1e6)

    def snapshot(self) -> TopicStats:
        return TopicStats(
            self.topic, self.direction, round(self._rates[0], 3), round(self._rates[1], 1),
            self.msgs, self.bytes, self.drops + (self.more_drops() if self.more_drops else 0),
            None if self._lat[0] is None else round(self._lat[0], 3),
            None if self._lat[1] is None else round(self._lat[1], 3),
            self.compression,
        )


def write_stats(path: Path, stats: RelayStats) -> None:
    """Atomically replace ``path`` so a reader (``fogiac status``) never sees half a file."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(stats.to_json())
    os.replace(tmp, path)


def read_stats(path: Path) -> RelayStats:
    """The figures a running ``fogiac relay ... --stats-file PATH`` last wrote."""
    return RelayStats.from_json(Path(path).read_text())
