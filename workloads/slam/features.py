"""ORB features of one frame, spread over the image, with the depth under each keypoint.

OpenCV's ORB keeps the strongest corners wherever they cluster; like ORB-SLAM2 we ask for three
times as many and keep the best of each grid cell, so that tracking sees the whole image.
``cv2`` releases the GIL while detecting and describing (measured: two threads extract twice as
many frames per second as one on two cores), so frames are extracted in a thread pool.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import cv2
import numpy as np

from workloads.slam.camera import Intrinsics

SCALE_FACTOR = 1.2
LEVELS = 8
GRID = (8, 6)  # cells across, down
MIN_DEPTH_M, MAX_DEPTH_M = 0.1, 6.0
EDGE_RATIO = 0.03  # depth spread in a 5 x 5 window, relative to the depth, above which a reading is dropped


@dataclass(frozen=True)
class Features:
    index: int  # frame number in the sequence
    stamp: float
    uv: np.ndarray  # (N, 2) float32 pixels
    octave: np.ndarray  # (N,) pyramid level: the measurement's scale is SCALE_FACTOR ** octave
    desc: np.ndarray  # (N, 32) uint8 ORB descriptors
    depth: np.ndarray  # (N,) float32 metres; 0 where the sensor had no valid reading (and in mono)

    def __len__(self) -> int:
        return len(self.uv)


class Extractor:
    """Callable from several threads: each thread keeps its own ORB detector."""

    def __init__(self, intrinsics: Intrinsics, *, features: int = 1000) -> None:
        self.intrinsics, self.features = intrinsics, features
        self._local = threading.local()

    def _orb(self) -> cv2.ORB:
        orb = getattr(self._local, "orb", None)
        if orb is None:
            orb = cv2.ORB.create(self.features * 3, scaleFactor=SCALE_FACTOR, nlevels=LEVELS, fastThreshold=12)
            self._local.orb = orb
        return orb

    def __call__(self, index: int, stamp: float, grey: np.ndarray, depth: np.ndarray | None) -> Features:
        keypoints, desc = self._orb().detectAndCompute(grey, None)
        if desc is None or not keypoints:
            return Features(index, stamp, np.zeros((0, 2), np.float32), np.zeros(0, np.int32),
                            np.zeros((0, 32), np.uint8), np.zeros(0, np.float32))
        uv = np.array([k.pt for k in keypoints], np.float32)
        response = np.array([k.response for k in keypoints], np.float32)
        octave = np.array([k.octave for k in keypoints], np.int32)
        keep = _spread(uv, response, self.intrinsics, self.features)
        uv, octave, desc = uv[keep], octave[keep], desc[keep]
        if depth is None:
            z = np.zeros(len(uv), np.float32)
        else:
            col = np.clip(np.round(uv[:, 0]).astype(int), 0, depth.shape[1] - 1)
            row = np.clip(np.round(uv[:, 1]).astype(int), 0, depth.shape[0] - 1)
            z = depth[row, col].astype(np.float32)
            # Corners sit on depth edges; there the nearest pixel's depth may be the background's.
            kernel = np.ones((5, 5), np.uint8)
            spread = cv2.dilate(depth, kernel)[row, col] - cv2.erode(depth, kernel)[row, col]
            z[(z < MIN_DEPTH_M) | (z > MAX_DEPTH_M) | (spread > EDGE_RATIO * z)] = 0.0
        return Features(index, stamp, uv, octave, desc, z)


def _spread(uv: np.ndarray, response: np.ndarray, intrinsics: Intrinsics, wanted: int) -> np.ndarray:
    """Indices of up to ``wanted`` keypoints: the strongest per grid cell first, round-robin over cells."""
    cols, rows = GRID
    cell = (np.minimum(uv[:, 0] * cols // intrinsics.width, cols - 1) * rows
            + np.minimum(uv[:, 1] * rows // intrinsics.height, rows - 1)).astype(int)
    order = np.lexsort((-response, cell))  # by cell, strongest first within a cell
    sorted_cells = cell[order]
    first = np.searchsorted(sorted_cells, sorted_cells, side="left")
    rank = np.arange(len(order)) - first  # 0 for a cell's strongest keypoint, 1 for the next...
    chosen = order[np.lexsort((-response[order], rank))][:wanted]
    return np.sort(chosen)
