"""The project's own test sequences: a textured room ray-cast with numpy, written as a TUM folder.

No data set can be downloaded where fogiac is tested, so sequences are rendered: an axis-aligned
room (5 x 3 x 5 m) with a few boxes standing in it, every face covered by its own random texture
of sharp-edged shapes (ORB finds corners on them as on a cluttered office). Each pixel's ray is
intersected with the room's inside and the boxes' outsides; the nearest hit gives the depth (the
optical-axis distance, as a depth camera reports it) and a bilinear texture lookup (``cv2.remap``
on one texture atlas). Sensor noise is added to both images, with depth noise growing with the
square of the distance as in a structured-light sensor.

Paths (``KINDS``): ``desk`` sways in front of one wall (fr1/desk-like); ``loop`` turns once
around the room and comes back to its first view (loop closure has something to find). The
harder test set (``TEST_SET``) adds what those two never exercise: ``bigloop`` walks an ellipse
1.9 x 1.5 m across, looking half ahead, half outwards (the shape a monocular map must keep);
``forward`` walks 1.6 m straight at a wall (little parallax near the image centre); ``turn``
swings the camera through 140 degrees about a small sway (rotation-heavy); ``wall`` is the desk
sway in a room of low-texture faces (few, faint shapes: few features to track).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from fogiac.errors import WorkloadError
from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import make
from workloads.slam.tum import Trajectory, write_camera, write_trajectory

ROOM = (np.array([-2.5, -1.5, -2.5]), np.array([2.5, 1.5, 2.5]))  # world y points down, as the camera's
BOXES = (  # (low corner, high corner) of boxes standing on the floor (y = 1.5)
    ((-1.9, 0.3, 1.2), (-1.1, 1.5, 2.1)),
    ((0.6, 0.7, 1.5), (1.5, 1.5, 2.3)),
    ((1.5, -0.2, -0.9), (2.3, 1.5, 0.2)),
    ((-0.7, 0.9, -2.3), (0.5, 1.5, -1.6)),
    ((-2.4, 0.1, -1.2), (-1.7, 1.5, -0.3)),
)
TILE = 1024  # texels per side of one face's texture
TEXEL_M = 0.005  # metres per texel: a tile spans 5.1 m, so no face (5 m at most) repeats its texture
GRID = 6  # atlas tiles per row: 6 faces x (room + 5 boxes) = 36 tiles
START_STAMP = 1000.0


SHAPES = 2500  # per face: a cluttered office
SPARSE_SHAPES = 120  # per face of the low-texture room


def _texture(rng: np.random.Generator, shapes: int = SHAPES) -> np.ndarray:
    """Sharp-edged shapes at several sizes over fine noise: corners at every viewing distance.

    Fewer ``shapes`` than the default also fade the noise and the shapes' contrast: a plain wall."""
    sparse = shapes < SHAPES
    noise = rng.integers(0, 256, (TILE // 8, TILE // 8)).astype(np.uint8)
    smooth = cv2.resize(noise, (TILE, TILE), interpolation=cv2.INTER_CUBIC)
    tile = smooth // 16 + 120 if sparse else smooth // 2 + 64
    for _ in range(shapes):
        colour = int(rng.integers(80, 200)) if sparse else int(rng.integers(0, 256))
        x, y = (int(v) for v in rng.integers(0, TILE, 2))
        size = int(rng.integers(4, 48))
        shape = rng.integers(0, 3)
        if shape == 0:
            cv2.rectangle(tile, (x, y), (x + size, y + int(rng.integers(4, 48))), colour, -1)
        elif shape == 1:
            cv2.circle(tile, (x, y), size // 2, colour, -1)
        else:
            points = rng.integers(-size, size, (4, 2)) + np.array([x, y])
            cv2.fillPoly(tile, [points.astype(np.int32)], colour)
    return cv2.GaussianBlur(tile, (3, 3), 0.7)


def _atlas(seed: int, shapes: int = SHAPES) -> np.ndarray:
    rng = np.random.default_rng(seed)
    atlas = np.zeros((GRID * TILE, GRID * TILE), np.uint8)
    for k in range(GRID * GRID):
        r, c = divmod(k, GRID)
        atlas[r * TILE:(r + 1) * TILE, c * TILE:(c + 1) * TILE] = _texture(rng, shapes)
    return atlas


class Scene:
    """The room, its boxes and their texture atlas; :meth:`render` gives one frame."""

    def __init__(self, intrinsics: Intrinsics, *, seed: int = 0, shapes: int = SHAPES) -> None:
        self.intrinsics = intrinsics
        self.atlas = _atlas(seed, shapes)
        self.tints = np.random.default_rng(seed + 1).uniform(0.65, 1.0, (GRID * GRID, 3)).astype(np.float32)
        u, v = np.meshgrid(np.arange(intrinsics.width, dtype=np.float64),
                           np.arange(intrinsics.height, dtype=np.float64))
        self.rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy,
                              np.ones_like(u)], axis=-1).reshape(-1, 3).astype(np.float32)
        # Rays with camera z = 1: a hit's ray parameter t is its depth.

    def render(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(BGR uint8 image, depth float32 metres) seen from camera-to-world ``pose``, noise-free.

        Arrays are one per axis (structure of arrays): numpy's per-row reductions on (N, 3)
        arrays were ten times slower.
        """
        d = [np.ascontiguousarray(c) for c in (self.rays @ pose[:3, :3].T.astype(np.float32)).T]
        o = pose[:3, 3].astype(np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = [np.float32(1.0) / c for c in d]
        lo, hi = ROOM
        best = np.full(len(d[0]), np.inf, np.float32)
        axis = np.zeros(len(d[0]), np.int64)
        face = np.zeros(len(d[0]), np.int64)
        for k in range(3):  # the room from inside: the first wall each ray leaves through
            t = np.where(d[k] > 0, (hi[k] - o[k]) * inv[k], (lo[k] - o[k]) * inv[k])
            closer = t < best
            face = np.where(closer, 2 * k + (d[k] > 0), face)
            best, axis = np.where(closer, t, best), np.where(closer, k, axis)
        for b, (blo, bhi) in enumerate(BOXES, start=1):  # the boxes from outside: slab test
            near = np.full(len(d[0]), -np.inf, np.float32)
            far = np.full(len(d[0]), np.inf, np.float32)
            b_axis = np.zeros(len(d[0]), np.int64)
            for k in range(3):
                t1, t2 = (blo[k] - o[k]) * inv[k], (bhi[k] - o[k]) * inv[k]
                k_near = np.minimum(t1, t2)
                later = k_near > near
                near, b_axis = np.where(later, k_near, near), np.where(later, k, b_axis)
                far = np.minimum(far, np.maximum(t1, t2))
            hit = (near <= far) & (near > 1e-6) & (near < best)
            side = np.choose(b_axis, d) < 0
            best = np.where(hit, near, best)
            face = np.where(hit, b * 6 + b_axis * 2 + side, face)
            axis = np.where(hit, b_axis, axis)
        point = [o[k] + d[k] * best for k in range(3)]
        s = np.choose(axis, [point[1], point[0], point[0]])
        t = np.choose(axis, [point[2], point[2], point[1]])
        row, col = np.divmod(face, GRID)
        map_x = (np.mod(s / TEXEL_M, TILE - 2) + 1 + col * TILE).astype(np.float32)
        map_y = (np.mod(t / TEXEL_M, TILE - 2) + 1 + row * TILE).astype(np.float32)
        shape = (self.intrinsics.height, self.intrinsics.width)
        grey = cv2.remap(self.atlas, map_x.reshape(shape), map_y.reshape(shape), cv2.INTER_LINEAR)
        image = (grey[..., None] * self.tints[face].reshape(*shape, 3)).astype(np.uint8)
        return image, best.reshape(shape)


def _look(eye: np.ndarray, yaw: float, pitch: float) -> np.ndarray:
    """Camera-to-world pose at ``eye``, turned ``yaw`` about the world's vertical, tilted ``pitch``."""
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    r_yaw = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    r_pitch = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    return make(r_yaw @ r_pitch, eye)


def desk_path(n: int) -> list[np.ndarray]:
    """A hand-held sway in front of the +z wall and its boxes: about 0.6 m and 30 degrees of motion."""
    poses = []
    for i in range(n):
        a = 2 * math.pi * i / max(n, 1)
        eye = np.array([0.35 * math.sin(a), -0.1 + 0.12 * math.sin(2 * a), -0.4 + 0.25 * math.sin(a + 1.0)])
        poses.append(_look(eye, 0.28 * math.sin(a + 0.5), -0.12 + 0.1 * math.sin(2 * a + 0.3)))
    return poses


def loop_path(n: int) -> list[np.ndarray]:
    """One turn (and a little more) around the room's centre looking outwards, back over its first view."""
    poses = []
    for i in range(n):
        a = 2 * math.pi * 1.12 * i / max(n - 1, 1)
        eye = np.array([0.6 * math.sin(a), -0.05 * math.cos(2 * a), 0.6 * math.cos(a) - 0.6])
        poses.append(_look(eye, a, -0.08 + 0.05 * math.sin(3 * a)))
    return poses


def bigloop_path(n: int) -> list[np.ndarray]:
    """An ellipse 1.9 x 1.5 m across (about 5.4 m walked), looking 35 degrees ahead of outwards."""
    poses = []
    for i in range(n):
        a = 2 * math.pi * i / max(n - 1, 1)
        eye = np.array([0.95 * math.sin(a), -0.1 + 0.04 * math.sin(3 * a), 0.75 * math.cos(a)])
        poses.append(_look(eye, a + 0.6, -0.06 + 0.04 * math.sin(2 * a)))
    return poses


def forward_path(n: int) -> list[np.ndarray]:
    """1.6 m straight towards the +z wall's boxes, with a slight hand-held sway."""
    poses = []
    for i in range(n):
        s = i / max(n - 1, 1)
        eye = np.array([0.08 * math.sin(3 * math.pi * s), -0.1 + 0.04 * math.sin(5 * math.pi * s), -1.2 + 1.6 * s])
        poses.append(_look(eye, 0.1 * math.sin(2 * math.pi * s), -0.05))
    return poses


def turn_path(n: int) -> list[np.ndarray]:
    """A 140-degree swing and back about a 0.3 m sway: mostly rotation, some parallax."""
    poses = []
    for i in range(n):
        a = 2 * math.pi * i / max(n - 1, 1)
        eye = np.array([0.15 * math.sin(a), -0.1, -0.3 + 0.15 * (1 - math.cos(a))])
        poses.append(_look(eye, 1.22 * math.sin(a), -0.05 + 0.05 * math.sin(2 * a)))
    return poses


KINDS: dict[str, Callable[[int], list[np.ndarray]]] = {
    "bigloop": bigloop_path, "desk": desk_path, "forward": forward_path, "loop": loop_path, "turn": turn_path,
    "wall": desk_path,
}
LOW_TEXTURE = {"wall"}  # kinds rendered in the low-texture room
TEST_SET = ("bigloop", "forward", "turn", "wall")  # the harder sequences (testset.py), beside desk and loop


def render_sequence(out: Path, *, kind: str = "desk", frames: int = 150, rate_hz: float = 30.0, seed: int = 0,
                    intrinsics: Intrinsics | None = None, noise: bool = True) -> Trajectory:
    """Write a TUM RGB-D folder (PNG colour and 16-bit depth, lists, ground truth); returns the truth."""
    if kind not in KINDS:
        raise WorkloadError(f"unknown sequence kind {kind!r}; valid: {', '.join(sorted(KINDS))}")
    intrinsics = intrinsics or Intrinsics.fr1()
    scene = Scene(intrinsics, seed=seed, shapes=SPARSE_SHAPES if kind in LOW_TEXTURE else SHAPES)
    rng = np.random.default_rng(seed + 2)
    (out / "rgb").mkdir(parents=True, exist_ok=True)
    (out / "depth").mkdir(exist_ok=True)
    poses = KINDS[kind](frames)
    stamps = START_STAMP + np.arange(frames) / rate_hz
    rgb_lines, depth_lines = ["# color images"], ["# depth maps"]
    for stamp, pose in zip(stamps, poses, strict=True):
        image, depth = scene.render(pose)
        if noise:
            image = np.clip(image + rng.normal(0.0, 2.0, image.shape), 0, 255).astype(np.uint8)
            depth = depth + rng.normal(0.0, 1.0, depth.shape) * 0.0012 * depth**2
        raw = np.clip(np.round(depth * intrinsics.depth_scale), 0, 65535).astype(np.uint16)
        name = f"{stamp:.6f}.png"
        cv2.imwrite(str(out / "rgb" / name), image)
        cv2.imwrite(str(out / "depth" / name), raw)
        rgb_lines.append(f"{stamp:.6f} rgb/{name}")
        depth_lines.append(f"{stamp:.6f} depth/{name}")
    (out / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (out / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    truth = Trajectory(stamps, np.array(poses))
    write_trajectory(out / "groundtruth.txt", truth)
    write_camera(out / "camera.txt", intrinsics)
    return truth
