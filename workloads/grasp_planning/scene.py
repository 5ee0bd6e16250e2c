"""Synthetic bin scenes: primitives on a table, exact depth by ray casting, a depth-sensor model.

Everything lives in the camera's optical frame (x right, y down the image, z out along the
optical axis), with the camera looking straight down at the table: the table is the plane
``z = table_z`` and "up" is ``-z``. Keeping one frame means the renderer, the analytic grasp
quality and the pose math never disagree about a sign.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from workloads.grasp_planning.camera import Intrinsics

KINDS = ("box", "cylinder", "lying_cylinder", "sphere")


@dataclass(frozen=True)
class Primitive:
    """One solid resting on the table.

    ``size`` by kind: box (half x, half y, half z); cylinder, upright (radius, half height, 0);
    lying_cylinder, axis along its local x (radius, half length, 0); sphere (radius, 0, 0).
    ``center`` is the solid's centre, ``yaw`` its rotation about the optical axis.
    """

    kind: str
    center: tuple[float, float, float]
    yaw: float
    size: tuple[float, float, float]
    graspable: bool = True


@dataclass(frozen=True)
class Scene:
    table_z: float
    objects: tuple[Primitive, ...]


@dataclass(frozen=True)
class Render:
    """Exact depth (metres) and the index of the object seen at each pixel (-1: table)."""

    depth: np.ndarray
    ids: np.ndarray


def rays(intr: Intrinsics, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel ray directions with unit z, so a hit's ray parameter *is* its depth."""
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    return (u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy


def to_local(prim: Primitive, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate camera-frame xy vectors into the primitive's yawed frame."""
    c, s = math.cos(prim.yaw), math.sin(prim.yaw)
    return c * x + s * y, -s * x + c * y


def _safe(d: np.ndarray) -> np.ndarray:
    return np.where(np.abs(d) < 1e-12, 1e-12, d)


def _hit_box(p: Primitive, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    ox, oy = to_local(p, np.array(-p.center[0]), np.array(-p.center[1]))
    lx, ly = to_local(p, dx, dy)
    tmin = np.full(dx.shape, -np.inf)
    tmax = np.full(dx.shape, np.inf)
    for o, d, half in ((ox, lx, p.size[0]), (oy, ly, p.size[1]), (-p.center[2], np.ones_like(dx), p.size[2])):
        d = _safe(d)
        t1, t2 = (-half - o) / d, (half - o) / d
        tmin = np.maximum(tmin, np.minimum(t1, t2))
        tmax = np.minimum(tmax, np.maximum(t1, t2))
    return np.where((tmax >= tmin) & (tmin > 0), tmin, np.inf)


def _circle_entry(ox: np.ndarray, oy: np.ndarray, dx: np.ndarray, dy: np.ndarray, r: float) -> np.ndarray:
    a = _safe(dx * dx + dy * dy)
    b = 2 * (ox * dx + oy * dy)
    c = ox * ox + oy * oy - r * r
    disc = b * b - 4 * a * c
    t = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a)
    return np.where(disc >= 0, t, np.inf)


def _hit_cylinder(p: Primitive, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    r, h = p.size[0], p.size[1]
    ox, oy, oz = -p.center[0], -p.center[1], -p.center[2]
    t_side = _circle_entry(np.array(ox), np.array(oy), dx, dy, r)
    z_side = oz + t_side
    t_side = np.where((z_side >= -h) & (z_side <= h), t_side, np.inf)
    t_cap = -h - oz
    on_cap = (ox + t_cap * dx) ** 2 + (oy + t_cap * dy) ** 2 <= r * r
    return np.minimum(t_side, np.where(on_cap, t_cap, np.inf))


def _hit_lying_cylinder(p: Primitive, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    r, half = p.size[0], p.size[1]
    ox, oy = to_local(p, np.array(-p.center[0]), np.array(-p.center[1]))
    oz = -p.center[2]
    lx, ly = to_local(p, dx, dy)
    t_side = _circle_entry(oy, np.array(oz), ly, np.ones_like(ly), r)
    t_side = np.where(np.abs(ox + t_side * lx) <= half, t_side, np.inf)
    best = t_side
    sx = _safe(lx)
    for end in (-half, half):
        t = (end - ox) / sx
        inside = (oy + t * ly) ** 2 + (oz + t) ** 2 <= r * r
        best = np.minimum(best, np.where(inside & (t > 0), t, np.inf))
    return best


def _hit_sphere(p: Primitive, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    r = p.size[0]
    ox, oy, oz = -p.center[0], -p.center[1], -p.center[2]
    a = dx * dx + dy * dy + 1
    b = 2 * (ox * dx + oy * dy + oz)
    c = ox * ox + oy * oy + oz * oz - r * r
    disc = b * b - 4 * a * c
    return np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)


RAY_CASTERS: dict[str, Callable[[Primitive, np.ndarray, np.ndarray], np.ndarray]] = {
    "box": _hit_box,
    "cylinder": _hit_cylinder,
    "lying_cylinder": _hit_lying_cylinder,
    "sphere": _hit_sphere,
}


def render(scene: Scene, intr: Intrinsics, *, height: int, width: int) -> Render:
    """Exact depth image of the scene, first hit per pixel."""
    dx, dy = rays(intr, height, width)
    depth = np.full((height, width), scene.table_z)
    ids = np.full((height, width), -1, dtype=np.int32)
    for i, prim in enumerate(scene.objects):
        t = RAY_CASTERS[prim.kind](prim, dx, dy)
        closer = t < depth
        depth = np.where(closer, t, depth)
        ids[closer] = i
    return Render(depth=depth.astype(np.float32), ids=ids)


def footprint_radius(p: Primitive) -> float:
    """Radius of a circle around the centre that holds the object's footprint (for placement)."""
    if p.kind == "box":
        return math.hypot(p.size[0], p.size[1])
    if p.kind == "lying_cylinder":
        return math.hypot(p.size[0], p.size[1])
    return p.size[0]


def _random_object(rng: np.random.Generator, table_z: float, x: float, y: float) -> Primitive:
    kind = KINDS[rng.choice(4, p=[0.4, 0.25, 0.2, 0.15])]
    yaw = float(rng.uniform(0, math.pi))
    if kind == "box":
        a, b = rng.uniform(0.01, 0.06, size=2)
        c = rng.uniform(0.01, 0.05)
        return Primitive("box", (x, y, table_z - c), yaw, (float(a), float(b), float(c)))
    if kind == "cylinder":
        r, h = rng.uniform(0.012, 0.05), rng.uniform(0.015, 0.06)
        return Primitive("cylinder", (x, y, table_z - h), yaw, (float(r), float(h), 0.0))
    if kind == "lying_cylinder":
        r, half = rng.uniform(0.012, 0.04), rng.uniform(0.03, 0.08)
        return Primitive("lying_cylinder", (x, y, table_z - r), yaw, (float(r), float(half), 0.0))
    r = rng.uniform(0.018, 0.045)
    return Primitive("sphere", (x, y, table_z - r), 0.0, (float(r), 0.0, 0.0))


def sample_scene(
    rng: np.random.Generator,
    *,
    table_z: float,
    center: tuple[float, float] = (0.0, 0.0),
    bin_half: tuple[float, float] = (0.16, 0.13),
    n_objects: int = 6,
) -> Scene:
    """A bin (four thin walls, not graspable) with non-overlapping objects inside it."""
    wall_h, wall_t = float(rng.uniform(0.04, 0.09)), 0.008
    bx, by = bin_half
    cx, cy = center
    z = table_z - wall_h / 2
    walls = (
        Primitive("box", (cx - bx - wall_t, cy, z), 0.0, (wall_t, by + 2 * wall_t, wall_h / 2), False),
        Primitive("box", (cx + bx + wall_t, cy, z), 0.0, (wall_t, by + 2 * wall_t, wall_h / 2), False),
        Primitive("box", (cx, cy - by - wall_t, z), 0.0, (bx, wall_t, wall_h / 2), False),
        Primitive("box", (cx, cy + by + wall_t, z), 0.0, (bx, wall_t, wall_h / 2), False),
    )
    placed: list[Primitive] = []
    for _ in range(n_objects * 20):
        if len(placed) == n_objects:
            break
        x, y = cx + rng.uniform(-bx, bx), cy + rng.uniform(-by, by)
        obj = _random_object(rng, table_z, float(x), float(y))
        rad = footprint_radius(obj)
        if abs(x - cx) + rad > bx or abs(y - cy) + rad > by:
            continue
        if all(math.hypot(x - o.center[0], y - o.center[1]) > rad + footprint_radius(o) + 0.005 for o in placed):
            placed.append(obj)
    return Scene(table_z=table_z, objects=walls + tuple(placed))


def sense(depth: np.ndarray, rng: np.random.Generator, *, dropout: float = 0.005) -> np.ndarray:
    """What a structured-light sensor reports for an exact depth image.

    Per image a multiplicative gamma scale (shape 1000, as Dex-Net 2.0 trains with); smooth
    correlated error (a coarse Gaussian grid, bilinearly upsampled); per-pixel axial noise
    growing with depth (Nguyen et al. 2012 Kinect model, 1.2 mm + 1.9 mm (z - 0.4)^2); holes
    (value 0) at depth edges and at random; quantised to whole millimetres like 16UC1.
    """
    h, w = depth.shape
    out = depth.astype(np.float64) * rng.gamma(1000.0, 1.0 / 1000.0)
    gh, gw = max(2, h // 16), max(2, w // 16)
    coarse = rng.normal(0.0, 0.0015, size=(gh, gw))
    gy = np.linspace(0, gh - 1, h)
    gx = np.linspace(0, gw - 1, w)
    y0, x0 = np.floor(gy).astype(int).clip(0, gh - 2), np.floor(gx).astype(int).clip(0, gw - 2)
    fy, fx = (gy - y0)[:, None], (gx - x0)[None, :]
    smooth = (
        coarse[y0][:, x0] * (1 - fy) * (1 - fx)
        + coarse[y0 + 1][:, x0] * fy * (1 - fx)
        + coarse[y0][:, x0 + 1] * (1 - fy) * fx
        + coarse[y0 + 1][:, x0 + 1] * fy * fx
    )
    sigma = 0.0012 + 0.0019 * (out - 0.4) ** 2
    out = out + smooth + rng.normal(size=out.shape) * sigma
    gy_, gx_ = np.gradient(depth.astype(np.float64))
    edge = np.hypot(gx_, gy_) > 0.01
    holes = (edge & (rng.random(out.shape) < 0.5)) | (rng.random(out.shape) < dropout)
    out = np.round(out * 1000.0) / 1000.0
    out[holes] = 0.0
    return out.astype(np.float32)
