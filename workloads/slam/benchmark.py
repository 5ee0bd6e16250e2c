"""Benchmark in the shape of the FogROS SLAM table: edge (1 core) against cloud (all cores), or a curve.

``python -m workloads.slam.benchmark --runs 3 [--sequence DIR ...] [--cores 1,2,4,8,16] [--frames N]
[--scale S] [--out FILE]``

Each sequence (rendered ``desk`` and ``loop`` at 640 x 480 by default, each in its own process, once
per cache folder; or TUM folders given with ``--sequence``) runs in a child process (``--one``: the
SLAM libraries only, no CLI packages, so it runs where only numpy, OpenCV and GTSAM are installed),
the core counts interleaved run by run so that load drifting during the benchmark hits every side
alike. Per sequence and core count it prints the median FPS and map-creation time, each against the
first core count measured in the same run, the load average before the runs, the cores the runs
actually got (CPU seconds of all their threads and processes while tracking, over those wall
seconds: a run pinned to 2 cores on a machine busy with other work gets less), and each stage's
CPU milliseconds per frame (read, extract, track, mapping, loop), which do not depend on the load.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import statistics
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

from workloads.slam.camera import Intrinsics
from workloads.slam.render import render_sequence
from workloads.slam.system import run_sequence
from workloads.slam.tracking import Config
from workloads.slam.tum import read_sequence

DEFAULT_SEQUENCES = (("desk", 150), ("loop", 260))


@dataclass(frozen=True)
class Run:
    sequence: str
    cores: int
    fps: float
    map_created_s: float | None
    ate_rmse_m: float | None
    tracked_ratio: float
    load_before: float
    cores_used: float  # CPU seconds / wall seconds while tracking, all of the run's processes and threads
    frames: int
    stage_cpu_s: dict[str, float]  # read, extract, track (threads here), mapping, loop (processes)
    first_map_frame: int | None
    load_after: float


def run_once(folder: Path, cores: int, *, features: int, frames: int | None = None) -> Run:
    """One run in a child process (``--one``: no CLI dependencies, so it runs where only the libraries are)."""
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, "-m", "workloads.slam.benchmark", "--one", str(folder),
                           "--cores", str(cores), "--features", str(features),
                           *(["--frames", str(frames)] if frames else [])],
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"slam run failed on {folder}: {done.stderr.strip()}")
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    return Run(folder.name, summary["cores"], summary["fps"], summary["map_created_s"], summary.get("ate_rmse_m"),
               summary["tracked_ratio"], load, summary["cores_used"], summary["frames"], summary["stage_cpu_s"],
               summary["first_map_frame"], os.getloadavg()[0])


def one(folder: Path, cores: int, features: int, frames: int | None) -> None:
    """Run SLAM on one folder and print its summary as one JSON line (the benchmark's child)."""
    result = run_sequence(read_sequence(folder), cores=cores, config=Config(features=features), max_frames=frames)
    print(json.dumps(result.summary()), flush=True)


def prepare(root: Path, *, scale: float) -> list[Path]:
    """The default rendered sequences under ``root``, rendered once (a marker file says done), each in its
    own process."""
    folders = [root / f"{kind}-{frames}-{scale:g}" for kind, frames in DEFAULT_SEQUENCES]
    todo = [(folder, kind, frames) for folder, (kind, frames) in zip(folders, DEFAULT_SEQUENCES, strict=True)
            if not (folder / "done").is_file()]
    if todo:
        with ProcessPoolExecutor(max_workers=len(todo), mp_context=mp.get_context("spawn")) as pool:
            for _ in pool.map(_render, *zip(*todo, strict=True), [scale] * len(todo)):
                pass
    return folders


def _render(folder: Path, kind: str, frames: int, scale: float) -> None:
    render_sequence(folder, kind=kind, frames=frames, intrinsics=Intrinsics.fr1().scaled(scale))
    (folder / "done").write_text("")


def _median(values: list[float | None]) -> float | None:
    present = [v for v in values if v is not None]
    return statistics.median(present) if present else None


STAGES = ("read", "extract", "track", "mapping", "loop")


def table(runs: list[Run], core_counts: list[int]) -> list[dict[str, object]]:
    rows = []
    for sequence in dict.fromkeys(r.sequence for r in runs):
        base = [r for r in runs if r.sequence == sequence and r.cores == core_counts[0]]
        base_fps, base_map = _median([r.fps for r in base]), _median([r.map_created_s for r in base])
        for c in core_counts:
            mine = [r for r in runs if r.sequence == sequence and r.cores == c]
            if not mine:
                continue
            fps, map_s = _median([r.fps for r in mine]), _median([r.map_created_s for r in mine])
            stage_ms = {name: _median([1000 * r.stage_cpu_s.get(name, 0.0) / r.frames for r in mine])
                        for name in STAGES}
            rows.append({
                "sequence": sequence, "cores": c, "runs": len(mine), "fps": fps, "map_created_s": map_s,
                "fps_ratio": fps / base_fps if fps and base_fps else None,
                "map_speedup": base_map / map_s if map_s and base_map else None,
                "ate_rmse_m": _median([r.ate_rmse_m for r in mine]),
                "tracked_ratio": min(r.tracked_ratio for r in mine),
                "load_before": _median([r.load_before for r in mine]),
                "load_after": _median([r.load_after for r in mine]),
                "cores_used": _median([r.cores_used for r in mine]),
                "first_map_frame": _median([r.first_map_frame for r in mine]),
                "stage_cpu_ms_per_frame": stage_ms,
            })
    return rows


def _fmt(value: object, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sequence", type=Path, action="append", help="TUM folder (repeatable); default: rendered")
    parser.add_argument("--cache", type=Path, default=Path("benchmarks/out/slam-sequences"))
    parser.add_argument("--scale", type=float, default=1.0, help="rendered resolution as a fraction of 640 x 480")
    parser.add_argument("--cores", default="", help="comma-separated core counts; the first is the baseline "
                                                    "(default: 1 and every core this process may use)")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--features", type=int, default=1000)
    parser.add_argument("--frames", type=int, help="run only each sequence's first frames (default: all)")
    parser.add_argument("--out", type=Path, help="write rows and runs as JSON here")
    parser.add_argument("--one", type=Path, help=argparse.SUPPRESS)  # the child: one run, one JSON line
    args = parser.parse_args(argv)
    if args.one is not None:
        one(args.one, int(args.cores or 0), args.features, args.frames)
        return
    everything = len(os.sched_getaffinity(0))
    try:
        core_counts = [int(c) for c in args.cores.split(",")] if args.cores else sorted({1, everything})
    except ValueError:
        raise SystemExit(f"--cores: {args.cores!r} is not a comma-separated list of numbers") from None
    if any(c < 1 or c > everything for c in core_counts):
        raise SystemExit(f"--cores: {args.cores!r} asks for more than the {everything} CPUs usable here (or < 1)")
    folders = args.sequence or prepare(args.cache, scale=args.scale)
    runs: list[Run] = []
    for i in range(args.runs):
        for folder in folders:
            for c in core_counts:
                runs.append(run_once(folder, c, features=args.features, frames=args.frames))
                r = runs[-1]
                per = {k: 1000 * v / r.frames for k, v in r.stage_cpu_s.items()}
                print(f"run {i + 1}/{args.runs} {r.sequence} cores={c}: {r.fps:.1f} FPS, "
                      f"map {_fmt(r.map_created_s, '.2f')} s (frame {r.first_map_frame}), "
                      f"load {r.load_before:.2f}-{r.load_after:.2f}, used {r.cores_used:.2f} cores; CPU ms/frame "
                      + " ".join(f"{k} {v:.1f}" for k, v in per.items()), flush=True)
    rows = table(runs, core_counts)
    print(f"\n{os.cpu_count()} CPUs here, {everything} usable; baseline: {core_counts[0]} core(s), same run")
    print(f"{'sequence':<16}{'cores':>6}{'FPS':>8}{'x FPS':>7}{'map s':>8}{'x map':>7}{'ATE cm':>8}{'tracked':>9}"
          f"{'load':>7}{'used':>7}  CPU ms/frame: read extract track mapping loop")
    for row in rows:
        ate = row["ate_rmse_m"]
        stage = row["stage_cpu_ms_per_frame"]
        assert isinstance(stage, dict)
        print(f"{row['sequence']:<16}{row['cores']:>6}{_fmt(row['fps'], '.1f'):>8}{_fmt(row['fps_ratio'], '.2f'):>7}"
              f"{_fmt(row['map_created_s'], '.2f'):>8}{_fmt(row['map_speedup'], '.2f'):>7}"
              f"{_fmt(None if ate is None else 100 * float(str(ate)), '.2f'):>8}{_fmt(row['tracked_ratio'], '.3f'):>9}"
              f"{_fmt(row['load_before'], '.2f'):>7}{_fmt(row['cores_used'], '.2f'):>7}  "
              + " ".join(_fmt(stage[k], ".1f") for k in STAGES))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"rows": rows, "runs": [asdict(r) for r in runs]}, indent=1))


if __name__ == "__main__":
    main()
