"""Depth images from the outside world (files, ROS messages), checked once at the edge.

Everything past this module sees a float32 (H, W) array in metres with 0 where the sensor
gave no return, so the planner never guesses units.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fogiac.errors import WorkloadError

MIN_SIDE = 16

# encoding -> (numpy dtype, metres per unit); the two depth encodings REP 118 allows
ENCODINGS: dict[str, tuple[str, float]] = {
    "32FC1": ("f4", 1.0),
    "16UC1": ("u2", 0.001),
    "mono16": ("u2", 0.001),
}


def depth_from_array(arr: np.ndarray, *, source: str) -> np.ndarray:
    """Validate and convert: floats are metres, unsigned 16-bit integers are millimetres."""
    if arr.ndim == 3 and arr.shape[-1] == 1:
        arr = arr[..., 0]
    if arr.ndim != 2 or min(arr.shape) < MIN_SIDE:
        raise WorkloadError(
            f"{source}: depth must be a 2-D array (H, W) with both sides >= {MIN_SIDE}, got shape {tuple(arr.shape)}"
        )
    if arr.dtype == np.uint16:
        depth = arr.astype(np.float32) * 0.001
    elif np.issubdtype(arr.dtype, np.floating):
        depth = arr.astype(np.float32)
    else:
        raise WorkloadError(f"{source}: depth must be float metres or uint16 millimetres, got dtype {arr.dtype}")
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    if not (depth > 0).any():
        raise WorkloadError(f"{source}: depth image has no valid (positive, finite) pixels")
    return depth


def load_depth_file(path: Path) -> np.ndarray:
    """A ``.npy`` depth image (float metres or uint16 millimetres)."""
    if not path.is_file():
        raise WorkloadError(f"{path}: no such file")
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as err:
        raise WorkloadError(f"{path}: not a .npy array ({err})") from None
    if not isinstance(arr, np.ndarray):
        raise WorkloadError(f"{path}: expected one array, got an archive of several")
    return depth_from_array(arr, source=str(path))


def depth_from_buffer(
    data: bytes, *, encoding: str, height: int, width: int, step: int, big_endian: bool, source: str
) -> np.ndarray:
    """The bytes of a sensor_msgs/Image as depth in metres (32FC1 metres, 16UC1 millimetres)."""
    if encoding not in ENCODINGS:
        raise WorkloadError(f"{source}: unsupported depth encoding {encoding!r}; use one of {', '.join(ENCODINGS)}")
    code, scale = ENCODINGS[encoding]
    dtype = np.dtype(code).newbyteorder(">" if big_endian else "<")
    if step < width * dtype.itemsize or len(data) < step * height:
        raise WorkloadError(
            f"{source}: {len(data)} bytes do not hold {height} rows of step {step} for {width} x {encoding}"
        )
    rows = np.frombuffer(data, dtype=np.uint8, count=step * height).reshape(height, step)
    arr = rows[:, : width * dtype.itemsize].copy().view(dtype).reshape(height, width)
    depth = arr.astype(np.float32) * np.float32(scale)
    return depth_from_array(depth, source=source)
