"""Benchmark: every problem N times on 1 core and on all cores; medians, success, speedup.

``python -m workloads.motion_planning.benchmark --runs 10 --out benchmarks/out``

Runs are paired and interleaved: run i uses seed ``seed + 1000 i`` on 1 core and, right after,
the same seed for worker 0 of the multi-core race (the others take the next seeds), so a
multi-core run is never a worse draw than its 1-core twin, only a luckier one or a slower one
through contention, and load that drifts during the benchmark hits both sides alike.
Failed runs count with their elapsed time (about the time limit), so medians stay honest.
Figures are ratios against the 1-core baseline measured in the same run. "work speedup" is
the ratio of median collision checks the winner needed before its first path: what the race
saves in work, which CPU contention from other jobs on the machine cannot distort (time can).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from workloads.motion_planning.planner import Solution, solve, warm_up
from workloads.motion_planning.problem import PROBLEMS_DIR, load_problem


@dataclass(frozen=True)
class Row:
    problem: str
    cores: int
    runs: int
    success_rate: float
    median_solve_s: float
    median_plan_s: float
    median_checks: float  # collision checks to the first path; a failed run counts as infinite
    times_s: tuple[float, ...]


def measure(cfg: Path, *, cores: Sequence[int], runs: int, seed: int, time_limit: float | None) -> list[Row]:
    """Interleaved: run i goes 1 core, then N cores, back to back, so load drift hits both alike."""
    problem = load_problem(cfg)
    results: dict[int, list[Solution]] = {c: [] for c in cores}
    for i in range(runs):
        for c in cores:
            results[c].append(solve(problem, cores=c, time_limit=time_limit, seed=seed + 1000 * i))
    rows = []
    for c, done in results.items():
        times = tuple(r.solve_time_s for r in done)
        plan = [r.plan_time_s if r.solved else r.solve_time_s for r in done]
        checks = [r.collision_checks if r.solved else float("inf") for r in done]
        rows.append(Row(problem.name, c, runs, sum(r.solved for r in done) / runs, statistics.median(times),
                        statistics.median(plan), statistics.median(checks), times))
    return rows


def table(rows: Sequence[Row], cores: int) -> str:
    lines = [f"{'problem':<10} {'1-core median s':>16} {f'{cores}-core median s':>17} {'speedup':>8} "
             f"{'plan speedup':>13} {'work speedup':>13} {'success 1/' + str(cores):>12}"]
    for name in dict.fromkeys(r.problem for r in rows):
        one = next(r for r in rows if r.problem == name and r.cores == 1)
        many = next(r for r in rows if r.problem == name and r.cores == cores)
        lines.append(f"{name:<10} {one.median_solve_s:>16.3f} {many.median_solve_s:>17.3f} "
                     f"{one.median_solve_s / many.median_solve_s:>7.2f}x "
                     f"{one.median_plan_s / many.median_plan_s:>12.2f}x "
                     f"{one.median_checks / many.median_checks:>12.2f}x "
                     f"{one.success_rate:>6.0%}/{many.success_rate:.0%}")
    return "\n".join(lines)


def plot(rows: Sequence[Row], cores: int, path: Path) -> None:
    import matplotlib  # noqa: PLC0415 (only --plot draws; the backend must be set before pyplot loads)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    names = list(dict.fromkeys(r.problem for r in rows))
    one = [next(r for r in rows if r.problem == n and r.cores == 1) for n in names]
    many = [next(r for r in rows if r.problem == n and r.cores == cores) for n in names]
    fig, ax = plt.subplots(figsize=(7, 4))
    xs = range(len(names))
    ax.bar([x - 0.2 for x in xs], [r.median_solve_s for r in one], width=0.4, label="1 core")
    ax.bar([x + 0.2 for x in xs], [r.median_solve_s for r in many], width=0.4, label=f"{cores} cores")
    for x, a, b in zip(xs, one, many, strict=True):
        label = f"time {a.median_solve_s / b.median_solve_s:.2f}x\nwork {a.median_checks / b.median_checks:.2f}x"
        ax.annotate(label, (x, max(a.median_solve_s, b.median_solve_s)), ha="center", va="bottom", fontsize=8)
    ax.set_xticks(list(xs), names)
    ax.set_ylabel("median solve time (s)")
    ax.margins(y=0.2)
    ax.set_title(f"SE(3) planning, RRTConnect race: 1 vs {cores} cores ({one[0].runs} runs each)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m workloads.motion_planning.benchmark")
    parser.add_argument("problems", nargs="*", help="problem names in problems/ (default: all)")
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--cores", type=int, default=os.cpu_count() or 1, help="the multi-core side (default: all)")
    parser.add_argument("--time-limit", type=float, default=None, help="seconds (default: each cfg's)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/out"))
    args = parser.parse_args(argv)
    names = args.problems or sorted(p.stem for p in PROBLEMS_DIR.glob("*.cfg"))
    warm_up()
    rows = []
    for name in names:
        for row in measure(PROBLEMS_DIR / f"{name}.cfg", cores=(1, args.cores), runs=args.runs, seed=args.seed,
                           time_limit=args.time_limit):
            print(f"  {name} on {row.cores} core(s): median {row.median_solve_s:.3f} s, "
                  f"{row.success_rate:.0%} solved", flush=True)
            rows.append(row)
    print(table(rows, args.cores))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "motion_planning.json").write_text(json.dumps([asdict(r) for r in rows], indent=1))
    plot(rows, args.cores, args.out / "motion_planning.png")
    print(f"wrote {args.out / 'motion_planning.png'} and {args.out / 'motion_planning.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
