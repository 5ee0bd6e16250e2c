"""A Zenoh router in a Python process, for machines without ``zenohd`` (the robot, tests).

``python -m fogiac.net.zenoh.router CONFIG.json`` opens a session in router mode with a config
that :mod:`fogiac.net.zenoh.config` rendered and serves until SIGTERM or SIGINT. eclipse-zenoh
is an optional extra (``fogiac[ros2]``), imported through :func:`fogiac.extras.need`.

A fleet's cloud router also follows a fleet file (``--fleet-file``: each robot's certificate name and edge
router id, the revoked robots; :func:`fogiac.net.zenoh.deploy.fleet_document`). Zenoh reads access control
once, when a session opens, and cannot refuse a TLS link by certificate; so this process serves a fleet as
:mod:`fogiac.net.zenoh.gate` describes: its own TLS gate on the edges' address, which refuses any certificate
but an admitted robot's, and a router per robot behind it holding that robot's rules. When the file changes,
only the robots added, removed, revoked or restored are touched (within a second): a robot cut off has its
links closed and its redials refused, and no other robot's link drops. Until the file exists no robot is
admitted.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path
from typing import Any

from fogiac.extras import need
from fogiac.net.zenoh.errors import ZenohError
from fogiac.net.zenoh.gate import FleetRouter, read_fleet
from fogiac.state import write_json_atomic

STATS_PERIOD_S = 1.0


def open_router(config: dict[str, Any]) -> Any:
    """An open zenoh ``Session`` in router mode; close it to stop routing."""
    zenoh = need("zenoh", extra="ros2")
    try:
        return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    except zenoh.ZError as err:
        raise ZenohError(f"zenoh router: {err}") from None


def _read(path: Path | None) -> bytes | None:
    try:
        return path.read_bytes() if path is not None else None
    except OSError:
        return None


def serve(config_path: Path, *, stats: Path | None = None, edge_id: str | list[str] | None = None,
          fleet: Path | None = None) -> None:
    """Route until told to stop; with ``stats``, write the ids of the routers linked to it every second
    and whether the edge's is one of them (``connected``, which autostop reads). With ``edge_id`` only
    that router counts: a zenohd or a bridge on the host linked to the loopback port is no edge.
    Without it (the edge's own router), any linked router counts. Several ids: one edge router per edge,
    any of them counts. ``fleet``: the fleet file whose robots replace ``edge_id``, followed while it runs
    (the module docstring)."""
    config = json.loads(config_path.read_text())
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    if fleet is not None:
        _serve_fleet(config, fleet, stats=stats, stop=stop)
        return
    edges = [edge_id] if isinstance(edge_id, str) else list(edge_id or [])
    session = open_router(config)
    print("ready", flush=True)
    try:
        while not stop.wait(STATS_PERIOD_S if stats is not None else None):
            routers = sorted(str(z) for z in session.info.routers_zid())
            _write_stats(stats, routers, edges)
    finally:
        session.close()


def _write_stats(stats: Path | None, routers: list[str], edges: list[str]) -> None:
    if stats is not None:
        linked = bool(set(edges) & set(routers)) if edges else bool(routers)
        write_json_atomic(stats, {"routers": routers, "connected": linked})


def _serve_fleet(config: dict[str, Any], fleet: Path, *, stats: Path | None, stop: threading.Event) -> None:
    """A fleet's router (:mod:`fogiac.net.zenoh.gate`): the fleet file applied robot by robot, each second it
    changed; one that cannot be read leaves the robots of before (none, at the start)."""
    router = FleetRouter(config, open_router=open_router)
    router.start()
    seen: bytes | None = None  # what the file held when last applied (None: absent)
    first = True  # the first pass applies the file, or its absence (no robot admitted)
    edges: list[str] = []
    print("ready", flush=True)
    try:
        while True:
            if (now := _read(fleet)) != seen or first:
                seen, first = now, False
                try:
                    doc = read_fleet(fleet)
                except (OSError, ValueError, KeyError, TypeError) as err:  # half an edit: the robots of before stand
                    print(f"error: {fleet}: {err}; the robots of before stand", file=sys.stderr, flush=True)
                else:
                    for change in router.apply(doc):
                        print(change, file=sys.stderr, flush=True)
                    edges = doc.edges
            _write_stats(stats, router.routers(), edges)
            router.refresh()
            if stop.wait(STATS_PERIOD_S):
                break
    finally:
        router.close()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="python -m fogiac.net.zenoh.router")
    parser.add_argument("config", type=Path)
    parser.add_argument("--stats-file", type=Path, help="write the linked routers' ids here every second")
    parser.add_argument("--edge-id", action="append",
                        help="an edge router's Zenoh id (one per edge): only they count as connected")
    parser.add_argument("--fleet-file", type=Path,
                        help="a fleet's robots and revocations: its access control, reloaded when it changes")
    args = parser.parse_args()
    try:
        serve(args.config, stats=args.stats_file, edge_id=args.edge_id, fleet=args.fleet_file)
    except (ZenohError, OSError, ValueError, IndexError, KeyError, TypeError) as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(1)
