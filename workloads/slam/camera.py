"""The pinhole camera of a sequence: intrinsics, depth scale, projection and back-projection.

Defaults are the TUM RGB-D ``freiburg1`` camera (fr1/xyz, fr1/desk) at 640 x 480, with the
data set's depth scale of 5000 per metre; ``Intrinsics.fr2()`` is the freiburg2 camera.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fogiac.errors import WorkloadError


@dataclass(frozen=True)
class Intrinsics:
    fx: float = 517.3
    fy: float = 516.5
    cx: float = 318.6
    cy: float = 255.3
    width: int = 640
    height: int = 480
    depth_scale: float = 5000.0  # 16-bit depth PNG units per metre (TUM RGB-D)

    def __post_init__(self) -> None:
        if min(self.fx, self.fy) <= 0 or min(self.width, self.height) <= 0 or self.depth_scale <= 0:
            raise WorkloadError(f"intrinsics must be positive: {self}")

    @classmethod
    def fr1(cls) -> Intrinsics:
        return cls()

    @classmethod
    def fr2(cls) -> Intrinsics:
        return cls(fx=520.9, fy=521.0, cx=325.1, cy=249.7)

    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, factor: float) -> Intrinsics:
        """The same camera at ``factor`` times the resolution (a smaller test sequence)."""
        return replace(self, fx=self.fx * factor, fy=self.fy * factor, cx=self.cx * factor, cy=self.cy * factor,
                       width=round(self.width * factor), height=round(self.height * factor))

    def backproject(self, uv: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """(N, 3) points in the camera frame from (N, 2) pixels and (N,) depths in metres."""
        x = (uv[:, 0] - self.cx) / self.fx * depth
        y = (uv[:, 1] - self.cy) / self.fy * depth
        return np.column_stack([x, y, depth])

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(pixels (N, 2), depths (N,)) of (N, 3) camera-frame points; depth <= 0 means behind."""
        z = points[:, 2]
        safe = np.where(np.abs(z) > 1e-9, z, 1e-9)
        uv = np.column_stack([self.fx * points[:, 0] / safe + self.cx, self.fy * points[:, 1] / safe + self.cy])
        return uv, z

    def inside(self, uv: np.ndarray, *, margin: float = 0.0) -> np.ndarray:
        return ((uv[:, 0] >= margin) & (uv[:, 0] < self.width - margin)
                & (uv[:, 1] >= margin) & (uv[:, 1] < self.height - margin))
