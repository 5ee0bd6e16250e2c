"""First reply wins: the middleware-neutral core of a replicated node's edge (relay and Zenoh alike).

A :class:`Merge` decides, for each request read off one of the node's ``in`` topics, which replicas get
it now (hedge ``all``: every live one; ``delayed``: the fastest first, the others when no reply came
within ``hedge_delay_s``, Dean and Barroso's hedged request), and for each reply whether it is the first
with its key on its topic (published) or a later copy (dropped). It counts per replica what ``fogiac
status`` shows. Thread-safe; it sends nothing itself: the middleware's edge does, with what it returns.

Memory is bounded: the last ``remember`` requests (for hedging and latency) and the last ``remember``
keys delivered per topic. Keys are bytes (:mod:`fogiac.net.relay.match` reads them off a message).
"""

from __future__ import annotations

import heapq
import statistics
import threading
from collections import OrderedDict, deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

HEDGES = ("all", "delayed")
WINDOW = 200  # latencies kept per replica for its median and p95


@dataclass
class _Figures:
    index: int
    host: str
    sent: int = 0
    answers: int = 0
    won: int = 0
    late: int = 0  # answers that came after another replica's (dropped)
    last_answer: float | None = None  # monotonic
    waiting_since: float | None = None  # the first request sent to it since its last answer
    latencies: deque[float] = field(default_factory=lambda: deque(maxlen=WINDOW))  # seconds

    def silent(self, now: float, after: float) -> bool:
        return self.waiting_since is not None and now - self.waiting_since > after


@dataclass
class _Request:
    arrived: float
    topic: str
    data: Any
    sent: set[int]
    answered: bool = False


class Merge:
    def __init__(self, replicas: Sequence[tuple[int, str]], *, hedge: str = "all", hedge_delay_s: float = 0.0,
                 remember: int = 4096, silent_after: float = 3.0) -> None:
        self.hedge, self.hedge_delay_s, self.remember, self.silent_after = hedge, hedge_delay_s, remember, silent_after
        self.figures = {i: _Figures(i, host) for i, host in replicas}
        self.lock = threading.RLock()  # re-entrant: a hedge loop reads next_due() holding ``changed``
        self.changed = threading.Condition(self.lock)  # a hedge timer was set
        self._requests: OrderedDict[bytes, _Request] = OrderedDict()
        self._delivered: dict[str, OrderedDict[bytes, None]] = {}
        self._timers: list[tuple[float, int, bytes]] = []
        self._seq = 0
        self._unmatched_from: int | None = None  # the one replica whose keyless replies pass (see reply)
        self.requests = self.delivered = self.duplicates = self.unmatched = 0

    def _first(self, live: list[int], now: float) -> int:
        """Whom a delayed hedge asks first: the fastest by recent answers once every live replica has
        answered, else the lowest index; a silent replica only when every one is."""
        known = all(self.figures[i].latencies for i in live)

        def rank(i: int) -> tuple[bool, float, int]:
            f = self.figures[i]
            return f.silent(now, self.silent_after), statistics.median(f.latencies) if known else 0.0, i

        return min(live, key=rank)

    def request(self, topic: str, key: bytes | None, data: Any, live: list[int], now: float) -> list[int]:
        """A request arrived: the replicas (of ``live``) to send it to now."""
        with self.lock:
            self.requests += 1
            if key is None or self.hedge == "all" or len(live) < 2:
                targets = list(live)
            else:
                targets = [self._first(live, now)]
                self._seq += 1
                heapq.heappush(self._timers, (now + self.hedge_delay_s, self._seq, key))
                self.changed.notify()
            if key is not None:
                self._requests[key] = _Request(now, topic, data, set(targets))
                self._requests.move_to_end(key)
                while len(self._requests) > self.remember:
                    self._requests.popitem(last=False)
            for i in targets:
                f = self.figures[i]
                f.sent += 1
                if f.waiting_since is None:
                    f.waiting_since = now
            return targets

    def next_due(self) -> float | None:
        with self.lock:
            return self._timers[0][0] if self._timers else None

    def due(self, now: float, live: list[int]) -> list[tuple[str, Any, list[int]]]:
        """Hedges whose delay ran out unanswered: (topic, request data, replicas to ask now)."""
        out = []
        with self.lock:
            while self._timers and self._timers[0][0] <= now:
                req = self._requests.get(heapq.heappop(self._timers)[2])
                if req is None or req.answered:
                    continue
                more = [i for i in live if i not in req.sent]
                for i in more:
                    req.sent.add(i)
                    f = self.figures[i]
                    f.sent += 1
                    if f.waiting_since is None:
                        f.waiting_since = now
                if more:
                    out.append((req.topic, req.data, more))
        return out

    def reply(self, topic: str, index: int, key: bytes | None, now: float) -> bool:
        """A replica's reply: True if it is the first with its key on ``topic`` (publish it)."""
        with self.lock:
            f = self.figures[index]
            f.answers += 1
            f.last_answer, f.waiting_since = now, None
            if key is None:
                # No key, no telling copies apart: one replica's keyless replies pass, the others' are dropped,
                # until that one falls silent. Never a duplicate, at the cost of no hedging for such replies.
                self.unmatched += 1
                sole = self._unmatched_from
                if sole is None or (sole != index and self.figures[sole].silent(now, self.silent_after)):
                    self._unmatched_from = sole = index
                if sole != index:
                    f.late += 1
                    self.duplicates += 1
                    return False
            else:
                req = self._requests.get(key)
                if req is not None:
                    f.latencies.append(now - req.arrived)
                    req.answered = True
                delivered = self._delivered.setdefault(topic, OrderedDict())
                if key in delivered:
                    f.late += 1
                    self.duplicates += 1
                    return False
                delivered[key] = None
                while len(delivered) > self.remember:
                    delivered.popitem(last=False)
            f.won += 1
            self.delivered += 1
            return True

    def stats(self, linked: set[int], now: float) -> dict[str, Any]:
        """Per replica: health (ok, silent, down), requests sent, answers, answers won, late copies dropped,
        latency median and p95 in ms, seconds since its last answer."""
        with self.lock:
            replicas = []
            for f in sorted(self.figures.values(), key=lambda f: f.index):
                lat = sorted(f.latencies)
                health = "down" if f.index not in linked else \
                    "silent" if f.silent(now, self.silent_after) else "ok"
                replicas.append({
                    "index": f.index, "host": f.host, "connected": f.index in linked, "health": health,
                    "sent": f.sent, "answers": f.answers, "won": f.won, "late": f.late,
                    "latency_ms": round(statistics.median(lat) * 1e3, 3) if lat else None,
                    "latency_p95_ms": round(lat[min(len(lat) - 1, int(len(lat) * 0.95))] * 1e3, 3) if lat else None,
                    "last_answer_s": None if f.last_answer is None else round(now - f.last_answer, 1),
                })
            return {"hedge": self.hedge, "hedge_delay_s": self.hedge_delay_s, "requests": self.requests,
                    "delivered": self.delivered, "duplicates_dropped": self.duplicates,
                    "unmatched": self.unmatched, "replicas": replicas}


def groups_of(routes: Sequence[Any]) -> dict[str, list[Any]]:
    """A plan's replicated nodes: group -> its routes (``Route.replica`` set), in replica order."""
    groups: dict[str, list[Any]] = {}
    for route in routes:
        if route.replica is not None:
            groups.setdefault(route.replica.group, []).append(route)
    return {g: sorted(rs, key=lambda r: r.replica.index) for g, rs in sorted(groups.items())}


def host_figures(routes: Sequence[Any],
                 written: Callable[[str], Mapping[str, Any] | None]) -> dict[str, dict[str, Any]]:
    """host -> its replica's figures for ``fogiac status``, from each group's stats (``written(group)``)."""
    out: dict[str, dict[str, Any]] = {}
    for group, members in groups_of(routes).items():
        doc = written(group) or {}
        by_host = {r.get("host"): r for r in doc.get("replicas", [])}
        for route in members:
            out[route.host] = {"group": group, "index": route.replica.index, "count": route.replica.count,
                               "hedge": route.replica.hedge, "health": "unknown", **by_host.get(route.host, {})}
    return out
