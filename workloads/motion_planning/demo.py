"""The README's main job: the paper's motion-planning table, on this machine.

``python -m workloads.motion_planning.demo [MANIFEST]`` deploys the motion-planning example with
``fogiac up --target local`` exactly as it would go to AWS (only the "cloud" is a sandbox here),
then, run after run, plans every shipped problem on the robot with 1 core and sends the same
problems from a robot-side client through the relay to the cloud node (all cores), so load that
drifts hits both sides alike; prints a table in the shape of the FogROS paper's (edge vs cloud,
compute and network time apart, load average beside it), and tears everything down with
``fogiac down``, also when something failed. Both sides plan warm: the robot's planner is a
long-lived 1-worker :class:`WarmPlanner`, as a robot's own planning node would be. Each run's
times are printed as they come, and at the end how many cores each side's planner processes
actually got while planning (on a machine shared with other jobs, fewer than it has).

Each request carries a seed, the same for the robot and the cloud (common random numbers): the
cloud's worker 0 searches exactly as the robot does and its other workers make other draws, so
a run compares one core and N cores on the same luck, not on two separate lucks. Each side on
its own is as random as ever (a fresh base seed per demo unless ``--seed``); only the noise in
their ratio shrinks.
"""

from __future__ import annotations

import argparse
import math
import os
import random
import statistics
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

import rospy

from fogiac.manifest.schema import load_manifest
from fogiac.procs import cpu_seconds, descendants
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


def edge_run(robot: WarmPlanner, names: list[str], *, time_limit: float | None,
             seeds: dict[str, int]) -> list[Solution]:
    """Plan on the robot itself: one core, as a robot without a big computer would."""
    return [robot.solve(name, time_limit=time_limit, seed=seeds[name]) for name in names]


def run_seeds(base: int, run: int, names: list[str]) -> dict[str, int]:
    """Each request's seed in one run: a thousand apart, so N workers' ``seed + i`` never meet."""
    return {name: base + 1000 * (run * len(names) + i) for i, name in enumerate(names)}


class CoresUsed:
    """CPU seconds a side's planner processes used over the wall seconds it spent planning: how many
    cores it actually got, which other jobs on a shared machine decide as much as its own count."""

    def __init__(self, pids: Callable[[], list[int]]) -> None:
        self._pids, self.cpu_s, self.wall_s, self.seen = pids, 0.0, 0.0, True

    @contextmanager
    def measure(self) -> Iterator[list[float]]:
        """CPU over the block; the block appends the wall seconds of its requests (not the set-up between)."""
        pids = self._pids()
        self.seen = self.seen and bool(pids)
        cpu = sum(map(cpu_seconds, pids))
        walls: list[float] = []
        yield walls
        self.cpu_s += sum(map(cpu_seconds, pids)) - cpu
        self.wall_s += sum(walls)

    @property
    def cores(self) -> float | None:
        return self.cpu_s / self.wall_s if self.wall_s > 0 and self.seen else None


def cloud_planner_pids() -> list[int]:
    """The cloud node and its workers, when exactly one motion-planning node runs on this machine."""
    nodes = [pid for pid in _pids() if _runs_node(pid)]
    return [nodes[0], *descendants(nodes[0])] if len(nodes) == 1 else []


def _pids() -> list[int]:
    return [int(entry.name) for entry in Path("/proc").iterdir() if entry.name.isdigit()]


def _runs_node(pid: int) -> bool:
    try:
        args = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    return any(args[i:i + 3] == [b"-m", b"workloads.motion_planning", b"node"] for i in range(len(args)))


def interleaved_runs(names: list[str], *, runs: int, time_limit: float | None, seed: int
                     ) -> tuple[dict[str, list], dict[str, list], tuple[CoresUsed, CoresUsed]]:
    """Run after run: every problem on the robot, then every problem in the cloud through the relay."""
    rospy.init_node("fogiac_demo_client", anonymous=True, disable_signals=True)
    edge: dict[str, list] = {name: [] for name in names}
    cloud: dict[str, list] = {name: [] for name in names}
    problems = {name: load_problem(PROBLEMS_DIR / f"{name}.cfg") for name in names}
    warm_up()
    with WarmPlanner(problems, workers=1) as robot:
        used = CoresUsed(robot.pids), CoresUsed(cloud_planner_pids)
        for run in range(runs):
            seeds = run_seeds(seed, run, names)
            with used[0].measure() as walls:
                solutions = edge_run(robot, names, time_limit=time_limit, seeds=seeds)
                walls += [s.solve_time_s for s in solutions]
            for name, solution in zip(names, solutions, strict=True):
                edge[name].append(solution)
            with used[1].measure() as walls:
                timings = request_paths(names, timeout=300, connect_timeout=120, seeds=seeds)
                walls += [t.round_trip_s for t in timings]
            for timing in timings:
                cloud[timing.name].append(timing)
            print(f"   run {run + 1}/{runs}: " + ", ".join(
                f"{n} {edge[n][-1].solve_time_s:.2f}s/{cloud[n][-1].round_trip_s:.2f}s" for n in names)
                + f" (robot/cloud), load average {os.getloadavg()[0]:.2f}", flush=True)
    return edge, cloud, used


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
    parser.add_argument("--seed", type=int, default=None, help="base seed of the requests; default: a fresh one")
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2**30)
    names = [n for n in args.problems.split(",") if n]
    edge_master = _edge_master(args.manifest)

    print("== fogiac up --target local", flush=True)
    try:
        _fogiac("up", str(args.manifest), "--target", "local", "--yes", "--start-edge-master")
        os.environ.update(ROS_MASTER_URI=edge_master, ROS_HOSTNAME="127.0.0.1")
        print(f"== {args.runs} run(s), each: every problem on the robot (1 core), then in the 'cloud' "
              f"through the relay; both sides search with the same seed per request (--seed {seed})", flush=True)
        edge, cloud, used = interleaved_runs(names, runs=args.runs, time_limit=args.time_limit, seed=seed)
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
    robot_cores, cloud_cores = (u.cores for u in used)
    print("cores the planners got while planning (CPU seconds / wall seconds): robot "
          + (f"{robot_cores:.2f} of 1" if robot_cores is not None else "unknown") + ", cloud "
          + (f"{cloud_cores:.2f} of {os.cpu_count()}" if cloud_cores is not None
             else "unknown (not exactly one motion-planning node on this machine)"))
    return 0 if all(r.cloud_solved for r in rows) else 1


def _edge_master(manifest: Path) -> str:
    uri = load_manifest(manifest).edge.ros_master
    url = urlparse(uri)
    return f"http://{'127.0.0.1' if url.hostname == 'localhost' else url.hostname}:{url.port}"


if __name__ == "__main__":
    sys.exit(main())
