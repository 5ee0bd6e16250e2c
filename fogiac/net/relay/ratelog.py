"""Log lines an outsider can provoke, at most one per kind per period.

Why: every refused connection was a log line, so anyone able to open TCP connections to the
relay's port could fill the host's disk (2 MB in 45 s). Each kind of line is written at once the
first time, then at most once per ``period`` with how many were left out meanwhile.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable


class RateLimitedLog:
    def __init__(self, log: logging.Logger, *, period: float = 10.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._log, self._period, self._clock = log, period, clock
        self._lock = threading.Lock()
        self._last: dict[str, float] = {}
        self._held: dict[str, int] = {}

    def warning(self, kind: str, message: str, *args: object) -> None:
        """Log ``message % args`` unless a ``kind`` line was logged less than ``period`` ago."""
        now = self._clock()
        with self._lock:
            last = self._last.get(kind)
            if last is not None and now - last < self._period:
                self._held[kind] = self._held.get(kind, 0) + 1
                return
            held = self._held.pop(kind, 0)
            self._last[kind] = now
        suffix = f" ({held} more like it in the last {self._period:g} s, not logged)" if held else ""
        self._log.warning(message + suffix, *args)
