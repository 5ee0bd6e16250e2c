"""Analytic parallel-jaw grasp quality, computed from the scene's exact geometry.

A candidate is a top-down grasp: centre (x, y) in the camera frame, the jaws closing along
``angle`` in the image plane, descending along the optical axis. Its nominal quality is

    feasible * friction_margin * depth_fraction * collision_free

- the jaw tips stop ``grasp_depth`` below the surface seen at the centre, but at least
  ``table_clearance`` above the table, and no lower than the widest section of a sphere or
  lying cylinder (below it the surface faces down and the jaws would slide off);
- feasible: the closing line, in the plane of the jaw tips, crosses the target's exact cross
  section (rectangle, circle, or the rectangle a lying cylinder cuts) around the centre; both
  contacts lie inside the open jaws; the width is at least ``min_width``; the target is not a
  bin wall; the tips are at least ``min_depth`` below the surface;
- friction_margin: with ``alpha`` the larger angle between the closing direction and the
  inward 3-D surface normal at the two contacts and ``beta = atan(friction)`` the half-angle
  of the friction cone, ``(cos alpha - cos beta) / (1 - cos beta)`` clipped at 0: above 0 iff
  both contacts are inside their friction cones (antipodal), 1 for a face-on grasp;
- depth_fraction: tip depth below the surface over ``grasp_depth`` (a shallow grip scores less);
- collision_free: each finger, from its open position to its contact, sampled 8 x 3 across its
  face in the plane of the tips, must see nothing of another object above that plane in the
  exact depth image (a finger cannot go where the camera sees something higher), and must
  stay inside the image (space the camera does not see is not assumed free).

The *robust* quality averages the nominal one over grasp centres within ``robust_radius``
(a 5 x 5 grid), the position-uncertainty part of Dex-Net's robust metric: edges score low.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from workloads.grasp_planning.camera import Intrinsics
from workloads.grasp_planning.scene import Primitive, Render, Scene, to_local

Contacts = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Gripper:
    open_width: float = 0.085
    finger_thickness: float = 0.01
    finger_breadth: float = 0.02
    grasp_depth: float = 0.02
    min_depth: float = 0.008
    table_clearance: float = 0.004
    friction: float = 0.5
    min_width: float = 0.005
    robust_radius: float = 0.005


def angles(k: int) -> np.ndarray:
    """The k jaw-closing directions the network scores: 0, pi/k, ..., (k-1) pi/k."""
    return np.arange(k) * math.pi / k


def _slab2d(px: np.ndarray, py: np.ndarray, dx: np.ndarray, dy: np.ndarray, hx: float, hy: np.ndarray | float) -> tuple:
    """Entry/exit of the line p + s d through the box |x|<=hx, |y|<=hy, and which face."""
    dx = np.where(np.abs(dx) < 1e-12, 1e-12, dx)
    dy = np.where(np.abs(dy) < 1e-12, 1e-12, dy)
    ax1, ax2 = (-hx - px) / dx, (hx - px) / dx
    ay1, ay2 = (-hy - py) / dy, (hy - py) / dy
    xin, xout = np.minimum(ax1, ax2), np.maximum(ax1, ax2)
    yin, yout = np.minimum(ay1, ay2), np.maximum(ay1, ay2)
    s1, s2 = np.maximum(xin, yin), np.minimum(xout, yout)
    miss = s2 < s1
    return np.where(miss, np.nan, s1), np.where(miss, np.nan, s2), xin >= yin, xout <= yout


def _box(p: Primitive, x: np.ndarray, y: np.ndarray, ax: np.ndarray, ay: np.ndarray, zg: np.ndarray) -> Contacts:
    px, py = to_local(p, x - p.center[0], y - p.center[1])
    dx, dy = to_local(p, ax, ay)
    s1, s2, in_x, out_x = _slab2d(px, py, dx, dy, p.size[0], p.size[1])
    return s1, s2, np.where(in_x, np.abs(dx), np.abs(dy)), np.where(out_x, np.abs(dx), np.abs(dy))


def _circle(
    px: np.ndarray, py: np.ndarray, ax: np.ndarray, ay: np.ndarray, rho: np.ndarray | float,
    r_normal: np.ndarray | float,
) -> Contacts:
    """Chord of a circle of radius rho; cosines against 3-D normals of a solid of radius r_normal."""
    b = px * ax + py * ay
    disc = b * b - (px * px + py * py - rho * rho)
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    s1, s2 = -b - root, -b + root
    c1 = np.abs((px + s1 * ax) * ax + (py + s1 * ay) * ay) / r_normal
    c2 = np.abs((px + s2 * ax) * ax + (py + s2 * ay) * ay) / r_normal
    return s1, s2, c1, c2


def _cylinder(p: Primitive, x: np.ndarray, y: np.ndarray, ax: np.ndarray, ay: np.ndarray, zg: np.ndarray) -> Contacts:
    return _circle(x - p.center[0], y - p.center[1], ax, ay, p.size[0], p.size[0])


def _lying_cylinder(
    p: Primitive, x: np.ndarray, y: np.ndarray, ax: np.ndarray, ay: np.ndarray, zg: np.ndarray
) -> Contacts:
    r = p.size[0]
    hz = zg - p.center[2]
    half_w = np.sqrt(np.where(np.abs(hz) < r, r * r - hz * hz, np.nan))
    px, py = to_local(p, x - p.center[0], y - p.center[1])
    dx, dy = to_local(p, ax, ay)
    s1, s2, in_x, out_x = _slab2d(px, py, dx, dy, p.size[1], half_w)
    side = np.abs(dy) * half_w / r
    return s1, s2, np.where(in_x, np.abs(dx), side), np.where(out_x, np.abs(dx), side)


def _sphere(p: Primitive, x: np.ndarray, y: np.ndarray, ax: np.ndarray, ay: np.ndarray, zg: np.ndarray) -> Contacts:
    r = p.size[0]
    hz = zg - p.center[2]
    rho = np.sqrt(np.where(np.abs(hz) < r, r * r - hz * hz, np.nan))
    return _circle(x - p.center[0], y - p.center[1], ax, ay, rho, r)


CONTACTS: dict[str, Callable[..., Contacts]] = {
    "box": _box,
    "cylinder": _cylinder,
    "lying_cylinder": _lying_cylinder,
    "sphere": _sphere,
}
ROUND = ("lying_cylinder", "sphere")


def _collides(
    render: Render, intr: Intrinsics, g: Gripper, x: np.ndarray, y: np.ndarray, ax: np.ndarray, ay: np.ndarray,
    zg: np.ndarray, obj: np.ndarray, s_from: np.ndarray, s_to: np.ndarray,
) -> np.ndarray:
    """Whether a finger sweeping from ``s_from`` to ``s_to`` meets anything above its tips."""
    h, w = render.depth.shape
    t = np.linspace(0.0, 1.0, 8)[None, :, None]
    b = (np.array([-0.5, 0.0, 0.5]) * g.finger_breadth)[None, None, :]
    s = s_from[:, None, None] + (s_to - s_from)[:, None, None] * t
    px = x[:, None, None] + s * ax[:, None, None] - b * ay[:, None, None]
    py = y[:, None, None] + s * ay[:, None, None] + b * ax[:, None, None]
    z = zg[:, None, None]
    u = np.rint(intr.fx * px / z + intr.cx).astype(np.int64)
    v = np.rint(intr.fy * py / z + intr.cy).astype(np.int64)
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    uc, vc = u.clip(0, w - 1), v.clip(0, h - 1)
    blocked = (render.depth[vc, uc] < z - 0.002) & (render.ids[vc, uc] != obj[:, None, None])
    blocked |= ~inside
    return blocked.reshape(len(x), -1).any(axis=1)


def nominal_quality(
    scene: Scene, render: Render, intr: Intrinsics, g: Gripper, *,
    x: np.ndarray, y: np.ndarray, zs: np.ndarray, obj: np.ndarray, angle: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Nominal quality and jaw width for candidates (all arrays of one shape, flat)."""
    n = len(x)
    quality, width = np.zeros(n), np.zeros(n)
    ax, ay = np.cos(angle), np.sin(angle)
    zg = np.minimum(zs + g.grasp_depth, scene.table_z - g.table_clearance)
    s1, s2 = np.full(n, np.nan), np.full(n, np.nan)
    c = np.zeros((2, n))
    for i, prim in enumerate(scene.objects):
        sel = np.flatnonzero(obj == i)
        if sel.size == 0 or not prim.graspable:
            continue
        if prim.kind in ROUND:
            zg[sel] = np.minimum(zg[sel], prim.center[2])
        a, b, c1, c2 = CONTACTS[prim.kind](prim, x[sel], y[sel], ax[sel], ay[sel], zg[sel])
        s1[sel], s2[sel], c[0, sel], c[1, sel] = a, b, c1, c2
    half = g.open_width / 2
    with np.errstate(invalid="ignore"):
        ok = (zg - zs >= g.min_depth) & (s1 <= 0) & (s2 >= 0) & (s1 >= -half) & (s2 <= half)
        ok &= s2 - s1 >= g.min_width
    cos_max = math.cos(math.atan(g.friction))
    friction = np.clip((np.minimum(c[0], c[1]) - cos_max) / (1.0 - cos_max), 0.0, 1.0)
    ok &= friction > 0
    idx = np.flatnonzero(ok)
    if idx.size:
        args = (render, intr, g, x[idx], y[idx], ax[idx], ay[idx], zg[idx], obj[idx])
        outer = half + g.finger_thickness
        hit = _collides(*args, np.full(idx.size, -outer), s1[idx]) | _collides(*args, np.full(idx.size, outer), s2[idx])
        depth_frac = np.clip((zg[idx] - zs[idx]) / g.grasp_depth, 0.0, 1.0)
        quality[idx] = friction[idx] * depth_frac * (~hit)
        width[idx] = s2[idx] - s1[idx]
    return quality, width


def _box_mean(a: np.ndarray, r: int) -> np.ndarray:
    """Mean over a (2r+1)^2 window along the last two axes, edges padded with zeros."""
    if r <= 0:
        return a
    p = np.pad(a, [(0, 0)] * (a.ndim - 2) + [(r + 1, r), (r + 1, r)])
    c = p.cumsum(-1).cumsum(-2)
    k = 2 * r + 1
    s = c[..., k:, k:] - c[..., :-k, k:] - c[..., k:, :-k] + c[..., :-k, :-k]
    return s / (k * k)


def quality_map(
    scene: Scene, render: Render, intr: Intrinsics, g: Gripper, *, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """Dense robust quality and nominal width, shape (k, H, W), for grasps centred at every pixel."""
    h, w = render.depth.shape
    graspable = np.array([o.graspable for o in scene.objects] + [False])
    vv, uu = np.nonzero(graspable[render.ids])
    zs = render.depth[vv, uu].astype(np.float64)
    x, y, _ = intr.deproject(uu.astype(np.float64), vv.astype(np.float64), zs)
    q = np.zeros((k, h, w))
    wid = np.zeros((k, h, w))
    for j, a in enumerate(angles(k)):
        qj, wj = nominal_quality(
            scene, render, intr, g, x=x, y=y, zs=zs, obj=render.ids[vv, uu], angle=np.full(len(x), a)
        )
        q[j, vv, uu], wid[j, vv, uu] = qj, wj
    pixel = float(np.median(render.depth)) / intr.fx
    return _box_mean(q, int(round(g.robust_radius / pixel))).astype(np.float32), wid.astype(np.float32)


def grasp_quality(
    scene: Scene, render: Render, intr: Intrinsics, g: Gripper, *, u: float, v: float, angle: float
) -> float:
    """Robust quality of one grasp at pixel (u, v): the mean over a 5 x 5 grid of centres."""
    h, w = render.depth.shape
    ui, vi = int(np.clip(round(u), 0, w - 1)), int(np.clip(round(v), 0, h - 1))
    z0 = float(render.depth[vi, ui])
    x0, y0, _ = intr.deproject(u, v, z0)
    off = np.linspace(-g.robust_radius, g.robust_radius, 5)
    ox, oy = (a.ravel() for a in np.meshgrid(off, off))
    x, y = x0 + ox, y0 + oy
    pu = np.rint(intr.fx * x / z0 + intr.cx).astype(np.int64).clip(0, w - 1)
    pv = np.rint(intr.fy * y / z0 + intr.cy).astype(np.int64).clip(0, h - 1)
    obj = render.ids[pv, pu]
    zs = render.depth[pv, pu].astype(np.float64)
    q, _ = nominal_quality(scene, render, intr, g, x=x, y=y, zs=zs, obj=obj, angle=np.full(len(x), angle))
    return float(q.mean())
