"""Helpers for the motion-planning tests: problem files under tmp_path, process bookkeeping."""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
PROBLEMS = REPO / "workloads" / "motion_planning" / "problems"

CUBE_OBJ = """\
v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.5 0.5 0.5
v -0.5 0.5 0.5
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""


def write_cfg(directory: Path, name: str = "p", *, robot: str = "robot.obj", world: str = "world.obj",
              problem: dict[str, str] | None = None, extra: str = "", drop: tuple[str, ...] = ()) -> Path:
    """A valid cfg (start/goal/volume) with overrides in ``problem`` and keys in ``drop`` left out."""
    keys = {"robot": robot, "world": world,
            "start.x": "-2", "start.y": "0", "start.z": "0", "start.theta": "0",
            "start.axis.x": "1", "start.axis.y": "0", "start.axis.z": "0",
            "goal.x": "2", "goal.y": "0", "goal.z": "0", "goal.theta": "1.5707963267948966",
            "goal.axis.x": "0", "goal.axis.y": "0", "goal.axis.z": "2",
            "volume.min.x": "-3", "volume.min.y": "-3", "volume.min.z": "-3",
            "volume.max.x": "3", "volume.max.y": "3", "volume.max.z": "3"}
    keys.update(problem or {})
    body = "\n".join(f"{k} = {v}" for k, v in keys.items() if k not in drop)
    path = directory / f"{name}.cfg"
    path.write_text(f"[problem]\n{body}\n{extra}", encoding="utf-8")
    return path


def descendants(pid: int) -> set[int]:
    """Every live process below ``pid``, from /proc (no psutil needed)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2:].split()
            if fields[0] != "Z":
                parents[int(entry.name)] = int(fields[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parents.items() if pp in frontier} - found
        found |= frontier
    return found


def own_pid() -> int:
    return os.getpid()
