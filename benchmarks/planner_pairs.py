"""Benchmark: one core and two on the same draw, request by request (no ROS, no relay).

    .venv/bin/python benchmarks/planner_pairs.py [--runs 8] [--seed 1234] [cubicles maze twisty]

A warm 1-worker planner (the robot) and a warm 2-worker planner in ``share`` mode (the cloud)
get the same requests with the same seed, taking turns, so the cloud's worker 0 repeats the
robot's search exactly (``WarmPlanner.solve(seed=)``) and worker 1 makes a second draw. Per
problem it prints each pair and then where the second core's time went: how often worker 1's
draw won the race, the speedup when it did and when it did not, the search's and the
simplifying's share of each side's time, and how much slower worker 0 ran the very same
search beside a busy worker 1 (contention for the machine, not planning). Figures are ratios
against the 1-worker side measured in the same run.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from workloads.motion_planning.planner import Solution, warm_up  # noqa: E402
from workloads.motion_planning.pool import WarmPlanner  # noqa: E402
from workloads.motion_planning.problem import PROBLEMS_DIR, load_problem  # noqa: E402


def describe(name: str, pairs: list[tuple[Solution, Solution]]) -> list[str]:
    lines = []
    for robot, cloud in pairs:
        lines.append(f"  {name:<9} robot {robot.solve_time_s:5.2f}s ({_parts(robot)})  "
                     f"cloud {cloud.solve_time_s:5.2f}s (worker {cloud.winner} won, {_parts(cloud)}, "
                     f"pieces {cloud.pieces})  "
                     f"{robot.solve_time_s / cloud.solve_time_s:4.2f}x")
    solved = [(r, c) for r, c in pairs if r.solved and c.solved]
    second = [(r, c) for r, c in solved if c.winner == 1]
    first = [(r, c) for r, c in solved if c.winner == 0]

    def ratio(group: list[tuple[Solution, Solution]]) -> str:
        return f"{statistics.median(r.solve_time_s / c.solve_time_s for r, c in group):.2f}x" if group else "-"

    same = [c.plan_time_s / r.plan_time_s for r, c in first if r.plan_time_s > 0.05]
    lines.append(f"  {name}: speedup median {ratio(solved)} over {len(solved)} of {len(pairs)} pairs solved; "
                 f"worker 1's draw won {len(second)} ({ratio(second)}), worker 0's {len(first)} ({ratio(first)}); "
                 f"search share of time robot {_share(solved, 0):.0%}, cloud {_share(solved, 1):.0%}; "
                 f"simplify robot/cloud {_simplify_ratio(solved):.2f}x; same search beside a busy worker: "
                 + (f"{statistics.median(same):.2f}x as long" if same else "-"))
    return lines


def _parts(s: Solution) -> str:
    """Search, simplify, and the rest (proving, repairs, passing pieces about), in seconds."""
    rest = s.solve_time_s - s.plan_time_s - s.simplify_time_s
    return f"search {s.plan_time_s:4.2f}, simplify {s.simplify_time_s:4.2f}, rest {rest:4.2f}, repairs {s.repairs}"


def _share(pairs: list[tuple[Solution, Solution]], side: int) -> float:
    """The search's share of one side's time, over all pairs."""
    done = [p[side] for p in pairs]
    total = sum(s.solve_time_s for s in done)
    return sum(s.plan_time_s for s in done) / total if total > 0 else 0.0


def _simplify_ratio(pairs: list[tuple[Solution, Solution]]) -> float:
    """Median of the robot's simplifying time over the cloud's (its slowest piece)."""
    ratios = [r.simplify_time_s / c.simplify_time_s for r, c in pairs if c.simplify_time_s > 0]
    return statistics.median(ratios) if ratios else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("problems", nargs="*", default=["cubicles", "maze", "twisty"])
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1234)
    args = parser.parse_args()
    warm_up()
    problems = {name: load_problem(PROBLEMS_DIR / f"{name}.cfg") for name in args.problems}
    with WarmPlanner(problems, workers=1, seed=args.seed) as robot, \
            WarmPlanner(problems, workers=2, seed=args.seed + 1, mode="share") as cloud:
        for name in args.problems:
            pairs = []
            for run in range(args.runs):
                seed = args.seed + 1000 * run
                pairs.append((robot.solve(name, seed=seed), cloud.solve(name, seed=seed)))
            print("\n".join(describe(name, pairs)), flush=True)


if __name__ == "__main__":
    main()
