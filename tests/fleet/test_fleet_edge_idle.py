"""A fleet's edge on this machine is idle only when every robot's link is: ``edge_idle_since`` reads each robot's
edge end's stats (``relay-edge-HOST@ROBOT.stats.json``), not only the first's, so the cost guard never calls a
fleet idle while one robot is still linked."""

from __future__ import annotations

import json
import os
from pathlib import Path

from fogiac.lifecycle.edge import edge_dir, edge_idle_since, forget_dropped_revocations
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.state import StackState

NOW = 1_800_000_000.0
FLEET = """name: idle
cloud: {provider: local}
robots:
  - {name: arm1, ros_master: "http://127.0.0.1:11312"}
  - {name: arm2, ros_master: "http://127.0.0.1:11313"}
nodes:
  - {name: planner, machine: t3.micro, command: [sleep, "3600"], topics: {in: [/plan/request], out: [/plan/reply]}}
"""


def _stats(folder: Path, robot: str, *, connected: bool, at: float) -> None:
    path = folder / f"relay-edge-planner@{robot}.stats.json"
    path.write_text(json.dumps({"connected": connected}))
    os.utime(path, (at, at))


def test_every_robots_link_counts(_state_dir: Path) -> None:
    plan = compile_plan(parse_manifest(FLEET, base=Path.cwd()), target="local")
    folder = edge_dir(plan)
    folder.mkdir(parents=True, exist_ok=True)
    assert edge_idle_since(plan, now=NOW) is None  # never ran here: unknown
    _stats(folder, "arm1", connected=True, at=NOW - 600)
    _stats(folder, "arm2", connected=True, at=NOW - 300)
    assert edge_idle_since(plan, now=NOW) == NOW - 300  # both gone: since the last one's last breath
    _stats(folder, "arm2", connected=True, at=NOW - 1)
    assert edge_idle_since(plan, now=NOW) is None  # arm2 is linked now: not idle, whatever arm1 says


def test_a_revocation_is_forgotten_once_robots_drops_the_robot(_state_dir: Path) -> None:
    """``fogiac robot revoke`` keeps a robot revoked until restored or dropped from the manifest: a robot of that
    name added later starts unrevoked."""
    plan = compile_plan(parse_manifest(FLEET, base=Path.cwd()), target="local")
    stack = StackState(plan.stack)
    stack.update(lambda doc: doc.update({StackState.EDGES: [], StackState.REVOKED: ["arm2", "arm7"]}))
    forget_dropped_revocations(plan)
    assert stack.get(StackState.REVOKED) == ["arm2"]  # arm7 is no robot of the manifest any more
    dropped = compile_plan(parse_manifest(FLEET.replace('  - {name: arm2, ros_master: "http://127.0.0.1:11313"}\n', ""),
                                          base=Path.cwd()), target="local")
    forget_dropped_revocations(dropped)
    assert stack.get(StackState.REVOKED) is None and stack.get(StackState.EDGES) == []
