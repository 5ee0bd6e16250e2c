"""The FogROS SLAM table through fogiac's relay on the local target: edge (1 core) against cloud.

``.venv/bin/python benchmarks/slam_local.py [--runs 1] [--scale 1.0] [--out FILE]``

Per sequence (rendered ``desk`` and ``loop``, cached under ``--cache``), run by run:

- **edge**: the robot runs SLAM itself on 1 core, ``python -m workloads.slam run DIR --cores 1
  --json``: FPS, map creation, and the cores it got (CPU seconds over tracking's wall seconds);
- **cloud**: ``fogiac up examples/slam.yaml --target local --start-edge-master`` (the node on every
  core of this machine, behind the relay over mutual TLS on loopback), then the robot-side player
  sends the sequence in lockstep (each frame once the last was answered, so none is dropped and
  every round trip is one frame's): end-to-end FPS (poses over the seconds from the first frame
  sent to the last pose back), the node's own map-creation time, the median round trip and compute
  time, and the network time per frame, round trip less compute (both relay hops, both ways);
  the cores the node got are its process tree's CPU seconds over the playing seconds; then ``down``.

The load average before each side's run is printed with it; ratios are against the 1-core edge of
the same run. Not a test: figures depend on what else the machine runs.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))  # run as a script: this checkout's fogiac and workloads, not an installed copy

from fogiac.procs import free_port  # noqa: E402
from workloads.slam.benchmark import prepare  # noqa: E402

TICKS = os.sysconf("SC_CLK_TCK")


def _cpu_s(root: int) -> float:
    """CPU seconds of ``root`` and every live descendant (threads included)."""
    parents: dict[int, int] = {}
    times: dict[int, float] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        pid = int(stat.parent.name)
        parents[pid], times[pid] = int(fields[1]), (int(fields[11]) + int(fields[12])) / TICKS
    tree, grew = {root}, True
    while grew:
        more = {p for p, parent in parents.items() if parent in tree} - tree
        tree |= more
        grew = bool(more)
    return sum(times.get(p, 0.0) for p in tree)


def edge(folder: Path) -> dict[str, Any]:
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, "-m", "workloads.slam", "run", str(folder), "--cores", "1", "--json"],
                          cwd=REPO, capture_output=True, text=True, check=True)
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    return {"fps": summary["fps"], "map_created_s": summary["map_created_s"], "cores_used": summary["cores_used"],
            "ate_rmse_m": summary.get("ate_rmse_m"), "load": load}


def _fogiac(args: list[str], env: dict[str, str]) -> None:
    done = subprocess.run([sys.executable, "-m", "fogiac", *args], cwd=REPO, env=env, capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"fogiac {' '.join(args[:1])} failed: {done.stdout[-2000:]}{done.stderr[-2000:]}")


def cloud(folder: Path, work: Path) -> dict[str, Any]:
    port = free_port()
    doc = yaml.safe_load((REPO / "examples" / "slam.yaml").read_text())
    doc.setdefault("edge", {})["ros_master"] = f"http://127.0.0.1:{port}"
    manifest = work / "slam.yaml"
    manifest.write_text(yaml.safe_dump(doc, sort_keys=False))
    state = work / "state"
    env = {**os.environ, "FOGIAC_STATE_DIR": str(state), "PYTHONPATH": str(REPO)}
    robot = {**env, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1"}
    _fogiac(["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"], env)
    try:
        (child,) = state.glob("slam-dev/local/slam/run/node-slam.child")
        node = int(child.read_text().split()[0])
        load = os.getloadavg()[0]
        cpu0, wall0 = _cpu_s(node), os.times().elapsed
        played = subprocess.run([sys.executable, "-m", "workloads.slam", "play", str(folder), "--lockstep", "--wait",
                                 "120", "--json"], cwd=REPO, env=robot, capture_output=True, text=True, check=True)
        cores_used = (_cpu_s(node) - cpu0) / (os.times().elapsed - wall0)
    finally:
        _fogiac(["down", str(manifest), "--target", "local", "--yes"], env)
    report = json.loads(played.stdout.strip().splitlines()[-1])
    keep = ("fps", "map_created_s", "round_trip_ms_median", "compute_ms_median", "network_ms_median", "ate_rmse_m",
            "frames", "poses")
    return {**{k: report.get(k) for k in keep}, "cores_used": round(cores_used, 2), "load": load,
            "cores": len(os.sched_getaffinity(0))}


def _med(rows: list[dict[str, Any]], key: str) -> float | None:
    values = [r[key] for r in rows if r.get(key) is not None]
    return statistics.median(values) if values else None


def _f(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, default=REPO / "benchmarks" / "out" / "slam-sequences")
    parser.add_argument("--scale", type=float, default=1.0, help="rendered resolution as a fraction of 640 x 480")
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--out", type=Path, help="write every run's figures as JSON here")
    args = parser.parse_args(argv)
    folders = prepare(args.cache, scale=args.scale)
    results: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for i in range(args.runs):
        for folder in folders:
            sides = results.setdefault(folder.name, {"edge": [], "cloud": []})
            sides["edge"].append(edge(folder))
            with tempfile.TemporaryDirectory(prefix="slam-local-") as work:
                sides["cloud"].append(cloud(folder, Path(work)))
            print(f"run {i + 1}/{args.runs} {folder.name}: edge {sides['edge'][-1]}\n  cloud {sides['cloud'][-1]}",
                  flush=True)
    print(f"\n{os.cpu_count()} CPUs here; edge pinned to 1 core, cloud node on {len(os.sched_getaffinity(0))}; "
          f"medians of {args.runs} run(s); ratios against the edge of the same runs")
    print(f"{'sequence':<16}{'side':>6}{'FPS':>7}{'x FPS':>7}{'map s':>7}{'x map':>7}{'rtt ms':>8}{'comp ms':>8}"
          f"{'net ms':>8}{'ATE cm':>8}{'load':>6}{'used':>6}")
    for name, sides in results.items():
        base_fps, base_map = _med(sides["edge"], "fps"), _med(sides["edge"], "map_created_s")
        for side, rows in sides.items():
            fps, map_s = _med(rows, "fps"), _med(rows, "map_created_s")
            ate = _med(rows, "ate_rmse_m")
            print(f"{name:<16}{side:>6}{_f(fps, '.1f'):>7}"
                  f"{_f(fps / base_fps if fps and base_fps else None, '.2f'):>7}{_f(map_s, '.2f'):>7}"
                  f"{_f(base_map / map_s if map_s and base_map else None, '.2f'):>7}"
                  f"{_f(_med(rows, 'round_trip_ms_median'), '.1f'):>8}{_f(_med(rows, 'compute_ms_median'), '.1f'):>8}"
                  f"{_f(_med(rows, 'network_ms_median'), '.1f'):>8}{_f(None if ate is None else 100 * ate, '.2f'):>8}"
                  f"{_f(_med(rows, 'load'), '.2f'):>6}{_f(_med(rows, 'cores_used'), '.2f'):>6}")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
