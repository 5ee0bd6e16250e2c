"""Rigid and similarity transforms as 4 x 4 arrays, quaternions, and trajectory alignment.

Poses are camera-to-world (``T_wc``: a camera-frame point ``p`` sits at ``T_wc @ p`` in the
world), as the TUM format writes them. Alignment is Umeyama's closed form (1991), our own code:
SE(3) for RGB-D (metric), Sim(3) for monocular (up to scale); ATE is the RMSE of the aligned
positions, the figure ``evo_ape --align [--correct_scale]`` reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


def make(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rotation, translation
    return t


def inverse(t: np.ndarray) -> np.ndarray:
    r, p = t[:3, :3], t[:3, 3]
    return make(r.T, -r.T @ p)


def transform(t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4 x 4 transform to (N, 3) points."""
    return points @ t[:3, :3].T + t[:3, 3]


def from_rvec(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    return make(cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))[0], np.asarray(tvec, dtype=np.float64).ravel())


def to_rvec(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return cv2.Rodrigues(t[:3, :3])[0].ravel(), t[:3, 3].copy()


def angle_of(rotation: np.ndarray) -> float:
    """The rotation angle in radians."""
    return float(np.arccos(np.clip((np.trace(rotation) - 1.0) / 2.0, -1.0, 1.0)))


def quat_to_rot(q: np.ndarray) -> np.ndarray:
    """Rotation from a quaternion (qx, qy, qz, qw), as TUM writes them."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rot_to_quat(r: np.ndarray) -> np.ndarray:
    """(qx, qy, qz, qw) with qw >= 0, from a rotation matrix (Shepperd's method)."""
    trace = np.trace(r)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = np.array([(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = np.zeros(4)
        q[i] = 0.25 * s
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
        q[3] = (r[k, j] - r[j, k]) / s
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


@dataclass(frozen=True)
class Alignment:
    rotation: np.ndarray
    translation: np.ndarray
    scale: float

    def apply(self, points: np.ndarray) -> np.ndarray:
        return self.scale * points @ self.rotation.T + self.translation


def umeyama(source: np.ndarray, target: np.ndarray, *, with_scale: bool) -> Alignment:
    """The similarity (or rigid, ``with_scale=False``) transform taking ``source`` onto ``target`` (N, 3)."""
    if len(source) < 3:
        raise ValueError(f"alignment needs at least 3 positions, got {len(source)}")
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    s, t = source - mu_s, target - mu_t
    cov = t.T @ s / len(source)
    u, d, vt = np.linalg.svd(cov)
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2, 2] = -1.0
    rotation = u @ sign @ vt
    scale = float(np.trace(np.diag(d) @ sign) / (s**2).sum(axis=1).mean()) if with_scale else 1.0
    return Alignment(rotation, mu_t - scale * rotation @ mu_s, scale)


def ate_rmse(estimate: np.ndarray, truth: np.ndarray, *, with_scale: bool) -> tuple[float, Alignment]:
    """RMSE in metres of the positions after the best SE(3)/Sim(3) alignment of ``estimate`` to ``truth``."""
    alignment = umeyama(estimate, truth, with_scale=with_scale)
    error = alignment.apply(estimate) - truth
    return float(np.sqrt((error**2).sum(axis=1).mean())), alignment
