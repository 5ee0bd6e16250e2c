"""Lifting path vertices that graze a wall: the segments they end become provable, the ends stay put."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.workloads.motion_planning.mp_support import CUBE_OBJ, write_cfg
from workloads.motion_planning import Pose, load_problem
from workloads.motion_planning.problem import validity_resolution
from workloads.motion_planning.search import CHECK_DIVISOR, Search


def _small_cube(side: float) -> str:
    """CUBE_OBJ scaled from side 1 to ``side``."""
    lines = []
    for line in CUBE_OBJ.splitlines():
        if line.startswith("v "):
            lines.append("v " + " ".join(f"{float(v) * side:g}" for v in line.split()[1:]))
        else:
            lines.append(line)
    return "\n".join(lines) + "\n"


def test_a_vertex_that_grazes_a_wall_is_lifted_and_its_segments_are_proven(tmp_path: Path) -> None:
    (tmp_path / "world.obj").write_text(CUBE_OBJ)  # a unit cube: its top face at y = 0.5
    (tmp_path / "robot.obj").write_text(_small_cube(0.2))  # a 0.2 cube: fitted resolution 0.05
    problem = load_problem(write_cfg(tmp_path))
    search, res = Search(problem), validity_resolution(problem)
    floor = res / CHECK_DIVISOR
    start, goal = Pose(-2.0, 1.5, 0.0), Pose(2.0, 1.5, 0.0)
    grazing = Pose(0.0, 0.601, 0.0)  # 1 mm above the cube's top face
    clearance = search.certifier.clearance
    assert clearance(grazing.position(), grazing.quaternion()) < floor
    path = [start, grazing, goal]
    assert not search.certifier.segment_is_free(grazing, goal, floor=floor)  # what made a repair before
    lifted = search.lift(path, res)
    assert lifted[0] == start and lifted[-1] == goal
    assert clearance(lifted[1].position(), lifted[1].quaternion()) >= res / 2
    assert np.allclose(lifted[1].quaternion(), grazing.quaternion())  # moved, not turned
    assert all(search.certifier.segment_is_free(a, b, floor=floor) for a, b in zip(lifted, lifted[1:]))
    assert search.lift(lifted, res) == lifted  # nothing left to lift


def _slot(gap: float) -> str:
    """Two unit cubes, one above the other, with a slot of ``0.2 + 2 * gap`` between them."""
    lines, faces = [], []
    for dy in (0.0, 1.2 + 2 * gap):
        for line in CUBE_OBJ.splitlines():
            if line.startswith("v "):
                x, y, z = (float(v) for v in line.split()[1:])
                lines.append(f"v {x:g} {y + dy:g} {z:g}")
    for offset in (0, 8):
        faces += [f"f {' '.join(str(int(i) + offset) for i in line.split()[1:])}"
                  for line in CUBE_OBJ.splitlines() if line.startswith("f ")]
    return "\n".join(lines + faces) + "\n"


def test_a_vertex_with_no_way_out_stays_where_it_was(tmp_path: Path) -> None:
    """A 0.2 robot in a slot 1 mm wider than it on each side: no direction lifts it to half a step,
    so lifting leaves the path as it was (the certifier and a repair deal with it, as before)."""
    (tmp_path / "world.obj").write_text(_slot(0.001))
    (tmp_path / "robot.obj").write_text(_small_cube(0.2))
    problem = load_problem(write_cfg(tmp_path))
    search, res = Search(problem), validity_resolution(problem)
    path = [Pose(-2.0, 0.601, 0.0), Pose(0.0, 0.601, 0.0), Pose(2.0, 0.601, 0.0)]
    assert 0 < search.certifier.clearance(path[1].position(), path[1].quaternion()) < res / 2
    assert search.lift(path, res) == path


def test_a_segment_that_grazes_an_edge_midway_is_bent_away_from_it(tmp_path: Path) -> None:
    """Both ends far from the cube, the robot sliding down over the cube's top face at a shallow
    slope and leaving it 0.2 mm above its edge: the segment cannot be proven (the clearance grows
    too slowly either side), and bending it at that pose, lifted, gives two that can."""
    (tmp_path / "world.obj").write_text(CUBE_OBJ)
    (tmp_path / "robot.obj").write_text(_small_cube(0.2))
    problem = load_problem(write_cfg(tmp_path))
    search, res = Search(problem), validity_resolution(problem)
    floor, gap, slope = res / CHECK_DIVISOR, 0.0002, 0.1
    a, b = (Pose(0.6 + t, 0.6 + gap - slope * t, 0.0) for t in (-1.5, 1.5))
    assert not search.certifier.segment_is_free(a, b, floor=floor)
    bent = search._bend(a, b, resolution=res, floor=floor)
    assert bent is not None and bent[-1] == b
    (m,) = bent[:-1]
    assert search.certifier.clearance(m.position(), m.quaternion()) >= res / 2
    assert search.certifier.segment_is_free(a, m, floor=floor) and search.certifier.segment_is_free(m, b, floor=floor)
