"""Problems of the FogROS paper's classes, written into ``problems/paper/`` (deterministic).

``python -m workloads.motion_planning.paper_problems`` regenerates them. OMPL.app's own
Apartment, Home and Twistycool may not be shipped (their license forbids it); these are built
from boxes to the same recipe, and ``solve`` reads OMPL.app's own files from any path.

- ``apartment``: a piano (keyboard, body, lid) carried through a flat of six rooms whose doors
  are narrower than the piano is long: it must turn to go through each, three doors apart
  (OMPL.app's ``Apartment``: "apartment_piano").
- ``home``: a table (top and four legs) carried across a house of nine rooms furnished with
  beds, sofas and cupboards, through doors it clears only edge-on (OMPL.app's ``Home``). Its cfg
  repeats keys in an OMPL.app-style ``[planner]`` section, as OMPL.app's own ``Home.cfg`` does.
- ``twistycool``: one wall across the whole space with one slot, and a robot of two crossed
  bars joined by a short neck: the first bar goes through lengthwise, then the robot must twist
  a quarter turn about the neck, inside the slot, for the second (OMPL.app's ``Twistycool``).

They live beside, not among, the demo's problems (``problems/``): each takes seconds to tens of
seconds on one core. Each cfg states its planning resolution in ``[solver]`` (the robots' thinnest
parts are thinner than the fitted default assumes).
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from pathlib import Path

import trimesh

from workloads.motion_planning.generate_problems import box, box_between, export, wall_with_door, write_all
from workloads.motion_planning.problem import PROBLEMS_DIR

PAPER_DIR = PROBLEMS_DIR / "paper"
Vec = Sequence[float]
# OMPL.app's Home.cfg lists planners for its benchmark tool, one key given twice; fogiac ignores the section
_PLANNER_SECTION = ("[planner]\nprm=\nrrtstar=\naps=\naps.name=APS1\naps.num_planners=1\n"
                    "aps=\naps.name=APS4\naps.num_planners=4\n")


def write_cfg(path: Path, *, start: Vec, goal: Vec, start_rot: Vec = (1, 0, 0, 0), goal_rot: Vec = (1, 0, 0, 0),
              lo: Vec, hi: Vec, resolution: float, time_limit: float = 120.0, planner_section: bool = False) -> None:
    """OMPL.app's layout: [problem] (``*_rot``: axis x, y, z, theta), [solver], [benchmark], optionally [planner]."""
    name = path.stem
    lines = ["[problem]", f"name = {name}", f"robot = {name}_robot.stl", f"world = {name}_env.stl"]
    for end, pos, rot in (("start", start, start_rot), ("goal", goal, goal_rot)):
        lines += [f"{end}.{k} = {v:g}" for k, v in zip("xyz", pos, strict=True)]
        lines += [f"{end}.theta = {rot[3]:.6f}"]
        lines += [f"{end}.axis.{k} = {v:g}" for k, v in zip("xyz", rot[:3], strict=True)]
    lines += [f"volume.{m}.{k} = {v:g}"
              for m, vec in (("min", lo), ("max", hi)) for k, v in zip("xyz", vec, strict=True)]
    lines += ["", "[solver]", f"time_limit = {time_limit:g}", f"resolution = {resolution:g}",
              "", "[benchmark]", f"time_limit = {time_limit:g}", "mem_limit = 1000.0", "run_count = 50", ""]
    path.write_text("\n".join(lines) + (_PLANNER_SECTION if planner_section else ""), encoding="utf-8")


def _rooms(cols: int, rows: int, cell: Vec, *, door_w: float, height: float, thick: float,
           doors: set[tuple[str, int, int]]) -> list[trimesh.Trimesh]:
    """Outer walls and a grid of rooms; ``doors`` names the inner walls with a door: ("v", i, j) is the
    wall x = i * cell_x between rows j, ("h", j, i) the wall y = j * cell_y between columns i."""
    cx, cy = cell
    parts = []
    for i in range(cols + 1):
        for j in range(rows):
            has = ("v", i, j) in doors and 0 < i < cols
            parts += wall_with_door((i * cx, j * cy), (i * cx, (j + 1) * cy), height=height, z0=0.0, thick=thick,
                                    door=j * cy + cy / 2 if has else None, door_w=door_w, door_h=2.1)
    for j in range(rows + 1):
        for i in range(cols):
            has = ("h", j, i) in doors and 0 < j < rows
            parts += wall_with_door((i * cx, j * cy), ((i + 1) * cx, j * cy), height=height, z0=0.0, thick=thick,
                                    door=i * cx + cx / 2 if has else None, door_w=door_w, door_h=2.1)
    return parts


def apartment(out: Path) -> None:
    cols, rows, cell, height = 3, 2, (5.0, 4.5), 2.6
    doors = {("v", 1, 0), ("v", 2, 0), ("h", 1, 2), ("v", 1, 1), ("v", 2, 1)}
    parts = [box_between((-1, -1, -0.3), (cols * cell[0] + 1, rows * cell[1] + 1, 0.0)),
             box_between((-1, -1, height), (cols * cell[0] + 1, rows * cell[1] + 1, height + 0.3))]
    parts += _rooms(cols, rows, cell, door_w=1.6, height=height, thick=0.15, doors=doors)
    export(parts, out / "apartment_env.stl")
    piano = [box((0, 0, 0), (1.5, 0.6, 0.9)), box((0, -0.4, 0.05), (1.4, 0.2, 0.1)),  # body, keyboard
             box((0, 0.1, 0.55), (1.5, 0.06, 0.2))]  # the lid, raised
    export(piano, out / "apartment_robot.stl")
    write_cfg(out / "apartment.cfg", start=(1.5, 1.5, 0.8), goal=(12.5, 7.0, 0.8), goal_rot=(0, 0, 1, math.pi),
              lo=(0, 0, 0.5), hi=(cols * cell[0], rows * cell[1], 2.0), resolution=0.03)


def home(out: Path, *, seed: int = 3) -> None:
    rng = random.Random(seed)
    cols, rows, cell, height = 3, 3, (5.0, 4.0), 2.5
    doors = {("v", 1, 0), ("h", 1, 1), ("v", 2, 1), ("h", 2, 2),  # the way through, and a loop round it
             ("v", 1, 1), ("h", 2, 0), ("v", 1, 2), ("v", 2, 2)}
    width, depth = cols * cell[0], rows * cell[1]
    parts = [box_between((-1, -1, -0.3), (width + 1, depth + 1, 0.0)),
             box_between((-1, -1, height), (width + 1, depth + 1, height + 0.3))]
    parts += _rooms(cols, rows, cell, door_w=1.4, height=height, thick=0.15, doors=doors)
    for i in range(cols):
        for j in range(rows):
            if (i, j) in ((0, 0), (2, 2)):
                continue  # the start and goal rooms stay clear around the endpoints
            for _ in range(2):  # furniture against a wall, clear of the room's middle where the doors lead
                w, d, h = rng.uniform(0.8, 1.6), rng.uniform(0.5, 0.9), rng.uniform(0.4, 1.9)  # clear of the doors
                x0 = i * cell[0] + rng.choice((0.2, cell[0] - 0.2 - w))
                y0 = j * cell[1] + rng.choice((0.2, cell[1] - 0.2 - d))
                parts.append(box_between((x0, y0, 0.0), (x0 + w, y0 + d, h)))
    export(parts, out / "home_env.stl")
    table = [box((0, 0, 0.35), (1.4, 0.9, 0.05))]
    table += [box((sx * 0.62, sy * 0.38, 0.0), (0.06, 0.06, 0.7)) for sx in (-1, 1) for sy in (-1, 1)]
    export(table, out / "home_robot.stl")
    write_cfg(out / "home.cfg", start=(2.5, 2.0, 0.7), goal=(12.5, 10.0, 0.7), lo=(0, 0, 0.45),
              hi=(width, depth, 2.0), resolution=0.03, planner_section=True)


def twistycool(out: Path) -> None:
    half, thick = 4.0, 0.1
    slot_y, slot_z = 2.8, 0.8  # the slot: a bar (0.3 thick, 2.1 long) goes through lengthwise only
    parts = [box_between((-thick / 2, -half, slot_z / 2), (thick / 2, half, half)),
             box_between((-thick / 2, -half, -half), (thick / 2, half, -slot_z / 2)),
             box_between((-thick / 2, -half, -slot_z / 2), (thick / 2, -slot_y / 2, slot_z / 2)),
             box_between((-thick / 2, slot_y / 2, -slot_z / 2), (thick / 2, half, slot_z / 2))]
    export(parts, out / "twistycool_env.stl")
    robot = [box((-0.65, 0, 0), (0.3, 2.1, 0.3)),  # the first bar, along y
             box((0.65, 0, 0), (0.3, 0.3, 2.1)),  # the second, along z: a quarter turn about x away
             box((0, 0, 0), (1.0, 0.2, 0.2))]  # the neck that turns inside the slot
    export(robot, out / "twistycool_robot.stl")
    write_cfg(out / "twistycool.cfg", start=(-2.5, 0, 0), goal=(2.5, 0, 0), lo=(-3.5, -2.5, -2.5),
              hi=(3.5, 2.5, 2.5), resolution=0.04)


GENERATORS = {"apartment": apartment, "home": home, "twistycool": twistycool}


def main() -> None:
    write_all(GENERATORS, PAPER_DIR)


if __name__ == "__main__":
    main()
