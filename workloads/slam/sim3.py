"""Similarity transforms (Sim(3)) and a small pose-graph optimiser over them.

Why Sim(3): a monocular map's scale is unobservable, so it drifts as the camera travels; around
a big loop the far side of the map ends up smaller than the near side, and the trajectory's shape
collapses along an axis. When a loop closes, the matched map points of the two keyframes give
the similarity between them (rotation, translation *and* scale, :func:`from_points`), and a pose
graph whose nodes are keyframe similarities (ORB-SLAM's essential graph, Strasdat et al. 2010)
spreads that scale correction along the loop instead of only closing the position gap.

A similarity is a 4 x 4 array ``[[s R, t], [0, 1]]`` (camera-to-world, as the poses in
:mod:`workloads.slam.geometry`); an SE(3) pose is one with ``s = 1``. The optimiser is our own
Levenberg-Marquardt with numerical Jacobians on 7-DoF increments (rotation vector, translation,
log scale), dense, because a keyframe graph has at most a few hundred nodes and numpy is all the
venv provides (no scipy).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workloads.slam.geometry import umeyama
from workloads.slam.mapdata import Map

MIN_SCALE_PAIRS = 15  # a loop's scale is read from at least this many points both ends have


def make(rotation: np.ndarray, translation: np.ndarray, scale: float) -> np.ndarray:
    s = np.eye(4)
    s[:3, :3] = scale * rotation
    s[:3, 3] = translation
    return s


def scale_of(s: np.ndarray) -> float:
    return float(np.cbrt(np.linalg.det(s[:3, :3])))


def inverse(s: np.ndarray) -> np.ndarray:
    k = scale_of(s)
    rotation = s[:3, :3] / k
    return make(rotation.T, -(rotation.T @ s[:3, 3]) / k, 1.0 / k)


def exp(delta: np.ndarray) -> np.ndarray:
    """A small similarity from (rotation vector, translation, log scale); exp(0) is the identity."""
    rotation, _ = cv2.Rodrigues(np.asarray(delta[:3], np.float64).reshape(3, 1))
    return make(rotation, delta[3:6], float(np.exp(delta[6])))


def log(s: np.ndarray) -> np.ndarray:
    """The 7-vector :func:`exp` inverts (exactly in rotation and scale; translation as is)."""
    k = scale_of(s)
    rvec, _ = cv2.Rodrigues(s[:3, :3] / k)
    return np.concatenate([rvec.ravel(), s[:3, 3], [np.log(k)]])


def from_points(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The similarity taking ``source`` (N, 3) onto ``target`` (N, 3): a loop's Sim(3) from the
    matched map points of two keyframes, each in its own keyframe's camera frame."""
    a = umeyama(source, target, with_scale=True)
    return make(a.rotation, a.translation, a.scale)


def from_loop(query_from_match: np.ndarray, in_query: np.ndarray, in_match: np.ndarray) -> tuple[np.ndarray, int]:
    """A loop's measured similarity ``inverse(S_match) @ S_query`` (the query keyframe's frame in the
    matched one's, scale = matched-map units per query-map unit) and how many points gave its scale.

    ``query_from_match`` is the rigid pose PnP found from the matched keyframe's points (in the
    matched keyframe's units) and the query's pixels; ``in_match`` holds the PnP inliers' points in
    the matched keyframe's frame and ``in_query`` the same features' own map points in the query's
    frame (NaN where the query has none). PnP already fixes rotation and direction, so only the
    scale is left: each pair's ``|in_query| / |query_from_match @ in_match|`` (distances along the
    same ray from the query camera) is one reading, and their median is robust to the few wrong
    matches a loop's inliers still hold. A least-squares similarity over all the pairs (Umeyama,
    what was tried first) lets those few pull rotation and translation away from PnP's answer.
    Fewer than ``MIN_SCALE_PAIRS`` readings: scale 1, the rigid answer."""
    predicted = in_match @ query_from_match[:3, :3].T + query_from_match[:3, 3]
    own = np.linalg.norm(in_query, axis=1)
    via = np.linalg.norm(predicted, axis=1)
    ok = np.isfinite(own) & (own > 0) & (via > 0) & (predicted[:, 2] > 0) & np.nan_to_num(in_query[:, 2] > 0)
    rotation, translation = query_from_match[:3, :3], query_from_match[:3, 3]
    scale = float(np.median(own[ok] / via[ok])) if ok.sum() >= MIN_SCALE_PAIRS else 1.0
    # S_qm takes matched-frame points (matched units) to the query's frame (query units)
    query_sim = make(rotation, scale * translation, scale)
    return inverse(query_sim), int(ok.sum())


def correct_map(m: Map, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Carry a Sim(3) pose graph's answer into the map's scale, and return the rigid poses left.

    ``before`` are the job's keyframe poses, ``after`` their corrected similarities (keyframe ids
    ``0 .. K-1``). Each map point, and each frame's pose relative to its keyframe, is scaled about
    its reference keyframe's old centre by that keyframe's scale (keyframes made while the graph ran,
    and their points, by the newest one's in the job, as the rigid correction moves them); what is
    left is a rigid move per keyframe, which the caller applies as it applies an SE(3) graph's."""
    last = len(before) - 1
    scales = np.array([scale_of(s) for s in after])
    centres = before[:, :3, 3]
    pts = m.points
    refs = np.minimum(pts.ref[:pts.count], last)
    pts.pos[:pts.count] = centres[refs] + scales[refs, None] * (pts.pos[:pts.count] - centres[refs])
    for kf in m.keyframes[last + 1:]:
        kf.pose[:3, 3] = centres[last] + scales[last] * (kf.pose[:3, 3] - centres[last])
    for record in m.frames:
        if record.ref >= 0:
            record.relative = record.relative.copy()
            record.relative[:3, 3] *= scales[min(record.ref, last)]
    rigid = after.copy()
    rigid[:, :3, :3] /= scales[:, None, None]
    return rigid


def correct_point(old_pose: np.ndarray, new_pose: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Map points (N, 3) seen from a keyframe whose pose moved from ``old_pose`` to ``new_pose``:
    expressed in that keyframe's frame by the old pose, put back in the world by the new one."""
    moved = new_pose @ inverse(old_pose)
    return xyz @ moved[:3, :3].T + moved[:3, 3]


@dataclass(frozen=True)
class Edge:
    """A measured ``inverse(S_i) @ S_j``: odometry/covisibility (scale 1) or a loop (any scale)."""
    i: int
    j: int
    measured: np.ndarray
    weight: float = 1.0


def residual(poses: list[np.ndarray], edge: Edge) -> np.ndarray:
    error = inverse(edge.measured) @ inverse(poses[edge.i]) @ poses[edge.j]
    return np.sqrt(edge.weight) * log(error)


def cost(poses: list[np.ndarray], edges: list[Edge]) -> float:
    return float(sum(np.sum(residual(poses, e) ** 2) for e in edges))


def optimise(poses: list[np.ndarray], edges: list[Edge], *, fixed: frozenset[int] = frozenset({0}),
             iterations: int = 20, step: float = 1e-6) -> list[np.ndarray]:
    """The node similarities that best agree with ``edges``, starting from ``poses``; the nodes
    in ``fixed`` stay put (a pose graph is free up to one similarity: fixing one node pins it)."""
    poses = [p.copy() for p in poses]
    free = [n for n in range(len(poses)) if n not in fixed]
    column = {n: 7 * k for k, n in enumerate(free)}
    size = 7 * len(free)
    if size == 0 or not edges:
        return poses
    damping, current = 1e-4, cost(poses, edges)
    for _ in range(iterations):
        h, g = np.zeros((size, size)), np.zeros(size)
        for e in edges:
            r = residual(poses, e)
            blocks: list[tuple[int, np.ndarray]] = []
            for n in (e.i, e.j):
                if n not in column:
                    continue
                jac = np.zeros((7, 7))
                base = poses[n]
                for d in range(7):
                    delta = np.zeros(7)
                    delta[d] = step
                    poses[n] = base @ exp(delta)
                    jac[:, d] = (residual(poses, e) - r) / step
                poses[n] = base
                blocks.append((column[n], jac))
            for ca, ja in blocks:
                g[ca:ca + 7] += ja.T @ r
                for cb, jb in blocks:
                    h[ca:ca + 7, cb:cb + 7] += ja.T @ jb
        improved = False
        while damping < 1e8:
            dx = np.linalg.solve(h + damping * np.diag(np.diag(h) + 1e-9), -g)
            trial = [p.copy() for p in poses]
            for n, c in column.items():
                trial[n] = poses[n] @ exp(dx[c:c + 7])
            trial_cost = cost(trial, edges)
            if trial_cost < current:
                poses, current, improved = trial, trial_cost, True
                damping = max(damping / 10, 1e-9)
                break
            damping *= 10
        if not improved or float(np.abs(dx).max()) < 1e-10:
            break
    return poses
