"""A Zenoh router in a Python process, for machines without ``zenohd`` (the robot, tests).

``python -m fogiac.net.zenoh.router CONFIG.json`` opens a session in router mode with a config
that :mod:`fogiac.net.zenoh.config` rendered and serves until SIGTERM or SIGINT. eclipse-zenoh
is an optional extra (``fogiac[ros2]``), imported through :func:`fogiac.extras.need`.
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
from fogiac.state import write_json_atomic

STATS_PERIOD_S = 1.0


def open_router(config: dict[str, Any]) -> Any:
    """An open zenoh ``Session`` in router mode; close it to stop routing."""
    zenoh = need("zenoh", extra="ros2")
    try:
        return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    except zenoh.ZError as err:
        raise ZenohError(f"zenoh router: {err}") from None


def serve(config_path: Path, *, stats: Path | None = None, edge_id: str | list[str] | None = None) -> None:
    """Route until told to stop; with ``stats``, write the ids of the routers linked to it every second
    and whether the edge's is one of them (``connected``, which autostop reads). With ``edge_id`` only
    that router counts: a zenohd or a bridge on the host linked to the loopback port is no edge.
    Without it (the edge's own router), any linked router counts. Several ids: one edge router per edge,
    any of them counts."""
    config = json.loads(config_path.read_text())
    edges = [edge_id] if isinstance(edge_id, str) else list(edge_id or [])
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    session = open_router(config)
    print("ready", flush=True)
    try:
        while not stop.wait(STATS_PERIOD_S if stats is not None else None):
            if stats is not None:
                routers = sorted(str(z) for z in session.info.routers_zid())
                linked = bool(set(edges) & set(routers)) if edges else bool(routers)
                write_json_atomic(stats, {"routers": routers, "connected": linked})
    finally:
        session.close()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="python -m fogiac.net.zenoh.router")
    parser.add_argument("config", type=Path)
    parser.add_argument("--stats-file", type=Path, help="write the linked routers' ids here every second")
    parser.add_argument("--edge-id", action="append",
                        help="an edge router's Zenoh id (one per edge): only they count as connected")
    args = parser.parse_args()
    try:
        serve(args.config, stats=args.stats_file, edge_id=args.edge_id)
    except (ZenohError, OSError, ValueError, IndexError) as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(1)
