"""Pinhole camera maths and the grasp pose: pure functions a test can check by hand.

Frames follow ROS's optical convention (REP 103): x right, y down the image, z along the
optical axis. A grasp's pose is given in that frame: its z axis is the approach direction
(the camera's z, straight into the scene) and its x axis the direction the jaws close along.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    import numpy as np

# One pixel (floats) or many at once (numpy arrays, elementwise): the same arithmetic serves both.
Coord = TypeVar("Coord", float, "np.ndarray")


@dataclass(frozen=True)
class Intrinsics:
    """Focal lengths and principal point in pixels (sensor_msgs/CameraInfo ``K``)."""

    fx: float
    fy: float
    cx: float
    cy: float

    def deproject(self, u: Coord, v: Coord, z: Coord) -> tuple[Coord, Coord, Coord]:
        """The point at depth ``z`` seen at pixel (u, v); arrays give one point per element."""
        return ((u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z)

    def project(self, x: float, y: float, z: float) -> tuple[float, float]:
        return (self.fx * x / z + self.cx, self.fy * y / z + self.cy)

    def scaled(self, factor: float) -> Intrinsics:
        """Intrinsics of the same camera after resizing its image by ``1 / factor``.

        Pixel centres map as ``u' = (u + 0.5) / factor - 0.5``, the convention of
        ``torch.nn.functional.interpolate(..., align_corners=False)``.
        """
        return Intrinsics(
            fx=self.fx / factor,
            fy=self.fy / factor,
            cx=(self.cx + 0.5) / factor - 0.5,
            cy=(self.cy + 0.5) / factor - 0.5,
        )


@dataclass(frozen=True)
class Pose:
    """Position in metres and orientation as a unit quaternion (x, y, z, w), as in ROS."""

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]


def approach_quaternion(angle: float) -> tuple[float, float, float, float]:
    """Orientation of a top-down grasp whose jaws close along ``angle`` in the image plane.

    The gripper frame is the camera frame turned by ``angle`` about the optical axis, so the
    quaternion is a pure z rotation: (0, 0, sin(angle/2), cos(angle/2)).
    """
    return (0.0, 0.0, math.sin(angle / 2.0), math.cos(angle / 2.0))


def grasp_pose(intr: Intrinsics, *, u: float, v: float, depth: float, angle: float) -> Pose:
    """Pose of the grasp centred at pixel (u, v) with its jaw tips at ``depth``."""
    return Pose(position=intr.deproject(u, v, depth), orientation=approach_quaternion(angle))


def to_original_pixel(u: float, v: float, factor: float) -> tuple[float, float]:
    """Inverse of the resize in :meth:`Intrinsics.scaled`: a resized pixel back to the input."""
    return ((u + 0.5) * factor - 0.5, (v + 0.5) * factor - 0.5)
