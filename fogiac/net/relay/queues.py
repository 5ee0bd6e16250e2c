"""Bounded per-topic queues feeding one writer, latest-wins.

A slow link must not pile up seconds of lag: when a topic's queue is full the oldest message
is dropped (and counted), so what crosses is always recent. Control frames have their own
lane and go first; it is bounded too (:data:`CONTROL_LIMIT`): a peer that sends PINGs but never
reads our PONGs fills it, and then :meth:`Outbox.put_control` says so and the link is closed.
Topics are served round-robin so a 6 MiB stream cannot starve a 100 Hz one.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Sequence

from fogiac.net.relay.framing import Payload

Item = Sequence[Payload]
CONTROL_LIMIT = 4096  # far above a healthy link's few pending OPEN/STATE/PONG frames


class Outbox:
    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._control: deque[Item] = deque()
        self._topics: dict[int, deque[Item]] = {}
        self._ready: deque[int] = deque()
        self._closed = False

    def put_control(self, item: Item) -> bool:
        """Queue a control frame; False when the lane is full (the peer is not reading)."""
        with self._cond:
            if len(self._control) >= CONTROL_LIMIT:
                return False
            self._control.append(item)
            self._cond.notify()
            return True

    def put(self, topic: int, item: Item, *, depth: int) -> int:
        """Queue ``item`` for ``topic``; returns how many stale items were dropped for it."""
        with self._cond:
            if self._closed:
                return 0
            queue = self._topics.get(topic)
            if queue is None:
                queue = self._topics[topic] = deque()
            dropped = 0
            while len(queue) >= max(depth, 1):
                queue.popleft()
                dropped += 1
            if not queue:
                self._ready.append(topic)
            queue.append(item)
            self._cond.notify()
            return dropped

    def wait(self) -> bool:
        """Block until something is queued (True) or the outbox is closed (False)."""
        with self._cond:
            while not self._closed and not self._control and not any(self._topics.values()):
                self._cond.wait()
            return not self._closed

    def empty(self) -> bool:
        with self._cond:
            return not self._control and not any(self._topics.values())

    def take_batch(self, *, max_bytes: int = 256 * 1024) -> list[Item]:
        """Whatever is queued now, up to about ``max_bytes``, so many small messages leave in
        one write (one TLS record, one syscall). Never blocks."""
        batch: list[Item] = []
        size = 0
        while size < max_bytes:
            item = self.get(timeout=0)
            if item is None:
                break
            batch.append(item)
            size += sum(len(b) for b in item)
        return batch

    def discard(self, topic: int) -> None:
        with self._cond:
            self._topics.pop(topic, None)

    def get(self, timeout: float | None = None) -> Item | None:
        """The next item to write, or None when closed (or nothing came within ``timeout``)."""
        with self._cond:
            while True:
                if self._closed:
                    return None
                if self._control:
                    return self._control.popleft()
                while self._ready:
                    topic = self._ready.popleft()
                    queue = self._topics.get(topic)
                    if not queue:
                        continue
                    item = queue.popleft()
                    if queue:
                        self._ready.append(topic)
                    return item
                if not self._cond.wait(timeout):
                    return None

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._topics.clear()
            self._control.clear()
            self._cond.notify_all()
