"""A replicated ROS 2 node over Zenoh: each replica under its own key prefix, an edge-side merge.

rmw_zenoh's data keys are ``<domain>/<topic>/<type>/<hash>``. On a replica's host a small process (``cloud``)
renames between the plain keys its nodes use and ``fogiac/replica/<group>/<number>/<key>`` (``<number>``:
1 for ``<group>-r1``), the only keys
its router lets cross to the edge (:func:`fogiac.net.zenoh.config.access_control` with ``Route.replica``).
On the edge, ``edge`` subscribes the robot's requests (the node's ``in`` topics, plain keys) and puts each
under every live replica's prefix (hedge ``all``), or the fastest one's first (``delayed``); it subscribes
the replies under every replica's prefix and puts the first one per request under the plain key, for the
robot, never a duplicate. Payloads, encodings and attachments (rmw_zenoh's sequence number, time and gid)
pass unchanged.

A reply names its request by the ``header.stamp`` of a CDR message whose first field is its
``std_msgs/Header``: where :data:`fogiac.msgtypes.CDR` places it (bytes 4..12, after the 4-byte
encapsulation header: int32 sec, uint32 nanosec), the same offsets as ROS 1's. Other keys need the
message's type description, which rmw_zenoh does not send: only ``header.stamp`` is supported here.

    python -m fogiac.net.zenoh.replicas cloud ROUTER --prefix P --to-cloud /t ... --to-edge /r ...
    python -m fogiac.net.zenoh.replicas edge ROUTER --group G --replica INDEX,HOST[,ROUTER_ID] ... \\
        --to-cloud /t ... --to-edge /r ... [--hedge all|delayed --hedge-delay S] [--linked-file F] [--stats-file F]
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from fogiac import msgtypes
from fogiac.extras import need
from fogiac.net.replicas import HEDGES, Merge
from fogiac.net.zenoh.config import topic_key
from fogiac.net.zenoh.errors import ZenohError
from fogiac.state import read_json, write_json_atomic

log = logging.getLogger(__name__)
PREFIX = "fogiac/replica"
SUPPORTED_MATCH = msgtypes.DEFAULT_MATCH
_STAMP = msgtypes.CDR.key_reader(msgtypes.HEADER, SUPPORTED_MATCH)


def replica_prefix(group: str, index: int) -> str:
    """Replica ``index`` (the plan's, from 0) of ``group`` crosses under its number, as it is shown: 1 of 2
    is ``fogiac/replica/<group>/1`` on host ``<group>-r1``."""
    return f"{PREFIX}/{group}/{index + 1}"


def stamp_key(payload: bytes) -> bytes | None:
    """A CDR message's header stamp (after the 4-byte encapsulation header), or None if too short."""
    return _STAMP(payload)


def _session(router: str) -> Any:
    zenoh = need("zenoh", extra="ros2")
    config = {"mode": "client", "connect": {"endpoints": [router]}, "scouting": {"multicast": {"enabled": False}}}
    try:
        return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    except zenoh.ZError as err:
        raise ZenohError(f"cannot open a Zenoh session on {router}: {err}") from None


def _forward(session: Any, key: str, sample: Any) -> None:
    session.put(key, sample.payload, encoding=sample.encoding, attachment=sample.attachment)


class CloudPrefix:
    """On a replica's host: the node's plain keys <-> the replica's prefixed keys, on the host's router."""

    def __init__(self, router: str, prefix: str, *, to_cloud: Sequence[str], to_edge: Sequence[str]) -> None:
        both = sorted(set(to_cloud) & set(to_edge))
        if both:  # renamed both ways, a message would come back to this process's own subscriber forever
            raise ZenohError(f"{', '.join(both)}: a replica's topic goes one way, to the cloud or to the edge")
        self.router, self.prefix, self.to_cloud, self.to_edge = router, prefix.rstrip("/"), to_cloud, to_edge
        self.session: Any = None
        self.moved = 0

    def start(self) -> None:
        self.session = _session(self.router)
        cut = len(self.prefix) + 1
        for topic in self.to_cloud:
            self.session.declare_subscriber(f"{self.prefix}/{topic_key(topic)}", lambda s: self._move(
                str(s.key_expr)[cut:], s))
        for topic in self.to_edge:
            self.session.declare_subscriber(topic_key(topic), lambda s: self._move(f"{self.prefix}/{s.key_expr}", s))

    def _move(self, key: str, sample: Any) -> None:
        self.moved += 1
        _forward(self.session, key, sample)

    def stop(self) -> None:
        if self.session is not None:
            self.session.close()


class EdgeMerge:
    """On the edge: requests fanned out under the replicas' prefixes, the first reply per request put back."""

    def __init__(self, router: str, group: str, replicas: Sequence[tuple[int, str]], *, to_cloud: Sequence[str],
                 to_edge: Sequence[str], hedge: str = "all", hedge_delay_s: float = 0.0,
                 linked: Callable[[], set[int]] | None = None, stats_file: Path | None = None,
                 silent_after: float = 3.0) -> None:
        if hedge not in HEDGES:
            raise ZenohError(f"hedge {hedge!r}: expected one of {', '.join(HEDGES)}")
        self.router, self.group, self.to_cloud, self.to_edge = router, group, to_cloud, to_edge
        self.indices = [i for i, _ in replicas]
        self.merge = Merge(replicas, hedge=hedge, hedge_delay_s=hedge_delay_s, silent_after=silent_after)
        self._linked = linked or (lambda: set(self.indices))
        self.stats_file = stats_file
        self.session: Any = None
        self._stopping = threading.Event()
        self._threads: list[threading.Thread] = []

    def start(self) -> None:
        self.session = _session(self.router)
        for topic in self.to_cloud:
            self.session.declare_subscriber(topic_key(topic), lambda s, t=topic: self._request(t, s))
        for topic in self.to_edge:  # one subscriber per replica: a host's access control admits exactly its keys
            for i in self.indices:
                self.session.declare_subscriber(f"{replica_prefix(self.group, i)}/{topic_key(topic)}",
                                                lambda s, t=topic: self._reply(t, s))
        for target in (self._hedge_loop, self._stats_loop):
            thread = threading.Thread(target=target, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        self._stopping.set()
        with self.merge.changed:
            self.merge.changed.notify_all()
        for thread in self._threads:
            thread.join(timeout=5)
        if self.session is not None:
            self.session.close()

    def live(self) -> list[int]:
        linked = self._linked()
        return [i for i in self.indices if i in linked]

    def _request(self, topic: str, sample: Any) -> None:
        key = str(sample.key_expr)
        for i in self.merge.request(topic, stamp_key(sample.payload.to_bytes()), (key, sample), self.live(),
                                    time.monotonic()):
            _forward(self.session, f"{replica_prefix(self.group, i)}/{key}", sample)

    def _reply(self, topic: str, sample: Any) -> None:
        parts = str(sample.key_expr).split("/", 4)  # fogiac, replica, group, number (index + 1), the plain key
        if len(parts) < 5 or not parts[3].isdigit() or int(parts[3]) - 1 not in self.merge.figures:
            return
        if self.merge.reply(topic, int(parts[3]) - 1, stamp_key(sample.payload.to_bytes()), time.monotonic()):
            _forward(self.session, parts[4], sample)

    def _hedge_loop(self) -> None:
        while not self._stopping.is_set():
            with self.merge.changed:
                due, now = self.merge.next_due(), time.monotonic()
                if due is None or due > now:
                    self.merge.changed.wait(1.0 if due is None else due - now)
                    continue
            for _, (key, sample), targets in self.merge.due(now, self.live()):
                for i in targets:
                    _forward(self.session, f"{replica_prefix(self.group, i)}/{key}", sample)

    def stats(self) -> dict[str, Any]:
        return {"group": self.group, "match": SUPPORTED_MATCH,
                **self.merge.stats(set(self.live()), time.monotonic())}

    def _stats_loop(self) -> None:
        while not self._stopping.wait(1.0):
            if self.stats_file is not None:
                try:
                    write_json_atomic(self.stats_file, self.stats())
                except OSError as err:
                    log.warning("cannot write %s: %s", self.stats_file, err)


def linked_from(path: Path, ids: dict[int, str]) -> Callable[[], set[int]]:
    """The replicas whose router the edge router is linked to now, from its stats file (``routers``); every
    one while the file is not there (the edge router not yet up, or run without one): unknown is not down."""
    def linked() -> set[int]:
        try:
            doc = read_json(path)
        except (OSError, ValueError):
            doc = None
        if not isinstance(doc, dict):
            return set(ids)
        routers = set(doc.get("routers", []))
        return {i for i, zid in ids.items() if zid in routers}

    return linked


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fogiac.net.zenoh.replicas")
    parser.add_argument("role", choices=["cloud", "edge"])
    parser.add_argument("router", help="the router's endpoint, e.g. tcp/127.0.0.1:7447")
    parser.add_argument("--prefix", help="cloud: this replica's key prefix")
    parser.add_argument("--group", help="edge: the replicated node's name")
    parser.add_argument("--replica", action="append", default=[], help="edge: INDEX,HOST[,ROUTER_ID]")
    parser.add_argument("--to-cloud", action="append", default=[])
    parser.add_argument("--to-edge", action="append", default=[])
    parser.add_argument("--hedge", default="all", choices=HEDGES)
    parser.add_argument("--hedge-delay", type=float, default=0.0)
    parser.add_argument("--linked-file", type=Path, help="edge: the edge router's stats file (linked routers)")
    parser.add_argument("--stats-file", type=Path)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    end: CloudPrefix | EdgeMerge
    try:
        if args.role == "cloud":
            if not args.prefix:
                raise ZenohError("cloud: --prefix is required")
            end = CloudPrefix(args.router, args.prefix, to_cloud=args.to_cloud, to_edge=args.to_edge)
        else:
            if not args.group or not args.replica:
                raise ZenohError("edge: --group and at least one --replica are required")
            fields = [r.split(",") for r in args.replica]
            if any(len(f) < 2 or not f[0].isdigit() for f in fields):
                raise ZenohError(f"--replica {args.replica}: expected INDEX,HOST[,ROUTER_ID]")
            ids = {int(f[0]): f[2] for f in fields if len(f) > 2 and f[2]}
            linked = linked_from(args.linked_file, ids) if args.linked_file is not None and ids else None
            end = EdgeMerge(args.router, args.group, [(int(f[0]), f[1]) for f in fields], to_cloud=args.to_cloud,
                            to_edge=args.to_edge, hedge=args.hedge, hedge_delay_s=args.hedge_delay,
                            linked=linked, stats_file=args.stats_file)
        end.start()
    except ZenohError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    print("ready", flush=True)
    try:
        done.wait()
    finally:
        end.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
