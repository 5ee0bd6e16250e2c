"""Benchmark: planning latency on 640 x 480 depth per device, and grasp success on held-out scenes.

    python -m workloads.grasp_planning.benchmark [--out benchmarks/out] [--scenes 100] [--reps 30]

Latency is one full ``plan`` call (resize, hole filling, network, arg-max, pose), timed with
the same weights on the CPU with 1 thread, with every core, at any extra thread counts asked
for, and on CUDA when torch sees a GPU; each is reported as a ratio against the 1-thread
median measured in the same run. Success is the analytic robust quality of the chosen grasp,
on the exact scene, at or above 0.5: for the model, a random grasp (a random pixel that is
above the bin floor, a random angle) and the analytic oracle (the best cell of the exact
quality map). Writes ``grasp_planning.json`` and ``grasp_planning.md`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from workloads.grasp_planning.camera import to_original_pixel
from workloads.grasp_planning.data import TEST_SEED, BenchScene, bench_scene, resize_factor
from workloads.grasp_planning.decode import decode_best
from workloads.grasp_planning.network import prepare
from workloads.grasp_planning.planner import MODEL_PATH, GraspPlanner
from workloads.grasp_planning.quality import grasp_quality, quality_map
from workloads.grasp_planning.scene import render
from workloads.grasp_planning.train import SUCCESS


def latency(planner: GraspPlanner, s: BenchScene, *, reps: int, warmup: int = 3) -> dict[str, float]:
    """Whole ``plan`` calls, and the network's forward pass alone on the same prepared input."""
    for _ in range(warmup):
        planner.plan(s.depth, s.intr)
    plans = []
    for _ in range(reps):
        t = time.perf_counter()
        planner.plan(s.depth, s.intr)  # ends with a device-to-host copy, so CUDA work is finished
        plans.append(time.perf_counter() - t)
    _, _, small, _ = planner.maps(s.depth, s.intr)
    x = prepare(torch.from_numpy(small)[None, None].to(planner.device))
    nets = []
    with torch.inference_mode():
        for i in range(warmup + reps):
            t = time.perf_counter()
            planner.net(x)
            if planner.device.type == "cuda":
                torch.cuda.synchronize(planner.device)
            if i >= warmup:
                nets.append(time.perf_counter() - t)
    return {
        "median_ms": 1000 * float(np.median(plans)),
        "p90_ms": 1000 * float(np.percentile(plans, 90)),
        "net_median_ms": 1000 * float(np.median(nets)),
        "net_p90_ms": 1000 * float(np.percentile(nets, 90)),
    }


def random_grasp(s: BenchScene, rng: np.random.Generator) -> tuple[float, float, float]:
    d = s.depth
    fg = np.argwhere((d > 0) & (d < np.median(d[d > 0]) - 0.01))
    v, u = fg[rng.integers(len(fg))] if len(fg) else (rng.integers(d.shape[0]), rng.integers(d.shape[1]))
    return float(u), float(v), float(rng.uniform(0, math.pi))


def oracle_grasp(s: BenchScene, *, k: int, planner: GraspPlanner) -> tuple[float, float, float]:
    """Best cell of the exact quality map, at the planner's canonical scale."""
    factor = resize_factor(s.truth.depth, s.intr)
    h, w = s.truth.depth.shape
    size = (round(h / factor), round(w / factor))
    intr = s.intr.scaled(w / size[1])
    truth = render(s.scene, intr, height=size[0], width=size[1])
    q, wid = quality_map(s.scene, truth, intr, planner.gripper, k=k)
    pick = decode_best(q, wid)
    u, v = to_original_pixel(pick.u, pick.v, w / size[1])
    return u, v, pick.angle


def success(planner: GraspPlanner, *, scenes: int, seed: int) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    k = int(planner.meta["k"])
    quality: dict[str, list[float]] = {"model": [], "random": [], "oracle": []}
    for i in range(scenes):
        s = bench_scene(seed + i)
        g = planner.plan(s.depth, s.intr)
        picks = {
            "model": (g.u, g.v, g.angle),
            "random": random_grasp(s, rng),
            "oracle": oracle_grasp(s, k=k, planner=planner),
        }
        for name, (u, v, a) in picks.items():
            quality[name].append(grasp_quality(s.scene, s.truth, s.intr, planner.gripper, u=u, v=v, angle=a))
    return {
        name: {"success_rate": float(np.mean(np.array(q) >= SUCCESS)), "mean_quality": float(np.mean(q))}
        for name, q in quality.items()
    }


def run(*, out: Path, model: Path, scenes: int, reps: int, threads: list[int]) -> dict[str, Any]:
    load_before = os.getloadavg()[0]  # other work on the machine skews the thread comparison
    s = bench_scene(TEST_SEED)
    rows: list[dict[str, Any]] = []
    cpu = GraspPlanner.load(model, device="cpu")
    for n in threads:
        torch.set_num_threads(n)
        rows.append({"device": "cpu", "threads": n, **latency(cpu, s, reps=reps)})
    torch.set_num_threads(max(threads))
    if torch.cuda.is_available():
        gpu = GraspPlanner.load(model, device="cuda")
        name = f"cuda ({torch.cuda.get_device_name(0)})"
        rows.append({"device": name, "threads": max(threads), **latency(gpu, s, reps=reps)})
    base, net_base = rows[0]["median_ms"], rows[0]["net_median_ms"]
    for r in rows:
        r["speedup_vs_1_thread"] = base / r["median_ms"]
        r["net_speedup_vs_1_thread"] = net_base / r["net_median_ms"]
    result = {
        "input": f"{s.depth.shape[1]}x{s.depth.shape[0]} depth",
        "net_input": "x".join(str(n) for n in cpu.maps(s.depth, s.intr)[2].shape[::-1]),
        "cpu_count": os.cpu_count(),
        "load_average_1min_before": load_before,
        "torch": torch.__version__,
        "latency": rows,
        "held_out_scenes": scenes,
        "scene_seed": TEST_SEED + 1000,
        "success": success(cpu, scenes=scenes, seed=TEST_SEED + 1000),
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "grasp_planning.json").write_text(json.dumps(result, indent=2))
    (out / "grasp_planning.md").write_text(table(result))
    return result


def table(result: dict[str, Any]) -> str:
    lines = [
        f"plan() on {result['input']}; network alone on its {result['net_input']} canonical input;"
        f" {result['cpu_count']} cores, 1-minute load average {result['load_average_1min_before']:.2f} before the run",
        "",
        "| device | threads | plan median ms | plan p90 ms | plan speedup | net median ms | net p90 ms | net speedup |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in result["latency"]:
        lines.append(
            f"| {r['device']} | {r['threads']} | {r['median_ms']:.1f} | {r['p90_ms']:.1f}"
            f" | {r['speedup_vs_1_thread']:.2f}x"
            f" | {r['net_median_ms']:.2f} | {r['net_p90_ms']:.2f} | {r['net_speedup_vs_1_thread']:.2f}x |"
        )
    lines.append("(speedups: against the 1-thread CPU median of the same run)")
    lines += [
        "",
        f"| grasp on {result['held_out_scenes']} held-out scenes | success rate | mean robust quality |",
        "|---|---|---|",
    ]
    for name, r in result["success"].items():
        lines.append(f"| {name} | {r['success_rate']:.2f} | {r['mean_quality']:.3f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m workloads.grasp_planning.benchmark",
                                description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/out"))
    p.add_argument("--model", type=Path, default=MODEL_PATH)
    p.add_argument("--scenes", type=int, default=100, help="held-out scenes for the success rates")
    p.add_argument("--reps", type=int, default=30, help="timed plans per device")
    p.add_argument("--threads", default="", help="extra CPU thread counts, e.g. 2,4,8 (1 and all cores always run)")
    a = p.parse_args(argv)
    extra = [int(t) for t in a.threads.split(",") if t.strip()]
    threads = sorted({1, os.cpu_count() or 1, *extra})
    result = run(out=a.out, model=a.model, scenes=a.scenes, reps=a.reps, threads=threads)
    print(table(result), end="")


if __name__ == "__main__":
    main()
