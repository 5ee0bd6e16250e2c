"""TUM RGB-D sequence folders in, TUM trajectories out.

A folder holds ``rgb.txt`` and ``depth.txt`` (``timestamp path`` per line, ``#`` comments),
the images they name (8-bit colour PNG, 16-bit depth PNG at ``depth_scale`` units per metre,
0 = no reading) and optionally ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``, the
camera-to-world pose). An optional ``camera.txt`` (our addition, written by ``render.py``) holds
``fx fy cx cy width height depth_scale`` on one line; without it the camera is TUM's fr1, and
the command line can override either. Colour and depth are paired by nearest timestamp within 20 ms, as the
data set's own ``associate.py`` does; so are estimate and ground truth for evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fogiac.errors import WorkloadError
from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import make, quat_to_rot, rot_to_quat

MAX_DIFFERENCE_S = 0.02


@dataclass(frozen=True)
class Trajectory:
    stamps: np.ndarray  # (N,) seconds
    poses: np.ndarray  # (N, 4, 4) camera-to-world

    def __len__(self) -> int:
        return len(self.stamps)

    def positions(self) -> np.ndarray:
        return self.poses[:, :3, 3]


@dataclass(frozen=True)
class FrameFiles:
    stamp: float
    rgb: Path
    depth: Path


@dataclass(frozen=True)
class Sequence:
    root: Path
    frames: tuple[FrameFiles, ...]
    intrinsics: Intrinsics
    groundtruth: Trajectory | None

    @property
    def rate_hz(self) -> float:
        """The sequence's frame rate (median spacing of its timestamps)."""
        if len(self.frames) < 2:
            return 30.0
        return float(1.0 / np.median(np.diff([f.stamp for f in self.frames])))


def _list_file(path: Path) -> list[tuple[float, str]]:
    if not path.is_file():
        raise WorkloadError(f"{path}: missing (a TUM RGB-D folder has rgb.txt and depth.txt)")
    rows = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = line.split()
        try:
            rows.append((float(parts[0]), parts[1]))
        except (IndexError, ValueError):
            raise WorkloadError(f"{path}:{number}: expected 'timestamp filename', got {line!r}") from None
    return rows


def associate(first: np.ndarray, second: np.ndarray, *,
              max_difference: float = MAX_DIFFERENCE_S) -> list[tuple[int, int]]:
    """Index pairs (i, j), each used once, closest stamps first, within ``max_difference`` seconds."""
    if len(first) == 0 or len(second) == 0:
        return []
    gaps = np.abs(first[:, None] - second[None, :])
    candidates = np.argwhere(gaps <= max_difference)
    order = np.argsort(gaps[candidates[:, 0], candidates[:, 1]], kind="stable")
    used_i: set[int] = set()
    used_j: set[int] = set()
    pairs = []
    for i, j in candidates[order]:
        if i not in used_i and j not in used_j:
            used_i.add(int(i))
            used_j.add(int(j))
            pairs.append((int(i), int(j)))
    return sorted(pairs)


def read_trajectory(path: Path) -> Trajectory:
    stamps, poses = [], []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        values = line.split()
        if len(values) != 8:
            raise WorkloadError(f"{path}:{number}: expected 'timestamp tx ty tz qx qy qz qw', got {line!r}")
        v = np.array([float(x) for x in values])
        stamps.append(v[0])
        poses.append(make(quat_to_rot(v[4:8]), v[1:4]))
    return Trajectory(np.array(stamps), np.array(poses).reshape(-1, 4, 4))


def write_trajectory(path: Path, trajectory: Trajectory) -> None:
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for stamp, pose in zip(trajectory.stamps, trajectory.poses, strict=True):
        t, q = pose[:3, 3], rot_to_quat(pose[:3, :3])
        lines.append(f"{stamp:.6f} " + " ".join(f"{x:.7f}" for x in (*t, *q)))
    path.write_text("\n".join(lines) + "\n")


def read_sequence(root: Path, *, intrinsics: Intrinsics | None = None) -> Sequence:
    """The folder's colour/depth pairs in time order, and its ground truth when it has one."""
    if not root.is_dir():
        raise WorkloadError(f"{root}: not a folder")
    rgb, depth = _list_file(root / "rgb.txt"), _list_file(root / "depth.txt")
    pairs = associate(np.array([r[0] for r in rgb]), np.array([d[0] for d in depth]))
    if not pairs:
        raise WorkloadError(f"{root}: no colour and depth images within {MAX_DIFFERENCE_S * 1000:.0f} ms of each other")
    frames = tuple(FrameFiles(rgb[i][0], root / rgb[i][1], root / depth[j][1]) for i, j in pairs)
    gt = root / "groundtruth.txt"
    camera = intrinsics or read_camera(root / "camera.txt")
    return Sequence(root, frames, camera, read_trajectory(gt) if gt.is_file() else None)


def read_camera(path: Path) -> Intrinsics:
    """The folder's ``camera.txt``, or TUM's fr1 camera when there is none."""
    if not path.is_file():
        return Intrinsics.fr1()
    lines = [x for x in path.read_text().splitlines() if x.strip() and not x.lstrip().startswith("#")]
    values = lines[0].split() if lines else []
    if len(values) != 7:
        raise WorkloadError(f"{path}: expected one line 'fx fy cx cy width height depth_scale'")
    fx, fy, cx, cy, width, height, scale = (float(v) for v in values)
    return Intrinsics(fx, fy, cx, cy, int(width), int(height), scale)


def write_camera(path: Path, k: Intrinsics) -> None:
    path.write_text("# fx fy cx cy width height depth_scale\n"
                    f"{k.fx} {k.fy} {k.cx} {k.cy} {k.width} {k.height} {k.depth_scale}\n")


def load_frame(frame: FrameFiles, intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """(grey uint8 image, depth float32 metres, 0 where unknown) of one frame."""
    grey = cv2.imread(str(frame.rgb), cv2.IMREAD_GRAYSCALE)
    raw = cv2.imread(str(frame.depth), cv2.IMREAD_UNCHANGED)
    if grey is None or raw is None:
        raise WorkloadError(f"cannot read {frame.rgb if grey is None else frame.depth}")
    return grey, raw.astype(np.float32) / np.float32(intrinsics.depth_scale)


def matched_positions(estimate: Trajectory, truth: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """(estimated, true) positions of the stamps the two trajectories share within 20 ms."""
    pairs = associate(estimate.stamps, truth.stamps)
    if not pairs:
        raise WorkloadError("the estimate and the ground truth share no timestamps within 20 ms")
    i, j = np.array(pairs).T
    return estimate.positions()[i], truth.positions()[j]
