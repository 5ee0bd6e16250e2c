"""A Zenoh router in a Python process, for machines without ``zenohd`` (the robot, tests).

``python -m fogiac.net.zenoh.router CONFIG.json`` opens a session in router mode with a config
that :mod:`fogiac.net.zenoh.config` rendered and serves until SIGTERM or SIGINT. eclipse-zenoh
is an optional extra (``fogiac[ros2]``), imported through :func:`fogiac.extras.need`.

A fleet's cloud router also follows a fleet file (``--fleet-file``: each robot's certificate name and edge
router id, the revoked robots; :func:`fogiac.net.zenoh.deploy.fleet_document`). Zenoh reads access control
once, when a session opens, so when the file changes this process closes its session and opens another on
the new rules (half a second, the same process): a robot added, removed or revoked restarts no service, and
the host's nodes and the other robots' edge routers, which redial, carry on. Until the file exists no robot
gets anything.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

from fogiac.extras import need
from fogiac.net.zenoh.config import fleet_access_control
from fogiac.net.zenoh.errors import ZenohError
from fogiac.state import write_json_atomic

STATS_PERIOD_S = 1.0
# Between closing the session and opening the next on new fleet rules: an edge router that redials while the
# old session is still closing was seen left without routes for good (1 reload in ~10, zenoh 1.10.2, loopback);
# with a pause none was in 24, and the edge routers' redial (at most 2 s apart) still links them within 4 s.
REOPEN_PAUSE_S = 1.0


def open_router(config: dict[str, Any]) -> Any:
    """An open zenoh ``Session`` in router mode; close it to stop routing."""
    zenoh = need("zenoh", extra="ros2")
    try:
        return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    except zenoh.ZError as err:
        raise ZenohError(f"zenoh router: {err}") from None


def fleet_config(config: dict[str, Any], fleet: Path) -> tuple[dict[str, Any], list[str]]:
    """``config`` with the fleet file's access control (no robot when the file is absent), and the edge router
    ids that count as connected (the robots not revoked). A file that cannot be read raises ValueError/OSError."""
    doc = json.loads(fleet.read_text()) if fleet.exists() else {"robots": {}, "revoked": []}
    robots = doc.get("robots", {}) if isinstance(doc, dict) else None
    revoked = set(map(str, doc.get("revoked", []))) if isinstance(doc, dict) else set()
    if not isinstance(robots, dict) or not all(isinstance(r, dict) and {"common_name", "zid"} <= set(r)
                                               for r in robots.values()):
        raise ValueError(f"{fleet}: robots is not a mapping of robot -> {{common_name, zid}}")
    names = {name: str(robot["common_name"]) for name, robot in robots.items()}
    made = {**config, "access_control": fleet_access_control(names, revoked=revoked)}
    return made, [str(robot["zid"]) for name, robot in robots.items() if name not in revoked]


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
    any of them counts. ``fleet``: the fleet file whose rules and robots replace ``config``'s and
    ``edge_id``'s, followed while it runs (the module docstring)."""
    config = json.loads(config_path.read_text())
    edges = [edge_id] if isinstance(edge_id, str) else list(edge_id or [])
    seen = _read(fleet)
    opened, edges = fleet_config(config, fleet) if fleet is not None else (config, edges)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    session = open_router(opened)
    print("ready", flush=True)
    try:
        while not stop.wait(STATS_PERIOD_S if stats is not None or fleet is not None else None):
            if fleet is not None and (now := _read(fleet)) != seen:
                seen = now
                try:
                    opened, edges = fleet_config(config, fleet)
                except (OSError, ValueError, KeyError, TypeError) as err:  # half an edit: the rules of before stand
                    print(f"error: {fleet}: {err}; the rules of before stand", file=sys.stderr, flush=True)
                else:
                    session.close()
                    time.sleep(REOPEN_PAUSE_S)
                    session = open_router(opened)
                    print(f"fleet rules reloaded: {len(edges)} robot(s) admitted", file=sys.stderr, flush=True)
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
    parser.add_argument("--fleet-file", type=Path,
                        help="a fleet's robots and revocations: its access control, reloaded when it changes")
    args = parser.parse_args()
    try:
        serve(args.config, stats=args.stats_file, edge_id=args.edge_id, fleet=args.fleet_file)
    except (ZenohError, OSError, ValueError, IndexError, KeyError, TypeError) as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(1)
