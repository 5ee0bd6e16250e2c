"""Collision checking with python-fcl and pose interpolation, shared by planner and checker.

The path checker does not trust OMPL: it walks the straight SE(3) segments between the
returned poses (linear position, quaternion slerp, as OMPL's SE3 space interpolates) with
its own step, so a test can catch a planner that skipped through a wall.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import pairwise
from typing import Any

import numpy as np

from workloads.motion_planning.problem import Mesh, Pose, Problem

Vector = Sequence[float] | np.ndarray  # OMPL hands over lists, interpolation numpy arrays


def _bvh(mesh: Mesh) -> Any:
    """An fcl.BVHModel of the mesh (typed Any: fcl ships no stubs)."""
    import fcl  # noqa: PLC0415 (a workload extra: loaded when a problem is checked, not on import)

    model = fcl.BVHModel()
    model.beginModel(len(mesh.vertices), len(mesh.faces))
    model.addSubModel(np.ascontiguousarray(mesh.vertices, dtype=float),
                      np.ascontiguousarray(mesh.faces, dtype=np.int32))
    model.endModel()
    return model


class CollisionChecker:
    """Holds fcl models of one problem; ``is_free`` answers for a robot pose in world frame."""

    def __init__(self, problem: Problem) -> None:
        import fcl  # noqa: PLC0415 (as in _bvh)

        self._fcl = fcl
        self._problem = problem
        self._robot = fcl.CollisionObject(_bvh(problem.robot), fcl.Transform())
        self._world = fcl.CollisionObject(_bvh(problem.world), fcl.Transform())
        self._request = fcl.CollisionRequest()
        self.checks = 0

    def is_free(self, position: Vector, quaternion_wxyz: Vector) -> bool:
        self.checks += 1
        self._robot.setTransform(self._fcl.Transform(np.asarray(quaternion_wxyz, dtype=float),
                                                     np.asarray(position, dtype=float)))
        result = self._fcl.CollisionResult()
        return self._fcl.collide(self._robot, self._world, self._request, result) == 0

    def in_bounds(self, position: Vector) -> bool:
        lo, hi = self._problem.bounds_min, self._problem.bounds_max
        return all(lo[i] <= position[i] <= hi[i] for i in range(3))

    def pose_is_free(self, pose: Pose) -> bool:
        return self.in_bounds(pose.position()) and self.is_free(pose.position(), pose.quaternion())


def slerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    """Shortest-arc spherical interpolation of (w, x, y, z) unit quaternions."""
    dot = float(np.dot(q0, q1))
    if dot < 0.0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + t * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = math.acos(min(1.0, dot))
    return (math.sin((1 - t) * theta) * q0 + math.sin(t * theta) * q1) / math.sin(theta)


def rotation_angle(q0: np.ndarray, q1: np.ndarray) -> float:
    """Angle of the rotation taking q0 to q1, in radians."""
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(q0, q1)))))


def interpolate(a: Pose, b: Pose, *, max_step: float, radius: float,
                min_steps: int = 1) -> list[tuple[np.ndarray, np.ndarray]]:
    """Poses from a to b (both included) such that no robot point moves more than ``max_step``,
    in at least ``min_steps`` steps."""
    p0, p1, q0, q1 = a.position(), b.position(), a.quaternion(), b.quaternion()
    sweep = float(np.linalg.norm(p1 - p0)) + radius * rotation_angle(q0, q1)
    n = max(min_steps, math.ceil(sweep / max_step))
    return [(p0 + (p1 - p0) * (i / n), slerp(q0, q1, i / n)) for i in range(n + 1)]


def path_is_collision_free(problem: Problem, path: Sequence[Pose], *, resolution: float) -> bool:
    """True when every pose on the interpolated path is inside the bounds and collision-free.

    ``resolution`` bounds how far any point of the robot moves between two checks, in world units.
    """
    if not path:
        return False
    checker = CollisionChecker(problem)
    radius = problem.robot.radius()
    segments = list(pairwise(path)) if len(path) > 1 else [(path[0], path[0])]
    for a, b in segments:
        for position, quat in interpolate(a, b, max_step=resolution, radius=radius):
            if not (checker.in_bounds(position) and checker.is_free(position, quat)):
                return False
    return True
