"""First reply wins: the middleware-neutral core of a replicated node's edge (relay and Zenoh alike).

A :class:`Merge` decides, for each request read off one of the node's ``in`` topics, which replicas get
it now (hedge ``all``: every live one; ``delayed``: the fastest first, the others when no reply came
within ``hedge_delay_s``, Dean and Barroso's hedged request), and for each reply whether it answers a
request not yet answered on its topic (published) or not (dropped). It counts per replica what ``fogiac
status`` shows. Thread-safe; it sends nothing itself: the middleware's edge does, with what it returns.

A replica is trusted with nothing it was not asked: a reply is published only as the answer to a
request that was sent to that replica and that no reply on the topic has answered yet. A replica's
replies are accounted on its own requests, in the order they were sent to it:

- a reply with a key answers the replica's oldest request with that key it has not answered on the
  topic (so requests with equal keys, a zero stamp for one, are each answered once, never merged); a
  key that names none of its requests is dropped (an answer before the question, or junk), unless the
  request it would answer had no key of its own;
- a reply without a key answers the replica's oldest request it has not answered on the topic.

So a replica that chatters can spend only its own requests, never another replica's: the healthy
replica's answers pass. Memory is bounded: the last ``remember`` requests, and for each the replicas
and topics that answered; a reply to a forgotten request is dropped. Keys are bytes
(:mod:`fogiac.net.relay.match` reads them off a message).
"""

from __future__ import annotations

import bisect
import heapq
import statistics
import threading
from collections import OrderedDict, deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

HEDGES = ("all", "delayed")
WINDOW = 200  # latencies kept per replica for its median and p95
_ANY, _NOKEY = "any", "no key"  # queue names beside the keys (bytes): every request, requests without a key


@dataclass
class _Figures:
    index: int
    host: str
    sent: int = 0
    answers: int = 0  # replies that answered one of its requests (first or not)
    won: int = 0
    late: int = 0  # answers that came after another replica's (dropped)
    unsolicited: int = 0  # replies that answered none of its requests (dropped)
    last_answer: float | None = None  # monotonic
    waiting_since: float | None = None  # the first request sent to it since its last answer
    latencies: deque[float] = field(default_factory=lambda: deque(maxlen=WINDOW))  # seconds

    def silent(self, now: float, after: float) -> bool:
        return self.waiting_since is not None and now - self.waiting_since > after


@dataclass
class _Request:
    seq: int
    arrived: float
    topic: str
    key: bytes | None
    data: Any
    sent: set[int]
    answered: set[str] = field(default_factory=set)  # the reply topics a reply was published on
    replied: set[int] = field(default_factory=set)  # the replicas that answered it (for latency)
    taken: set[tuple[int, str]] = field(default_factory=set)  # (replica, reply topic) that answered it


@dataclass
class _Queue:
    """One replica's remembered requests of one kind (a key, or all of them), by sequence number, and how far
    its replies on each topic have got through them."""

    seqs: list[int] = field(default_factory=list)
    taken: dict[str, int] = field(default_factory=dict)  # reply topic -> the last request answered on it

    def after(self, topic: str) -> list[int]:
        """The requests after the last one answered on ``topic``, oldest first."""
        return self.seqs[bisect.bisect_right(self.seqs, self.taken.get(topic, 0)):]


class Merge:
    def __init__(self, replicas: Sequence[tuple[int, str]], *, hedge: str = "all", hedge_delay_s: float = 0.0,
                 remember: int = 4096, silent_after: float = 3.0) -> None:
        self.hedge, self.hedge_delay_s, self.remember, self.silent_after = hedge, hedge_delay_s, remember, silent_after
        self.figures = {i: _Figures(i, host) for i, host in replicas}
        self.lock = threading.RLock()  # re-entrant: a hedge loop reads next_due() holding ``changed``
        self.changed = threading.Condition(self.lock)  # a hedge timer was set
        self._requests: OrderedDict[int, _Request] = OrderedDict()  # by sequence number, oldest first
        self._queues: dict[tuple[int, bytes | str], _Queue] = {}  # (replica, key or _ANY or _NOKEY)
        self._timers: list[tuple[float, int]] = []
        self._seq = 0
        self.requests = self.delivered = self.duplicates = self.unmatched = self.unsolicited = 0

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
            self._seq += 1
            req = _Request(self._seq, now, topic, key, data, set())
            self._requests[req.seq] = req
            if self.hedge == "all" or len(live) < 2:
                targets = list(live)
            else:
                targets = [self._first(live, now)]
                heapq.heappush(self._timers, (now + self.hedge_delay_s, req.seq))
                self.changed.notify()
            self._send(req, targets, now)
            while len(self._requests) > self.remember:
                self._forget(self._requests.popitem(last=False)[1])
            return targets

    def _send(self, req: _Request, targets: list[int], now: float) -> None:
        for i in targets:
            req.sent.add(i)
            for kind in (_ANY, _NOKEY if req.key is None else req.key):
                bisect.insort(self._queues.setdefault((i, kind), _Queue()).seqs, req.seq)
            f = self.figures[i]
            f.sent += 1
            if f.waiting_since is None:
                f.waiting_since = now

    def _forget(self, req: _Request) -> None:
        for i in req.sent:
            for kind in (_ANY, _NOKEY if req.key is None else req.key):
                queue = self._queues.get((i, kind))
                if queue is None:
                    continue
                pos = bisect.bisect_left(queue.seqs, req.seq)
                if pos < len(queue.seqs) and queue.seqs[pos] == req.seq:
                    del queue.seqs[pos]
                if not queue.seqs:
                    del self._queues[(i, kind)]

    def next_due(self) -> float | None:
        with self.lock:
            return self._timers[0][0] if self._timers else None

    def due(self, now: float, live: list[int]) -> list[tuple[str, Any, list[int]]]:
        """Hedges whose delay ran out unanswered: (topic, request data, replicas to ask now)."""
        out = []
        with self.lock:
            while self._timers and self._timers[0][0] <= now:
                req = self._requests.get(heapq.heappop(self._timers)[1])
                if req is None or req.answered:
                    continue
                more = [i for i in live if i not in req.sent]
                self._send(req, more, now)
                if more:
                    out.append((req.topic, req.data, more))
        return out

    def _answers(self, topic: str, index: int, key: bytes | None) -> _Request | None:
        """The request this reply of replica ``index`` answers (see the module's docstring), marked answered
        by it on ``topic``; None: it answers none of the requests sent to it."""
        kinds: tuple[bytes | str, ...] = (_ANY,) if key is None else (key, _NOKEY)
        for kind in kinds:
            queue = self._queues.get((index, kind))
            for seq in queue.after(topic) if queue is not None else ():
                assert queue is not None
                queue.taken[topic] = seq
                req = self._requests[seq]
                if (index, topic) not in req.taken:  # (else answered through another queue: a key, or none)
                    req.taken.add((index, topic))
                    return req
        return None

    def reply(self, topic: str, index: int, key: bytes | None, now: float) -> bool:
        """A replica's reply: True if it answers a request sent to it that no reply on ``topic`` has answered
        yet (publish it)."""
        with self.lock:
            f = self.figures[index]
            if key is None:
                self.unmatched += 1
            req = self._answers(topic, index, key)
            if req is None:
                f.unsolicited += 1
                self.unsolicited += 1
                return False
            f.answers += 1
            f.last_answer, f.waiting_since = now, None
            if index not in req.replied:
                req.replied.add(index)
                f.latencies.append(now - req.arrived)
            if topic in req.answered:
                f.late += 1
                self.duplicates += 1
                return False
            req.answered.add(topic)
            f.won += 1
            self.delivered += 1
            return True

    def stats(self, linked: set[int], now: float) -> dict[str, Any]:
        """Per replica: health (ok, silent, down), requests sent, answers, answers won, late copies dropped,
        replies that answered none of its requests, latency median and p95 in ms, seconds since its last
        answer."""
        with self.lock:
            replicas = []
            for f in sorted(self.figures.values(), key=lambda f: f.index):
                lat = sorted(f.latencies)
                health = "down" if f.index not in linked else \
                    "silent" if f.silent(now, self.silent_after) else "ok"
                replicas.append({
                    "index": f.index, "host": f.host, "connected": f.index in linked, "health": health,
                    "sent": f.sent, "answers": f.answers, "won": f.won, "late": f.late,
                    "unsolicited": f.unsolicited,
                    "latency_ms": round(statistics.median(lat) * 1e3, 3) if lat else None,
                    "latency_p95_ms": round(lat[min(len(lat) - 1, int(len(lat) * 0.95))] * 1e3, 3) if lat else None,
                    "last_answer_s": None if f.last_answer is None else round(now - f.last_answer, 1),
                })
            return {"hedge": self.hedge, "hedge_delay_s": self.hedge_delay_s, "requests": self.requests,
                    "delivered": self.delivered, "duplicates_dropped": self.duplicates,
                    "unmatched": self.unmatched, "unsolicited": self.unsolicited, "replicas": replicas}


def groups_of(routes: Sequence[Any]) -> dict[str, list[Any]]:
    """A plan's replicated nodes: group -> its routes (``Route.replica`` set), in replica order."""
    groups: dict[str, list[Any]] = {}
    for route in routes:
        if route.replica is not None:
            groups.setdefault(route.replica.group, []).append(route)
    return {g: sorted(rs, key=lambda r: r.replica.index) for g, rs in sorted(groups.items())}


def host_figures(routes: Sequence[Any],
                 written: Callable[[str], Mapping[str, Any] | None]) -> dict[str, dict[str, Any]]:
    """host -> its replica's figures for ``fogiac status``, from each group's stats (``written(group)``);
    ``number`` is the replica as shown (1 of 2, on ``<node>-r1``), ``index`` the plan's (from 0)."""
    out: dict[str, dict[str, Any]] = {}
    for group, members in groups_of(routes).items():
        doc = written(group) or {}
        by_host = {r.get("host"): r for r in doc.get("replicas", [])}
        for route in members:
            out[route.host] = {"group": group, "index": route.replica.index, "number": route.replica.index + 1,
                               "count": route.replica.count,
                               "hedge": route.replica.hedge, "health": "unknown", **by_host.get(route.host, {})}
    return out
