"""The autostop watchdog: a host with no edge and no traffic for N minutes stops itself.

Why on the host: a forgotten stack must stop without the operator's laptop. The watchdog runs
as one more supervised service beside the middleware's cloud side and judges "idle" only from
what fogiac already knows, the stats file that side writes every second (the relay's cloud end,
the Zenoh router): no edge connected (``connected``) and no message crossing (the ``msgs`` of its
``topics`` did not move, where it counts them). A host with no stats file yet counts as idle
from the watchdog's start, so a host whose edge never came stops too, though never before
``START_GRACE_S`` after that start (the ``up`` that started it is still bringing its edge in).
A stats file not rewritten for ``STATS_STALE_S`` (its writer stopped, hung or was SIGSTOPped)
says nothing either: its last ``connected: true`` must not keep the host up (the operator's
side judges it the same way).

How it stops is the target's choice (``--power``): ``machine`` powers the host off (on EC2 the
instance's shutdown behaviour, stop or terminate, is set by the compute stack); ``services``
stops every fogiac service in the run folder, itself last (the local target's sandboxes, lab
machines that must stay on). Before stopping it writes ``autostop.json`` in the run folder, the
file ``fogiac status`` reads: idle since when, when it will stop, and whether it has.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from fogiac.provision import supervise

STATE_FILE = "autostop.json"
SERVICE = "autostop"
_POLL_S = 1.0
STATS_STALE_S = 30.0  # stats are written every second; older than this, their writer no longer runs
START_GRACE_S = 60.0  # a (re)started host waits at least this long for its edge's first link


@dataclass(frozen=True)
class IdleState:
    """What the watchdog last concluded (wall-clock seconds since the epoch)."""

    idle_since: float | None  # None: the edge is connected or traffic is crossing
    stops_at: float | None
    stopped_at: float | None = None
    action: str = "stop"

    def to_json(self) -> str:
        return json.dumps(asdict(self), separators=(",", ":"))


@dataclass(frozen=True)
class Activity:
    """What a middleware's stats file says about the host's link to the edge, at one moment."""

    connected: bool  # an edge is linked now (the relay's edge end, the edge's Zenoh router)
    msgs: int | None = None  # messages crossed so far; None where the file does not count them


class IdleClock:
    """Pure: feeds on activity snapshots and says since when the host has been idle.

    ``grace_s`` is the least time a host gets, from the clock's start, before it is judged idle while
    nothing has linked yet: its services were just (re)started by ``fogiac up``, whose edge end dials
    in moments later (seconds on a loaded machine), and a short ``idle_s`` must not stop the host under
    that ``up``. Once anything was active, ``idle_s`` alone counts.
    """

    def __init__(self, idle_s: float, now: float, *, grace_s: float = 0.0) -> None:
        self.idle_s = idle_s
        self.last_active = now
        self._started = now
        self._grace_s = grace_s
        self._active_once = False
        self._msgs: int | None = None

    def observe(self, seen: Activity | None, now: float) -> None:
        msgs = seen.msgs if seen is not None else None
        moved = msgs is not None and self._msgs is not None and msgs != self._msgs
        if (seen is not None and seen.connected) or moved:
            self.last_active = now
            self._active_once = True
        self._msgs = msgs

    def idle_since(self, now: float) -> float | None:
        return self.last_active if now > self.last_active else None

    def stops_at(self) -> float:
        """When the host stops if nothing happens before then."""
        if self._active_once:
            return self.last_active + self.idle_s
        return self._started + max(self.idle_s, self._grace_s)

    def due(self, now: float) -> bool:
        return now >= self.stops_at()


def read_activity(path: Path, *, stale_s: float = STATS_STALE_S,
                  clock: Callable[[], float] = time.time) -> Activity | None:
    """``{"connected": bool, "topics": [{"msgs": int, ...}, ...]}`` (topics optional); None if unreadable
    or stale (not rewritten for ``stale_s``: what it said is no longer so)."""
    try:
        if clock() - path.stat().st_mtime > stale_s:
            return None
        doc = json.loads(path.read_text())
        topics = doc.get("topics")
        msgs = sum(int(t["msgs"]) for t in topics) if isinstance(topics, list) else None
        return Activity(connected=bool(doc.get("connected")), msgs=msgs)
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None


def _write_state(run_dir: Path, state: IdleState) -> None:
    tmp = run_dir / f".{STATE_FILE}.tmp"
    tmp.write_text(state.to_json() + "\n")
    os.replace(tmp, run_dir / STATE_FILE)


def parse_state(text: str) -> IdleState | None:
    """The watchdog's state file's text as an :class:`IdleState`, or None if it is not one."""
    try:
        return IdleState(**json.loads(text))
    except (ValueError, TypeError):
        return None


def read_state(run_dir: Path) -> IdleState | None:
    """The watchdog's last word for this run folder, or None if it never ran there."""
    try:
        return parse_state((run_dir / STATE_FILE).read_text())
    except OSError:
        return None


def _stop_services(run_dir: Path, state: IdleState) -> None:
    others = sorted(p.name.removesuffix(".pid") for p in run_dir.glob("*.pid") if p.name != f"{SERVICE}.pid")
    supervise.stop_many(run_dir, others)
    _write_state(run_dir, state)  # only once the services are down, so status never says stopped too early
    supervise.stop(run_dir, SERVICE)  # our own supervisor last: this ends the process


def _power_off(run_dir: Path, state: IdleState) -> None:
    _write_state(run_dir, state)
    command = ["shutdown", "-h", "now"]
    subprocess.run(command if os.geteuid() == 0 else ["sudo", "-n", *command], check=False)


POWER: dict[str, Callable[[Path, IdleState], None]] = {"services": _stop_services, "machine": _power_off}


def watch(*, stats_file: Path, run_dir: Path, idle_s: float, action: str, power: str,
          clock: Callable[[], float] = time.time, sleep: Callable[[float], None] = time.sleep,
          stale_s: float = STATS_STALE_S) -> IdleState:
    """Poll until idle for ``idle_s``, record it, then stop the way ``power`` says."""
    stop = POWER[power]
    idle = IdleClock(idle_s, clock(), grace_s=START_GRACE_S)
    while True:
        now = clock()
        idle.observe(read_activity(stats_file, stale_s=stale_s, clock=clock), now)
        since = idle.idle_since(now)
        if idle.due(now):
            state = IdleState(idle_since=since, stops_at=now, stopped_at=now, action=action)
            stop(run_dir, state)
            return state
        _write_state(run_dir, IdleState(idle_since=since, stops_at=idle.stops_at(), action=action))
        sleep(_POLL_S)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fogiac.provision.autostop", description=__doc__.splitlines()[0])
    parser.add_argument("--stats", type=Path, required=True, help="the middleware's stats file on this host")
    parser.add_argument("--run", type=Path, required=True, help="the supervisor's run folder")
    parser.add_argument("--idle-s", type=float, required=True)
    parser.add_argument("--action", choices=("stop", "terminate"), default="stop")
    parser.add_argument("--power", choices=tuple(POWER), required=True)
    args = parser.parse_args(argv)
    watch(stats_file=args.stats, run_dir=args.run, idle_s=args.idle_s, action=args.action, power=args.power)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
