"""The shipped weights: safe to load, small, and better than grasping at random."""

from __future__ import annotations

import numpy as np
import torch

from workloads.grasp_planning.benchmark import random_grasp
from workloads.grasp_planning.data import TEST_SEED, bench_scene
from workloads.grasp_planning.planner import MODEL_PATH, GraspPlanner
from workloads.grasp_planning.quality import grasp_quality
from workloads.grasp_planning.train import SUCCESS

SCENES = 12


def test_shipped_weights_load_with_weights_only_and_say_how_they_were_made() -> None:
    assert MODEL_PATH.stat().st_size < 2_000_000
    blob = torch.load(MODEL_PATH, map_location="cpu", weights_only=True)
    meta = blob["meta"]
    assert blob["format"] == 1
    assert meta["command"].startswith("python -m workloads.grasp_planning train ")
    assert {"model_success", "random_success", "oracle_success"} <= set(meta["validation"])


def test_shipped_model_beats_random_grasps_on_held_out_scenes() -> None:
    planner = GraspPlanner.load(device="cpu")
    rng = np.random.default_rng(0)
    model, random = [], []
    for i in range(SCENES):  # seeds disjoint from training (TRAIN_SEED) and validation (VAL_SEED)
        s = bench_scene(TEST_SEED + 1000 + i, height=240, width=320)
        g = planner.plan(s.depth, s.intr)
        model.append(grasp_quality(s.scene, s.truth, s.intr, planner.gripper, u=g.u, v=g.v, angle=g.angle))
        u, v, a = random_grasp(s, rng)
        random.append(grasp_quality(s.scene, s.truth, s.intr, planner.gripper, u=u, v=v, angle=a))
    model_rate = float(np.mean(np.array(model) >= SUCCESS))
    random_rate = float(np.mean(np.array(random) >= SUCCESS))
    assert model_rate >= random_rate + 0.25, (model, random)  # shipped: 11/12 against 0/12
    assert float(np.mean(model)) > float(np.mean(random))
