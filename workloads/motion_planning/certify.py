"""Proving a path collision-free between its waypoints, not just at sampled poses.

OMPL's motion check samples a segment at a fixed step, so a thin wall or a corner can sit
between two free samples. Here each segment is proven free with clearances (fcl distance):
if no robot point moves more than ``s`` between two poses whose clearances add up to more
than ``s``, every pose between them is free (each point is nearer to one of the two poses
than its clearance). Pieces that cannot be proven are halved down to ``floor``; one still
unproven there counts as a collision, so a path that grazes a wall is repaired, not sent.

The sweep bound is the one the planner's step uses: a robot point at distance at most ``R``
from the body origin moves at most ``|dp| + R * angle`` along a segment (linear position,
slerp rotation at constant angular speed), and proportionally less along part of it.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise
from typing import Any

import numpy as np

from workloads.motion_planning.geometry import _bvh, rotation_angle, slerp
from workloads.motion_planning.problem import Pose, Problem

_MAX_PIECES = 200_000  # per segment: a bound on work, far above what a real path needs


class Certifier:
    """Holds fcl models for clearance queries; built once per problem and process."""

    def __init__(self, problem: Problem) -> None:
        import fcl  # noqa: PLC0415 (a workload extra, as in geometry)

        self._fcl = fcl
        self._problem = problem
        self._robot = fcl.CollisionObject(_bvh(problem.robot), fcl.Transform())
        self._world = fcl.CollisionObject(_bvh(problem.world), fcl.Transform())
        self._request = fcl.DistanceRequest()
        self.radius = problem.robot.radius()
        self.queries = 0

    def clearance(self, position: np.ndarray, quaternion_wxyz: np.ndarray) -> float:
        """Distance from the robot at this pose to the world; 0 when they touch or overlap."""
        self.queries += 1
        lo, hi = self._problem.bounds_min, self._problem.bounds_max
        if not all(lo[i] <= position[i] <= hi[i] for i in range(3)):
            return 0.0
        self._robot.setTransform(self._fcl.Transform(quaternion_wxyz, position))
        return max(0.0, float(self._fcl.distance(self._robot, self._world, self._request, self._fcl.DistanceResult())))

    def segment_is_free(self, a: Pose, b: Pose, *, floor: float) -> bool:
        """True when every pose between a and b is proven collision-free (see module docstring)."""
        p0, p1, q0, q1 = a.position(), b.position(), a.quaternion(), b.quaternion()
        if float(np.dot(q0, q1)) < 0.0:
            q1 = -q1  # the short way round, as slerp goes
        sweep = float(np.linalg.norm(p1 - p0)) + self.radius * rotation_angle(q0, q1)

        def clearance_at(t: float) -> float:
            return self.clearance(p0 + (p1 - p0) * t, slerp(q0, q1, t))

        stack = [(0.0, clearance_at(0.0), 1.0, clearance_at(1.0))]
        pieces = 0
        while stack:
            t0, c0, t1, c1 = stack.pop()
            if c0 <= 0.0 or c1 <= 0.0:
                return False
            length = sweep * (t1 - t0)
            if c0 + c1 > length:
                continue
            pieces += 1
            if length < floor or pieces > _MAX_PIECES:
                return False
            tm = (t0 + t1) / 2
            cm = clearance_at(tm)
            stack += [(t0, c0, tm, cm), (tm, cm, t1, c1)]
        return True

    def first_bad_segment(self, path: Sequence[Pose], *, floor: float) -> int | None:
        """Index i of the first segment path[i] -> path[i+1] not proven free; None when all are."""
        if len(path) == 1:
            return None if self.segment_is_free(path[0], path[0], floor=floor) else 0
        for i, (a, b) in enumerate(pairwise(path)):
            if not self.segment_is_free(a, b, floor=floor):
                return i
        return None


def as_poses(states: Sequence[Any]) -> list[Pose]:
    """OMPL SE(3) states to poses (quaternion x, y, z, w)."""
    return [Pose(s.getX(), s.getY(), s.getZ(), s.rotation().x, s.rotation().y, s.rotation().z, s.rotation().w)
            for s in states]
