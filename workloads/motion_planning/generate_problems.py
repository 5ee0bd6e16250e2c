"""Write the shipped problems (meshes + OMPL.app-style .cfg) into ``problems/``.

Run ``python -m workloads.motion_planning.generate_problems`` to regenerate them; output is
deterministic (the maze uses a fixed seed). Every world is built from boxes, so meshes stay
a few KB, and walls extend past the position bounds by more than the robot's radius, so
the only way through is the intended one.

- ``easy``: one wall with a wide window; a test fixture that solves in milliseconds.
- ``twisty``: a narrow twisting tunnel: plates whose slots turn 40 degrees apiece; a flat bar
  must roll to pass each one.
- ``cubicles``: two storeys of office cubicles with doors, joined by a hatch in the slab.
- ``maze``: an apartment-scale 6 x 6 maze of 2 m rooms under a ceiling, for a sofa-sized box.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import trimesh

from workloads.motion_planning.problem import PROBLEMS_DIR

Vec = Sequence[float]


def box(center: Vec, size: Vec) -> trimesh.Trimesh:
    """An axis-aligned box."""
    return trimesh.creation.box(extents=size, transform=trimesh.transformations.translation_matrix(center))


def box_between(lo: Vec, hi: Vec) -> trimesh.Trimesh:
    """The axis-aligned box with corners ``lo`` and ``hi``."""
    return box([(a + b) / 2 for a, b in zip(lo, hi, strict=True)], [b - a for a, b in zip(lo, hi, strict=True)])


def plate_with_slot(x: float, *, half: float, thick: float, slot: Vec, offset: Vec,
                    angle: float) -> list[trimesh.Trimesh]:
    """A square plate in the y-z plane at ``x`` with a rectangular slot, all turned by ``angle``."""
    sl, sw = slot  # slot extent along the plate's own y and z before turning
    oy, oz = offset
    top, bottom, left, right = oz + sw / 2, oz - sw / 2, oy - sl / 2, oy + sl / 2
    parts = [
        box((x, 0, (top + half) / 2), (thick, 2 * half, half - top)),
        box((x, 0, (bottom - half) / 2), (thick, 2 * half, bottom + half)),
        box((x, (left - half) / 2, oz), (thick, left + half, sw)),
        box((x, (right + half) / 2, oz), (thick, half - right, sw)),
    ]
    for p in parts:
        p.apply_transform(trimesh.transformations.rotation_matrix(angle, [1, 0, 0], [x, 0, 0]))
    return parts


def wall_with_door(a: Vec, b: Vec, *, height: float, z0: float, thick: float, door: float | None,
                   door_w: float, door_h: float) -> list[trimesh.Trimesh]:
    """A straight wall from a to b (2-D, axis-aligned) with an optional door centred at ``door``."""
    (ax, ay), (bx, by) = a, b
    along_x = abs(bx - ax) > abs(by - ay)
    lo, hi = (min(ax, bx), max(ax, bx)) if along_x else (min(ay, by), max(ay, by))
    fixed = ay if along_x else ax
    spans = [(lo, hi)] if door is None else [(lo, door - door_w / 2), (door + door_w / 2, hi)]
    parts = []
    for s0, s1 in spans:
        if s1 - s0 > 1e-9:
            parts.append(_wall_piece(along_x, fixed, s0, s1, z0, z0 + height, thick))
    if door is not None:  # the lintel over the door
        parts.append(_wall_piece(along_x, fixed, door - door_w / 2, door + door_w / 2, z0 + door_h, z0 + height,
                                 thick))
    return parts


def _wall_piece(along_x: bool, fixed: float, s0: float, s1: float, z0: float, z1: float,
                thick: float) -> trimesh.Trimesh:
    c, length = (s0 + s1) / 2, s1 - s0 + thick
    center = (c, fixed, (z0 + z1) / 2) if along_x else (fixed, c, (z0 + z1) / 2)
    size = (length, thick, z1 - z0) if along_x else (thick, length, z1 - z0)
    return box(center, size)


def write_cfg(path: Path, *, robot: str, world: str, start: Vec, goal: Vec, start_rot: Vec = (1, 0, 0, 0),
              goal_rot: Vec = (1, 0, 0, 0), lo: Vec, hi: Vec, time_limit: float, fraction: float | None) -> None:
    """``*_rot`` are (axis.x, axis.y, axis.z, theta); no ``fraction``: no [solver] section, as OMPL.app's."""
    lines = ["[problem]", f"name = {path.stem}", f"robot = {robot}", f"world = {world}"]
    for end, pos, rot in (("start", start, start_rot), ("goal", goal, goal_rot)):
        lines += [f"{end}.{k} = {v:g}" for k, v in zip("xyz", pos, strict=True)]
        lines += [f"{end}.theta = {rot[3]:.6f}"]
        lines += [f"{end}.axis.{k} = {v:g}" for k, v in zip("xyz", rot[:3], strict=True)]
    lines += [f"volume.{m}.{k} = {v:g}"
              for m, vec in (("min", lo), ("max", hi)) for k, v in zip("xyz", vec, strict=True)]
    if fraction is not None:
        lines += ["", "[solver]", f"time_limit = {time_limit:g}", f"longest_valid_segment_fraction = {fraction:g}"]
    lines += ["", "[benchmark]", f"time_limit = {time_limit:g}", "run_count = 10", ""]
    path.write_text("\n".join(lines), encoding="utf-8")


def export(meshes: list[trimesh.Trimesh], path: Path) -> None:
    trimesh.util.concatenate(meshes).export(str(path))


def easy(out: Path) -> None:
    parts = [box((0, 0, 2.75), (0.3, 10, 4.5)), box((0, 0, -2.75), (0.3, 10, 4.5)),  # a 1 m x 1 m window
             box((0, 2.75, 0), (0.3, 4.5, 1.0)), box((0, -2.75, 0), (0.3, 4.5, 1.0))]
    export(parts, out / "easy_env.stl")
    export([box((0, 0, 0), (1.0, 0.3, 0.3))], out / "easy_robot.stl")
    write_cfg(out / "easy.cfg", robot="easy_robot.stl", world="easy_env.stl", start=(-2, 0, 0), goal=(2, 0, 0),
              goal_rot=(0, 0, 1, math.pi / 2), lo=(-3, -3, -3), hi=(3, 3, 3), time_limit=10, fraction=0.005)


def twisty(out: Path, *, plates: int = 4, slot: Vec = (2.9, 0.95), name: str = "twisty", thick: float = 0.4,
           turn: float = 40.0, scale: float = 1.0, fraction: float | None = 0.002) -> None:
    """``turn`` degrees between slots; ``scale`` grows everything; ``fraction=None`` leaves [solver] out."""
    parts = []
    for k in range(plates):
        off = (0.6 * math.cos(1.3 * k), 0.6 * math.sin(1.3 * k))
        parts += plate_with_slot(3.0 * (k + 1), half=5.0, thick=thick, slot=slot, offset=off,
                                 angle=math.radians(turn * k))
    robot = box((0, 0, 0), (0.4, 2.0, 0.35))
    if scale != 1.0:
        for mesh in [*parts, robot]:
            mesh.apply_scale(scale)
    export(parts, out / f"{name}_env.stl")
    export([robot], out / f"{name}_robot.stl")
    length = 3.0 * (plates + 1) * scale
    half = 2.5 * scale
    write_cfg(out / f"{name}.cfg", robot=f"{name}_robot.stl", world=f"{name}_env.stl", start=(0.5 * scale, 0, 0),
              goal=(length - 0.5 * scale, 0, 0), lo=(0, -half, -half), hi=(length, half, half), time_limit=60,
              fraction=fraction)


def cubicles(out: Path, *, n: int = 2, door_w: float = 1.4, name: str = "cubicles") -> None:
    t, h, cell = 0.2, 3.0, 4.0
    size = n * cell
    lo, hi = -3.0, size + 3.0  # floor, slab and ceiling reach past the walls
    parts = [box_between((lo, lo, -0.5), (hi, hi, 0.0)), box_between((lo, lo, 2 * h), (hi, hi, 2 * h + 0.5))]
    h0, h1 = size - 2.8, size - 1.2  # the 1.6 m square hatch between storeys, in the far cubicle
    z0, z1 = h - 0.15, h + 0.15
    parts += [box_between((lo, lo, z0), (h0, hi, z1)), box_between((h1, lo, z0), (hi, hi, z1)),
              box_between((h0, lo, z0), (h1, h0, z1)), box_between((h0, h1, z0), (h1, hi, z1))]
    for storey in range(2):
        z0 = storey * h + (0.15 if storey else 0.0)
        for i in range(n + 1):
            for j in range(n):
                door = j * cell + cell / 2 + (1.0 if (i + j + storey) % 2 else -1.0) if 0 < i < n else None
                parts += wall_with_door((i * cell, j * cell), (i * cell, (j + 1) * cell), height=h - 0.15, z0=z0,
                                        thick=t, door=door, door_w=door_w, door_h=2.0)
                door = j * cell + cell / 2 if 0 < i < n and (i + j) % 2 == storey else None
                parts += wall_with_door((j * cell, i * cell), ((j + 1) * cell, i * cell), height=h - 0.15, z0=z0,
                                        thick=t, door=door, door_w=door_w, door_h=2.0)
    export(parts, out / f"{name}_env.stl")
    robot = [box((0, 0, 0), (0.9, 0.3, 0.3)), box((0.3, 0, 0.3), (0.3, 0.3, 0.4))]  # an L: vertex mean is off-centre
    export(robot, out / f"{name}_robot.stl")
    write_cfg(out / f"{name}.cfg", robot=f"{name}_robot.stl", world=f"{name}_env.stl", start=(2, 2, 1.0),
              goal=(2, 2, h + 1.2), lo=(0, 0, 0.1), hi=(size, size, 2 * h - 0.1), time_limit=60, fraction=0.002)


def maze(out: Path, *, cells: int = 6, cell: float = 2.0, seed: int = 7) -> None:
    rng = random.Random(seed)
    size, height, t = cells * cell, 2.4, 0.2
    walls = {(kind, i, j) for kind in "vh" for i in range(cells + 1) for j in range(cells)}
    seen, stack = {(0, 0)}, [(0, 0)]
    while stack:  # depth-first carving: a perfect maze, one route between any two rooms
        x, y = stack[-1]
        nbrs = [(x + dx, y + dy) for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))
                if 0 <= x + dx < cells and 0 <= y + dy < cells and (x + dx, y + dy) not in seen]
        if not nbrs:
            stack.pop()
            continue
        nx, ny = rng.choice(nbrs)
        walls.discard(("v", max(x, nx), y) if nx != x else ("h", max(y, ny), x))
        seen.add((nx, ny))
        stack.append((nx, ny))
    parts = [box_between((-2, -2, -0.5), (size + 2, size + 2, 0)),
             box_between((-2, -2, height), (size + 2, size + 2, height + 0.5))]
    for kind, i, j in sorted(walls):
        a, b = (i * cell, j * cell), (i * cell, (j + 1) * cell)
        if kind == "h":
            a, b = a[::-1], b[::-1]
        parts += wall_with_door(a, b, height=height, z0=0.0, thick=t, door=None, door_w=0, door_h=0)
    export(parts, out / "maze_env.stl")
    export([box((0, 0, 0), (1.3, 0.6, 0.7)), box((0, 0.2, 0.5), (1.3, 0.2, 0.3))], out / "maze_robot.stl")
    write_cfg(out / "maze.cfg", robot="maze_robot.stl", world="maze_env.stl", start=(1, 1, 1.0),
              goal=(size - 1, size - 1, 1.0), goal_rot=(0, 0, 1, math.pi / 2), lo=(0, 0, 0.55), hi=(size, size, 1.8),
              time_limit=60, fraction=0.002)


GENERATORS = {"easy": easy, "twisty": twisty, "cubicles": cubicles, "maze": maze}


def write_all(generators: Mapping[str, Callable[[Path], None]], folder: Path) -> None:
    """Write each generator's problem (its .cfg and meshes) into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, make in generators.items():
        make(folder)
        print(f"wrote {folder / name}.cfg")


def main() -> None:
    write_all(GENERATORS, PROBLEMS_DIR)


if __name__ == "__main__":
    main()
