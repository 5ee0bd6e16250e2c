"""OMPL.app-style ``.cfg`` problem files, read once into a frozen :class:`Problem`.

OMPL.app's conventions are kept so its benchmark problems come out right:

- meshes are read the way assimp reads them: a COLLADA file whose ``<up_axis>`` is ``Z_UP``
  is turned Y-up, (x, y, z) becomes (x, z, -y) (``X_UP``: (x, y, z) becomes (-y, x, z));
  STL and OBJ files are taken as they are; COLLADA ``<unit>`` is not applied;
- the robot mesh is shifted so the mean of its (merged) vertices is at the origin before a
  pose is applied;
- a pose is a position plus an axis-angle rotation (``theta`` in radians);
- without ``volume.*`` the bounds are the world mesh's bounding box, grown to hold start and goal.

The validity resolution (how far any robot point may move between two collision checks while
planning) is fitted to the robot unless the file sets it; see :func:`validity_resolution`.
"""

from __future__ import annotations

import configparser
import dataclasses
import difflib
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fogiac.errors import WorkloadError

# assimp's root-node rotation per COLLADA up axis, applied to column vectors.
_UP_AXIS = {
    "Y_UP": np.eye(3),
    "Z_UP": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    "X_UP": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
}
_PROBLEM_KEYS = (
    "robot", "world",
    *(f"{end}.{k}" for end in ("start", "goal") for k in ("x", "y", "z", "theta", "axis.x", "axis.y", "axis.z")),
)
_VOLUME_KEYS = tuple(f"volume.{m}.{a}" for m in ("min", "max") for a in "xyz")
PROBLEMS_DIR = Path(__file__).resolve().parent / "problems"  # the problems shipped with the workload
DEFAULT_TIME_LIMIT = 10.0
ROBOT_THICKNESS_STEPS = 4  # fitted resolution: the robot's thinnest extent over this


@dataclass(frozen=True)
class Pose:
    """Position plus unit quaternion (x, y, z, w order as in geometry_msgs/Pose)."""

    x: float
    y: float
    z: float
    qx: float = 0.0
    qy: float = 0.0
    qz: float = 0.0
    qw: float = 1.0

    @classmethod
    def from_arrays(cls, position: np.ndarray, quaternion: np.ndarray) -> Pose:
        """The inverse of :meth:`position` and :meth:`quaternion` (w, x, y, z)."""
        x, y, z = (float(v) for v in position)
        w, qx, qy, qz = (float(v) for v in quaternion)
        return cls(x, y, z, qx, qy, qz, w)

    @classmethod
    def from_axis_angle(cls, x: float, y: float, z: float, *, axis: tuple[float, float, float], theta: float) -> Pose:
        norm = math.sqrt(sum(a * a for a in axis))
        if norm == 0.0:
            return cls(x, y, z)
        s = math.sin(theta / 2.0) / norm
        return cls(x, y, z, axis[0] * s, axis[1] * s, axis[2] * s, math.cos(theta / 2.0))

    def position(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def quaternion(self) -> np.ndarray:
        """(w, x, y, z), normalised: the order fcl and OMPL's SO3 math use."""
        q = np.array([self.qw, self.qx, self.qy, self.qz])
        return q / np.linalg.norm(q)

    def as_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")}


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangle soup: float (n, 3) vertices and int (m, 3) faces."""

    vertices: np.ndarray
    faces: np.ndarray

    def radius(self) -> float:
        return float(np.linalg.norm(self.vertices, axis=1).max()) if len(self.vertices) else 0.0


@dataclass(frozen=True, eq=False)
class Problem:
    """A rigid body to move from start to goal among a static world, inside position bounds."""

    name: str
    robot: Mesh  # already mean-centred
    world: Mesh
    start: Pose
    goal: Pose
    bounds_min: tuple[float, float, float]
    bounds_max: tuple[float, float, float]
    time_limit: float = DEFAULT_TIME_LIMIT
    segment_fraction: float | None = None  # OMPL's longest_valid_segment_fraction, when the file sets it
    resolution: float | None = None  # [solver] resolution in world units, when the file sets it
    source: str = field(default="")

    def with_endpoints(self, start: Pose, goal: Pose) -> Problem:
        """The same scene with other endpoints (a ROS request may bring its own)."""
        return dataclasses.replace(self, start=start, goal=goal)


def read_mesh(path: Path, *, cfg: Path, key: str) -> Mesh:
    """Load a mesh like assimp does; errors name the cfg file and key that pointed here."""
    import trimesh  # noqa: PLC0415 (a workload extra, slow to load: only reading a mesh needs it)

    if not path.is_file():
        raise WorkloadError(f"{cfg}: [problem] {key}: mesh file not found: {path}")
    try:
        mesh = trimesh.load(str(path), force="mesh", process=True)
    except Exception as err:  # trimesh raises many types for unreadable files
        raise WorkloadError(f"{cfg}: [problem] {key}: cannot read mesh {path}: {err}".replace("\n", " ")) from err
    if not isinstance(mesh, trimesh.Trimesh):  # force="mesh" merges a scene into one; anything else holds none
        raise WorkloadError(f"{cfg}: [problem] {key}: {path} holds no triangle mesh ({type(mesh).__name__})")
    vertices = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0:
        raise WorkloadError(f"{cfg}: [problem] {key}: mesh {path} has no triangles")
    if path.suffix.lower() == ".dae":
        vertices = vertices @ _UP_AXIS[collada_up_axis(path)].T
    return Mesh(vertices, faces)


def collada_up_axis(path: Path) -> str:
    """The ``<asset><up_axis>`` of a COLLADA file; Y_UP when absent, as the spec says."""
    for _, elem in ET.iterparse(str(path)):
        if elem.tag.rsplit("}", 1)[-1] == "up_axis":
            axis = (elem.text or "").strip()
            return axis if axis in _UP_AXIS else "Y_UP"
    return "Y_UP"


def load_problem(path: str | Path) -> Problem:
    """Read and check an OMPL.app-style problem file; every error names the file and the key."""
    cfg_path = Path(path)
    # OMPL.app's own files repeat keys in sections only its benchmark tool reads (Home.cfg: ``aps=`` twice
    # under [planner]), and its parser takes them; so does this one, but a key fogiac reads must be single.
    parser = configparser.ConfigParser(interpolation=None, strict=False)
    try:
        text = cfg_path.read_text(encoding="utf-8")
        parser.read_string(text, source=str(cfg_path))
    except FileNotFoundError as err:
        raise WorkloadError(f"{cfg_path}: problem file not found") from err
    except configparser.Error as err:
        raise WorkloadError(f"{cfg_path}: not an INI-style problem file: {err.message.splitlines()[0]}") from err
    _refuse_repeats(cfg_path, text)
    if not parser.has_section("problem"):
        raise WorkloadError(f"{cfg_path}: no [problem] section")
    section = parser["problem"]
    for key in _PROBLEM_KEYS:
        if key not in section:
            unknown = [k for k in section if k not in _PROBLEM_KEYS and k not in _VOLUME_KEYS]
            near = difflib.get_close_matches(key, unknown, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise WorkloadError(f"{cfg_path}: [problem] {key}: missing{hint}")
    num = {key: _number(cfg_path, "problem", key, section[key]) for key in _PROBLEM_KEYS[2:]}
    start, goal = (
        Pose.from_axis_angle(num[f"{e}.x"], num[f"{e}.y"], num[f"{e}.z"], theta=num[f"{e}.theta"],
                             axis=(num[f"{e}.axis.x"], num[f"{e}.axis.y"], num[f"{e}.axis.z"]))
        for e in ("start", "goal")
    )
    base = cfg_path.parent
    robot = read_mesh(base / section["robot"], cfg=cfg_path, key="robot")
    robot = Mesh(robot.vertices - robot.vertices.mean(axis=0), robot.faces)
    world = read_mesh(base / section["world"], cfg=cfg_path, key="world")
    lo, hi = _bounds(cfg_path, section, world, start, goal)
    return Problem(
        name=section.get("name", cfg_path.stem).strip() or cfg_path.stem,
        robot=robot, world=world, start=start, goal=goal, bounds_min=lo, bounds_max=hi,
        time_limit=_time_limit(cfg_path, parser),
        segment_fraction=_optional_positive(cfg_path, parser, "longest_valid_segment_fraction"),
        resolution=_optional_positive(cfg_path, parser, "resolution"),
        source=str(cfg_path),
    )


_READ: dict[str, frozenset[str] | None] = {"problem": None, "solver": None,  # section -> keys read (None: all)
                                          "benchmark": frozenset({"time_limit"})}


def _refuse_repeats(cfg: Path, text: str) -> None:
    """A key fogiac reads, given twice in its section, is an error naming both lines; repeats elsewhere
    ([planner], the rest of [benchmark]: OMPL.app's benchmark settings, unused here) pass."""
    section, seen = "", dict[tuple[str, str], int]()  # a section opened twice is one section, as configparser has it
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1].strip().lower()
            continue
        key = line.split("=", 1)[0].split(":", 1)[0].strip().lower()
        read = _READ.get(section, frozenset())
        if read is not None and key not in read:
            continue
        if (section, key) in seen:
            raise WorkloadError(f"{cfg}: [{section}] {key}: given twice (lines {seen[section, key]} and {number})")
        seen[section, key] = number


def space_extent(problem: Problem) -> float:
    """How far a robot point can move across the space: the volume's diagonal plus half a turn."""
    diagonal = float(np.linalg.norm(np.subtract(problem.bounds_max, problem.bounds_min)))
    return diagonal + math.pi * problem.robot.radius()


def validity_resolution(problem: Problem) -> float:
    """World units any robot point may move between two checks while planning.

    ``[solver] resolution`` wins; else ``longest_valid_segment_fraction`` keeps OMPL's meaning
    (that fraction of the space's extent per step); else a quarter of the robot's thinnest
    extent, so the robot cannot hop over a wall however thin, whatever the space's size.
    OMPL's own default (1% of the extent) ignores the robot and steps over thin walls.
    """
    if problem.resolution is not None:
        return problem.resolution
    if problem.segment_fraction is not None:
        return problem.segment_fraction * space_extent(problem)
    extents = problem.robot.vertices.max(axis=0) - problem.robot.vertices.min(axis=0)
    return float(extents.min()) / ROBOT_THICKNESS_STEPS


def _bounds(cfg: Path, section: configparser.SectionProxy, world: Mesh, start: Pose,
            goal: Pose) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    given = [k for k in _VOLUME_KEYS if k in section]
    if given and len(given) < len(_VOLUME_KEYS):
        missing = next(k for k in _VOLUME_KEYS if k not in section)
        raise WorkloadError(f"{cfg}: [problem] {missing}: missing (give all six volume.* keys or none)")
    if given:
        v = [_number(cfg, "problem", k, section[k]) for k in _VOLUME_KEYS]
        lo, hi = v[:3], v[3:]
        for axis, a, b in zip("xyz", lo, hi, strict=True):
            if a >= b:
                raise WorkloadError(f"{cfg}: [problem] volume.min.{axis}: must be less than volume.max.{axis}")
    else:
        pts = np.vstack([world.vertices, start.position(), goal.position()])
        lo, hi = pts.min(axis=0).tolist(), pts.max(axis=0).tolist()
    return (lo[0], lo[1], lo[2]), (hi[0], hi[1], hi[2])


def _time_limit(cfg: Path, parser: configparser.ConfigParser) -> float:
    """[solver] time_limit wins over [benchmark] time_limit; OMPL.app files carry the latter."""
    for section in ("solver", "benchmark"):
        if parser.has_option(section, "time_limit"):
            return _positive(cfg, parser, section, "time_limit", DEFAULT_TIME_LIMIT)
    return DEFAULT_TIME_LIMIT


def _optional_positive(cfg: Path, parser: configparser.ConfigParser, key: str) -> float | None:
    return _positive(cfg, parser, "solver", key, 0.0) if parser.has_option("solver", key) else None


def _positive(cfg: Path, parser: configparser.ConfigParser, section: str, key: str, default: float) -> float:
    if not parser.has_option(section, key):
        return default
    value = _number(cfg, section, key, parser.get(section, key))
    if value <= 0:
        raise WorkloadError(f"{cfg}: [{section}] {key}: must be positive, got {value:g}")
    return value


def _number(cfg: Path, section: str, key: str, raw: str) -> float:
    try:
        value = float(raw)
    except ValueError:
        raise WorkloadError(f"{cfg}: [{section}] {key}: {raw.strip()!r} is not a number") from None
    if not math.isfinite(value):
        raise WorkloadError(f"{cfg}: [{section}] {key}: {raw.strip()!r} is not a finite number")
    return value
