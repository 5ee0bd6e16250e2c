"""Reading OMPL.app-style problem files: conventions checked against hand-computed numbers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from tests.workloads.motion_planning.mp_support import CUBE_OBJ, PROBLEMS, write_cfg

from fogiac.errors import WorkloadError
from workloads.motion_planning import Pose, load_problem
from workloads.motion_planning.problem import space_extent, validity_resolution

# Four vertices, one tetrahedron; written as Z_UP COLLADA below.
TETRA = [(0, 0, 0), (2, 0, 0), (0, 4, 0), (0, 0, 6)]
TETRA_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def collada(vertices: list[tuple[float, float, float]], faces: list[tuple[int, int, int]], *, up: str,
            matrix: str = "") -> str:
    floats = " ".join(f"{c:g}" for v in vertices for c in v)
    idx = " ".join(str(i) for f in faces for i in f)
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>{up}</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="p"><float_array id="pa" count="{len(vertices) * 3}">{floats}</float_array>
      <technique_common><accessor source="#pa" count="{len(vertices)}" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="{len(faces)}"><input semantic="VERTEX" source="#v" offset="0"/><p>{idx}</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n">{f"<matrix>{matrix}</matrix>" if matrix else ""}
    <instance_geometry url="#g"/></node></visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def _rows(a: np.ndarray) -> list[tuple[float, ...]]:
    return sorted(tuple(round(float(c), 9) for c in row) for row in a)


@pytest.fixture
def cube_dir(tmp_path: Path) -> Path:
    (tmp_path / "robot.obj").write_text(CUBE_OBJ)
    (tmp_path / "world.obj").write_text(CUBE_OBJ)
    return tmp_path


def test_z_up_collada_is_turned_y_up_and_robot_is_mean_centred(tmp_path: Path) -> None:
    pytest.importorskip("collada", reason="trimesh reads .dae through pycollada (pip install pycollada)")
    (tmp_path / "robot.dae").write_text(collada(TETRA, TETRA_FACES, up="Z_UP"))
    (tmp_path / "world.dae").write_text(collada(TETRA, TETRA_FACES, up="Z_UP"))
    problem = load_problem(write_cfg(tmp_path, robot="robot.dae", world="world.dae"))
    # (x, y, z) -> (x, z, -y): (0,0,0) (2,0,0) (0,0,-4) (0,6,0); their mean is (0.5, 1.5, -1).
    assert _rows(problem.world.vertices) == _rows(np.array([(0, 0, 0), (2, 0, 0), (0, 0, -4), (0, 6, 0)]))
    centred = [(-0.5, -1.5, 1), (1.5, -1.5, 1), (-0.5, -1.5, -3), (-0.5, 4.5, 1)]
    assert _rows(problem.robot.vertices) == _rows(np.array(centred))


def test_node_matrix_applies_before_the_up_axis_turn(tmp_path: Path) -> None:
    pytest.importorskip("collada", reason="trimesh reads .dae through pycollada (pip install pycollada)")
    # 90 degrees about z, then +(10, 20, 30): (x, y, z) -> (10 - y, 20 + x, 30 + z); then Z_UP: (x, z, -y).
    matrix = "0 -1 0 10  1 0 0 20  0 0 1 30  0 0 0 1"
    (tmp_path / "world.dae").write_text(collada(TETRA, TETRA_FACES, up="Z_UP", matrix=matrix))
    (tmp_path / "robot.obj").write_text(CUBE_OBJ)
    problem = load_problem(write_cfg(tmp_path, world="world.dae"))
    expected = [(10, 30, -20), (10, 30, -22), (6, 30, -20), (10, 36, -20)]
    assert _rows(problem.world.vertices) == _rows(np.array(expected, dtype=float))


def test_y_up_collada_is_left_alone(tmp_path: Path) -> None:
    pytest.importorskip("collada", reason="trimesh reads .dae through pycollada (pip install pycollada)")
    (tmp_path / "world.dae").write_text(collada(TETRA, TETRA_FACES, up="Y_UP"))
    (tmp_path / "robot.obj").write_text(CUBE_OBJ)
    problem = load_problem(write_cfg(tmp_path, world="world.dae"))
    assert _rows(problem.world.vertices) == _rows(np.array(TETRA, dtype=float))


def test_obj_robot_is_centred_on_vertex_mean_not_bounding_box(tmp_path: Path) -> None:
    # Six distinct vertices: bounding-box centre (1.5, 0.5, 0), vertex mean (8/6, 3/6, 0).
    verts = [(0, 0, 0), (3, 0, 0), (3, 1, 0), (1, 1, 0), (1, 2, 0), (0, -1, 0)]
    (tmp_path / "robot.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in verts)
                                        + "f 1 2 3\nf 1 3 4\nf 1 4 5\nf 1 6 2\n")
    (tmp_path / "world.obj").write_text(CUBE_OBJ)
    problem = load_problem(write_cfg(tmp_path))
    mean = np.array([8 / 6, 3 / 6, 0.0])
    assert _rows(problem.robot.vertices) == _rows(np.array(verts, dtype=float) - mean)


def test_poses_bounds_and_limits(cube_dir: Path) -> None:
    problem = load_problem(write_cfg(cube_dir, extra="[solver]\ntime_limit = 7.5\n[benchmark]\ntime_limit = 99\n"))
    assert problem.name == "p"
    assert problem.start == Pose(-2.0, 0.0, 0.0)
    h = math.sqrt(0.5)  # 90 degrees about z; the axis (0, 0, 2) is normalised
    assert problem.goal.as_dict() == pytest.approx({"x": 2, "y": 0, "z": 0, "qx": 0, "qy": 0, "qz": h, "qw": h})
    assert (problem.bounds_min, problem.bounds_max) == ((-3, -3, -3), (3, 3, 3))
    assert problem.time_limit == 7.5
    assert problem.segment_fraction is None and problem.resolution is None


def test_validity_resolution_is_fitted_unless_set(cube_dir: Path) -> None:
    fitted = load_problem(write_cfg(cube_dir))
    assert validity_resolution(fitted) == pytest.approx(1.0 / 4)  # the unit cube robot's thinnest side, over 4
    fraction = load_problem(write_cfg(cube_dir, extra="[solver]\nlongest_valid_segment_fraction = 0.01\n"))
    assert validity_resolution(fraction) == pytest.approx(0.01 * space_extent(fraction))
    assert space_extent(fraction) == pytest.approx(math.sqrt(3 * 36) + math.pi * math.sqrt(0.75))
    given = load_problem(write_cfg(cube_dir, extra="[solver]\nresolution = 0.02\nlongest_valid_segment_fraction = 0.5\n"))
    assert validity_resolution(given) == 0.02
    with pytest.raises(WorkloadError, match=r"p\.cfg: \[solver\] resolution: must be positive, got -1$"):
        load_problem(write_cfg(cube_dir, extra="[solver]\nresolution = -1\n"))


def test_benchmark_time_limit_and_inferred_volume(cube_dir: Path) -> None:
    drop = tuple(f"volume.{m}.{a}" for m in ("min", "max") for a in "xyz")
    problem = load_problem(write_cfg(cube_dir, drop=drop, extra="[benchmark]\ntime_limit = 20.0\n"))
    assert problem.time_limit == 20.0
    # world cube [-0.5, 0.5]^3 grown to hold start x=-2 and goal x=2
    assert (problem.bounds_min, problem.bounds_max) == ((-2, -0.5, -0.5), (2, 0.5, 0.5))


def test_shipped_problems_load() -> None:
    names = sorted(p.stem for p in PROBLEMS.glob("*.cfg"))
    assert names == ["cubicles", "easy", "maze", "twisty"]
    for name in names:
        problem = load_problem(PROBLEMS / f"{name}.cfg")
        assert problem.name == name
        assert np.allclose(problem.robot.vertices.mean(axis=0), 0.0)
        assert (PROBLEMS / f"{name}_env.stl").stat().st_size < 300_000


@pytest.mark.parametrize(
    ("problem", "drop", "extra", "message"),
    [
        ({}, ("start.x",), "", r"p\.cfg: \[problem\] start\.x: missing$"),
        ({"goal.axiz.x": "0"}, ("goal.axis.x",), "",
         r"p\.cfg: \[problem\] goal\.axis\.x: missing \(did you mean 'goal\.axiz\.x'\?\)$"),
        ({"start.y": "north"}, (), "", r"p\.cfg: \[problem\] start\.y: 'north' is not a number$"),
        ({"goal.theta": "nan"}, (), "", r"p\.cfg: \[problem\] goal\.theta: 'nan' is not a finite number$"),
        ({"robot": "nope.stl"}, (), "", r"p\.cfg: \[problem\] robot: mesh file not found: .*nope\.stl$"),
        ({}, ("volume.max.z",), "",
         r"p\.cfg: \[problem\] volume\.max\.z: missing \(give all six volume\.\* keys or none\)$"),
        ({"volume.min.y": "3"}, (), "", r"p\.cfg: \[problem\] volume\.min\.y: must be less than volume\.max\.y$"),
        ({}, (), "[solver]\ntime_limit = -1\n", r"p\.cfg: \[solver\] time_limit: must be positive, got -1$"),
    ],
)
def test_bad_cfg_names_file_and_key(cube_dir: Path, problem: dict[str, str], drop: tuple[str, ...], extra: str,
                                    message: str) -> None:
    with pytest.raises(WorkloadError, match=message):
        load_problem(write_cfg(cube_dir, problem=problem, drop=drop, extra=extra))


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(WorkloadError, match=r"missing\.cfg: problem file not found$"):
        load_problem(tmp_path / "missing.cfg")
    (tmp_path / "x.cfg").write_text("[solver]\ntime_limit = 1\n")
    with pytest.raises(WorkloadError, match=r"x\.cfg: no \[problem\] section$"):
        load_problem(tmp_path / "x.cfg")
    (tmp_path / "y.cfg").write_text("robot = a.stl\n")
    with pytest.raises(WorkloadError, match=r"y\.cfg: not an INI-style problem file: File contains no section headers"):
        load_problem(tmp_path / "y.cfg")


# OMPL.app's Home.cfg: its benchmark tool's sections repeat keys (aps= twice), as OMPL.app's parser allows
HOME_STYLE = ("[benchmark]\ntime_limit=60.0\nmem_limit=1000.0\nrun_count=50\n\n[planner]\nprm=\nrrtstar=\naps=\n"
              "aps.name=APS1\naps.num_planners=1\naps=\naps.name=APS4\naps.num_planners=4\n")


def test_repeated_keys_in_sections_fogiac_does_not_read_pass(cube_dir: Path) -> None:
    problem = load_problem(write_cfg(cube_dir, extra=HOME_STYLE))
    assert problem.time_limit == 60.0 and problem.start == Pose(-2.0, 0.0, 0.0)


@pytest.mark.parametrize(("extra", "message"), [
    ("start.x = 1\n", r"p\.cfg: \[problem\] start\.x: given twice \(lines 4 and 24\)$"),
    ("[benchmark]\ntime_limit = 5\nrun_count = 1\ntime_limit = 6\n",
     r"p\.cfg: \[benchmark\] time_limit: given twice \(lines 25 and 27\)$"),
    ("[solver]\nresolution = 0.1\n[planner]\naps=\n[solver]\nresolution: 0.2\n",
     r"p\.cfg: \[solver\] resolution: given twice \(lines 25 and 29\)$"),
])
def test_a_key_fogiac_reads_given_twice_is_refused(cube_dir: Path, extra: str, message: str) -> None:
    with pytest.raises(WorkloadError, match=message):
        load_problem(write_cfg(cube_dir, extra=extra))


def test_paper_class_problems_load() -> None:
    from workloads.motion_planning.paper_problems import PAPER_DIR

    names = sorted(p.stem for p in PAPER_DIR.glob("*.cfg"))
    assert names == ["apartment", "home", "twistycool"]
    for name in names:
        problem = load_problem(PAPER_DIR / f"{name}.cfg")
        assert problem.name == name and problem.resolution is not None
        assert (PAPER_DIR / f"{name}_env.stl").stat().st_size < 100_000
    assert "aps=\n" in (PAPER_DIR / "home.cfg").read_text().split("[planner]")[1]
