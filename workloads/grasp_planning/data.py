"""Training and evaluation data: random bin scenes, their sensed depth, their analytic labels.

Training crops are rendered straight at the canonical resolution the planner resizes every
input to (``PIXEL_SIZE`` metres per pixel at the median depth), give or take 10 %, so the
network learns one scale. Every example is a pure function of its seed, so a data set is
reproducible from ``(seed, count)`` and held-out seeds never overlap the training ones.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from workloads.grasp_planning.camera import Intrinsics
from workloads.grasp_planning.quality import Gripper, quality_map
from workloads.grasp_planning.scene import Render, Scene, render, sample_scene, sense

PIXEL_SIZE = 0.004
TRAIN_SEED = 1_000_000
VAL_SEED = 2_000_000
TEST_SEED = 3_000_000


@dataclass(frozen=True)
class Example:
    depth: np.ndarray  # sensed, (H, W) float32 metres, 0 = no return
    quality: np.ndarray  # robust analytic quality, (k, H, W) float32 in [0, 1]
    width: np.ndarray  # jaw width at contact, (k, H, W) float32 metres


@dataclass(frozen=True)
class BenchScene:
    """A full-size scene for evaluation: the truth, the camera, and what the sensor saw."""

    scene: Scene
    intr: Intrinsics
    truth: Render
    depth: np.ndarray


def training_example(seed: int, *, size: int = 80, k: int = 8, gripper: Gripper = Gripper()) -> Example:
    rng = np.random.default_rng(seed)
    table_z = float(rng.uniform(0.6, 0.8))
    f = table_z / PIXEL_SIZE * float(rng.uniform(0.9, 1.1))
    # the crop is a window of a wider view: shifting the principal point shows the perspective
    # lean of objects up to ~0.2 m off the optical axis, as at the edges of a full image
    ox, oy = rng.uniform(-50, 50, size=2)
    c = (size - 1) / 2
    intr = Intrinsics(fx=f, fy=f, cx=c + float(ox), cy=c + float(oy))
    scene = sample_scene(
        rng,
        table_z=table_z,
        center=(float(-ox * table_z / f + rng.uniform(-0.05, 0.05)),
                float(-oy * table_z / f + rng.uniform(-0.05, 0.05))),
        bin_half=(float(rng.uniform(0.1, 0.17)), float(rng.uniform(0.08, 0.15))),
        n_objects=int(rng.integers(3, 10)),
    )
    truth = render(scene, intr, height=size, width=size)
    q, w = quality_map(scene, truth, intr, gripper, k=k)
    return Example(depth=sense(truth.depth, rng), quality=q, width=w)


def bench_scene(seed: int, *, height: int = 480, width: int = 640) -> BenchScene:
    """A 640 x 480 view (fx = fy = 540 px scaled with the width) of a bin, about 0.7 m below."""
    rng = np.random.default_rng(seed)
    table_z = float(rng.uniform(0.65, 0.75))
    f = 540.0 * width / 640
    intr = Intrinsics(fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2)
    scene = sample_scene(rng, table_z=table_z, bin_half=(0.2, 0.15), n_objects=int(rng.integers(4, 10)))
    truth = render(scene, intr, height=height, width=width)
    return BenchScene(scene=scene, intr=intr, truth=truth, depth=sense(truth.depth, rng))


def _one(args: tuple[int, int, int]) -> Example:
    seed, size, k = args
    return training_example(seed, size=size, k=k)


def build(first_seed: int, count: int, *, size: int = 80, k: int = 8, workers: int = 1) -> tuple[np.ndarray, ...]:
    """``count`` examples from consecutive seeds, stacked: depth, quality (uint8), width (float16)."""
    jobs = [(first_seed + i, size, k) for i in range(count)]
    if workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            examples = list(pool.map(_one, jobs, chunksize=max(1, count // (4 * workers))))
    else:
        examples = [_one(j) for j in jobs]
    depth = np.stack([e.depth for e in examples])
    quality = np.stack([np.round(e.quality * 255).astype(np.uint8) for e in examples])
    width = np.stack([e.width.astype(np.float16) for e in examples])
    return depth, quality, width


def resize_factor(depth: np.ndarray, intr: Intrinsics) -> float:
    """How much to shrink an image so one pixel spans PIXEL_SIZE at its median valid depth."""
    valid = depth[depth > 0]
    if valid.size == 0:
        raise ValueError("depth image has no valid pixels")
    return PIXEL_SIZE * math.sqrt(intr.fx * intr.fy) / float(np.median(valid))
