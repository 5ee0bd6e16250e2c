"""The README's main job: the paper's motion-planning table, on this machine.

``python -m workloads.motion_planning.demo [MANIFEST]`` deploys the motion-planning example with
``fogiac up --target local`` exactly as it would go to AWS (only the "cloud" is a sandbox here),
then, run after run, plans every shipped problem on the robot with 1 core and sends the same
problems from a robot-side client through the relay to the cloud node (all cores), so load that
drifts hits both sides alike; prints a table in the shape of the FogROS paper's (edge vs cloud,
compute and network time apart, load average beside it), and tears everything down with
``fogiac down``, also when something failed. Both sides plan warm: the robot's planner is a
long-lived 1-worker :class:`WarmPlanner`, as a robot's own planning node would be.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

import rospy

from fogiac.manifest.schema import load_manifest
from workloads.motion_planning.client import request_paths, shipped_problems
from workloads.motion_planning.planner import Solution, warm_up
from workloads.motion_planning.pool import WarmPlanner
from workloads.motion_planning.problem import PROBLEMS_DIR, load_problem

REPO_EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "motion-planning.yaml"


@dataclass(frozen=True)
class Row:
    problem: str
    edge_s: float
    edge_solved: int
    cloud_compute_s: float
    cloud_round_trip_s: float
    cloud_solved: int
    runs: int

    @property
    def network_s(self) -> float:
        return max(0.0, self.cloud_round_trip_s - self.cloud_compute_s)

    @property
    def speedup(self) -> float:
        return self.edge_s / self.cloud_round_trip_s if self.cloud_round_trip_s else 0.0


def _fogiac(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "fogiac", *args], check=True)


def edge_run(robot: WarmPlanner, names: list[str], *, time_limit: float | None) -> list[Solution]:
    """Plan on the robot itself: one core, as a robot without a big computer would."""
    return [robot.solve(name, time_limit=time_limit) for name in names]


def interleaved_runs(names: list[str], *, runs: int,
                     time_limit: float | None) -> tuple[dict[str, list], dict[str, list]]:
    """Run after run: every problem on the robot, then every problem in the cloud through the relay."""
    rospy.init_node("fogiac_demo_client", anonymous=True, disable_signals=True)
    edge: dict[str, list] = {name: [] for name in names}
    cloud: dict[str, list] = {name: [] for name in names}
    problems = {name: load_problem(PROBLEMS_DIR / f"{name}.cfg") for name in names}
    warm_up()
    with WarmPlanner(problems, workers=1) as robot:
        for run in range(runs):
            for name, solution in zip(names, edge_run(robot, names, time_limit=time_limit), strict=True):
                edge[name].append(solution)
            for timing in request_paths(names, timeout=300, connect_timeout=120):
                cloud[timing.name].append(timing)
            print(f"   run {run + 1}/{runs} done, load average {os.getloadavg()[0]:.2f}", flush=True)
    return edge, cloud


def geometric_mean(values: list[float]) -> float:
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values and all(v > 0 for v in values) else 0.0


def table(rows: list[Row], *, cloud_cores: int) -> str:
    head = (f"{'problem':<10} {'edge 1 core':>12} {'cloud ' + str(cloud_cores) + ' cores':>14} "
            f"{'network+relay':>14} {'cloud total':>12} {'speedup':>8} {'solved e c':>11}")
    lines = [head, "-" * len(head)]
    for r in rows:
        solved = f"{r.edge_solved}/{r.runs} {r.cloud_solved}/{r.runs}"
        lines.append(f"{r.problem:<10} {r.edge_s:>11.2f}s {r.cloud_compute_s:>13.2f}s {r.network_s:>13.3f}s "
                     f"{r.cloud_round_trip_s:>11.2f}s {r.speedup:>7.2f}x {solved:>11}")
    lines.append(f"geometric mean speedup {geometric_mean([r.speedup for r in rows]):.2f}x; "
                 "medians over runs; speedup = edge time / cloud total (compute + network + relay)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m workloads.motion_planning.demo", description=__doc__)
    parser.add_argument("manifest", nargs="?", type=Path, default=REPO_EXAMPLE)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--problems", default=",".join(p for p in shipped_problems() if p != "easy"))
    parser.add_argument("--time-limit", type=float, default=None, help="per solve; default: the .cfg's")
    args = parser.parse_args(argv)
    names = [n for n in args.problems.split(",") if n]
    edge_master = _edge_master(args.manifest)

    print("== fogiac up --target local", flush=True)
    try:
        _fogiac("up", str(args.manifest), "--target", "local", "--yes", "--start-edge-master")
        os.environ.update(ROS_MASTER_URI=edge_master, ROS_HOSTNAME="127.0.0.1")
        print(f"== {args.runs} run(s), each: every problem on the robot (1 core), then in the 'cloud' "
              "through the relay", flush=True)
        edge, cloud = interleaved_runs(names, runs=args.runs, time_limit=args.time_limit)
        _fogiac("status", str(args.manifest), "--target", "local")
    finally:
        print("== fogiac down", flush=True)
        _fogiac("down", str(args.manifest), "--target", "local", "--yes")
    rows = [
        Row(problem=name,
            edge_s=statistics.median(s.solve_time_s for s in edge[name]),
            edge_solved=sum(s.solved for s in edge[name]),
            cloud_compute_s=statistics.median(t.compute_time_s for t in cloud[name]),
            cloud_round_trip_s=statistics.median(t.round_trip_s for t in cloud[name]),
            cloud_solved=sum(t.solved for t in cloud[name]), runs=args.runs)
        for name in names
    ]
    print(table(rows, cloud_cores=os.cpu_count() or 1))
    print(f"load average (1, 5, 15 min) at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if all(r.cloud_solved for r in rows) else 1


def _edge_master(manifest: Path) -> str:
    uri = load_manifest(manifest).edge.ros_master
    url = urlparse(uri)
    return f"http://{'127.0.0.1' if url.hostname == 'localhost' else url.hostname}:{url.port}"


if __name__ == "__main__":
    sys.exit(main())
