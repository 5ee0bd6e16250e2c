"""Turning quality maps into one grasp: pure array code, no torch, no camera."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pick:
    """The best cell of a (k, H, W) quality map: angle index, pixel, its quality and width."""

    angle_index: int
    angle: float
    u: int
    v: int
    quality: float
    width: float


def decode_best(quality: np.ndarray, width: np.ndarray, *, mask: np.ndarray | None = None) -> Pick:
    """Arg-max over angles and pixels; ``mask`` (H, W) marks pixels allowed as grasp centres.

    Angle index ``i`` of ``k`` means the jaws close along ``i * pi / k`` in the image plane,
    measured from the +u axis towards +v. Ties go to the first cell in (angle, v, u) order.
    """
    if quality.ndim != 3 or quality.shape != width.shape:
        raise ValueError(f"quality and width must both be (k, H, W), got {quality.shape} and {width.shape}")
    q = quality
    if mask is not None:
        q = np.where(mask[None, :, :], quality, -np.inf)
    flat = int(np.argmax(q))
    i, v, u = np.unravel_index(flat, q.shape)
    k = quality.shape[0]
    return Pick(
        angle_index=int(i),
        angle=float(i) * math.pi / k,
        u=int(u),
        v=int(v),
        quality=float(quality[i, v, u]),
        width=float(width[i, v, u]),
    )


def local_depths(depth: np.ndarray, *, u: int, v: int, radius: int) -> np.ndarray:
    """Valid (non-zero) depths in the square window of ``radius`` pixels around (u, v)."""
    h, w = depth.shape
    win = depth[max(0, v - radius) : min(h, v + radius + 1), max(0, u - radius) : min(w, u + radius + 1)]
    return win[win > 0]


def tip_depth(
    depth: np.ndarray, *, u: int, v: int, pixel_size: float, grasp_depth: float, open_width: float, clearance: float
) -> float:
    """Where the jaw tips go: ``grasp_depth`` below the surface at (u, v), above the local floor.

    Surface: median of the 3 x 3 window. Floor: the 95th percentile of depth within half the
    open width, the lowest thing the fingers could meet around the object.
    """
    centre = local_depths(depth, u=u, v=v, radius=1)
    around = local_depths(depth, u=u, v=v, radius=max(1, int(round(open_width / 2 / pixel_size))))
    if centre.size == 0:
        raise ValueError(f"no valid depth around pixel ({u}, {v})")
    surface = float(np.median(centre))
    floor = float(np.percentile(around, 95))
    return max(surface, min(surface + grasp_depth, floor - clearance))
