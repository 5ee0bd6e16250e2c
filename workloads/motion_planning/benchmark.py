"""Benchmark of the race and share modes: every problem N times on 1 core and on all cores, cold and
warm; medians, speedup. The divided search (the default mode) has its own: ``benchmarks/planner_pairs.py``.

``python -m workloads.motion_planning.benchmark --runs 10 --out benchmarks/out``

Cold is :func:`solve` (workers started and collision models built per request); warm is a
:class:`WarmPlanner` per core count, kept for the whole benchmark, racing (``warm``) or, on N
cores, also sharing the finish of the first path between the workers (``share``, ``share.py``). "overhead" is the median
wall time of a request that needs no search (both endpoints in one open room, one straight
segment), cold and warm: what a request costs beyond planning.

Runs are paired and interleaved: run i uses seed ``seed + 1000 i`` on 1 core and, right after,
the same seed for worker 0 of the multi-core race (the others take the next seeds), so a
multi-core run is never a worse draw than its 1-core twin, only a luckier one or a slower one
through contention, and load that drifts during the benchmark hits both sides alike. Warm
requests carry the same seed (``WarmPlanner.solve(seed=)``), so warm worker 0 repeats the 1-core
search too.
Failed runs count with their elapsed time (about the time limit), so medians stay honest.
Figures are ratios against the 1-core baseline measured in the same run. "work speedup" is
the ratio of median collision checks the winner needed before its first path: what the race
saves in work, which CPU contention from other jobs on the machine cannot distort (time can).
"cpu speedup" is the same idea for the whole request, warm: median CPU seconds on the critical
path (the winner's search, then its finish or the slowest piece's) on 1 core / on N cores.
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
from workloads.motion_planning.pool import WarmPlanner
from workloads.motion_planning.problem import PROBLEMS_DIR, Pose, Problem, load_problem


@dataclass(frozen=True)
class Row:
    problem: str
    mode: str  # cold | warm | share
    cores: int
    runs: int
    success_rate: float
    median_solve_s: float
    median_plan_s: float
    median_checks: float  # collision checks to the first path; a failed run counts as infinite
    median_cpu_s: float  # CPU seconds on the critical path (warm only; cold reports it too)
    times_s: tuple[float, ...]


def measure(name: str, problem: Problem, warm: dict[tuple[str, int], WarmPlanner], *, cores: Sequence[int], runs: int,
            seed: int, time_limit: float | None) -> list[Row]:
    """Interleaved: run i goes cold, warm, share on each core count, back to back, so load drift hits all alike."""
    results: dict[tuple[str, int], list[Solution]] = {("cold", c): [] for c in cores}
    results.update({key: [] for key in warm})
    for i in range(runs):
        for c in cores:
            results[("cold", c)].append(solve(problem, cores=c, time_limit=time_limit, seed=seed + 1000 * i,
                                                    mode="race"))
            for mode in ("warm", "share"):
                if (mode, c) in warm:
                    results[(mode, c)].append(warm[(mode, c)].solve(name, time_limit=time_limit,
                                                                    seed=seed + 1000 * i))
    rows = []
    for (mode, c), done in results.items():
        times = tuple(r.solve_time_s for r in done)
        plan = [r.plan_time_s if r.solved else r.solve_time_s for r in done]
        checks = [r.collision_checks if r.solved else float("inf") for r in done]
        cpu = [r.cpu_s if r.solved else float("inf") for r in done]
        rows.append(Row(name, mode, c, runs, sum(r.solved for r in done) / runs, statistics.median(times),
                        statistics.median(plan), statistics.median(checks), statistics.median(cpu), times))
    return rows


def overhead_ms(name: str, problem: Problem, warm: WarmPlanner, *, requests: int = 20) -> tuple[float, float]:
    """Median ms of a request needing no search (start and goal 0.5 apart in free space), cold and warm.

    No simplification either side: what is left is starting workers, loading models (cold only),
    passing the request and the answer, and proving the one segment.
    """
    start = problem.start
    goal = Pose(start.x, start.y + 0.5, start.z, start.qx, start.qy, start.qz, start.qw)
    trivial = problem.with_endpoints(start, goal)
    cold, hot = [], []
    for _ in range(requests):
        cold.append(solve(trivial, cores=warm.workers, simplify_time=0.0, mode="race").solve_time_s)
        hot.append(warm.solve(name, start=start, goal=goal, simplify_time=0.0).solve_time_s)
    return statistics.median(cold) * 1e3, statistics.median(hot) * 1e3


def _get(rows: Sequence[Row], name: str, mode: str, cores: int) -> Row:
    return next(r for r in rows if r.problem == name and r.mode == mode and r.cores == cores)


def table(rows: Sequence[Row], cores: int) -> str:
    n = cores
    lines = [f"{'problem':<10} {'cold 1c s':>10} {f'cold {n}c s':>10} {'warm 1c s':>10} {f'warm {n}c s':>10} "
             f"{f'share {n}c s':>11} {'speedup cold':>13} {'warm':>6} {'share':>6} {'warm/cold':>10} "
             f"{'work speedup':>13} {'cpu warm':>9} {'cpu share':>10} {'solved':>16}"]
    for name in dict.fromkeys(r.problem for r in rows):
        c1, cn, w1, wn, sn = (_get(rows, name, m, c) for m, c in (("cold", 1), ("cold", n), ("warm", 1),
                                                                   ("warm", n), ("share", n)))
        solved = "/".join(f"{r.success_rate:.0%}" for r in (c1, cn, w1, wn, sn))
        lines.append(f"{name:<10} {c1.median_solve_s:>10.3f} {cn.median_solve_s:>10.3f} {w1.median_solve_s:>10.3f} "
                     f"{wn.median_solve_s:>10.3f} {sn.median_solve_s:>11.3f} "
                     f"{c1.median_solve_s / cn.median_solve_s:>12.2f}x {w1.median_solve_s / wn.median_solve_s:>5.2f}x "
                     f"{w1.median_solve_s / sn.median_solve_s:>5.2f}x {cn.median_solve_s / wn.median_solve_s:>9.2f}x "
                     f"{c1.median_checks / cn.median_checks:>12.2f}x {w1.median_cpu_s / wn.median_cpu_s:>8.2f}x "
                     f"{w1.median_cpu_s / sn.median_cpu_s:>9.2f}x {solved:>16}")
    lines.append("speedup = 1 core / N cores (medians; warm 1 core is the baseline of warm and share); warm/cold = "
                 "cold N / warm N; work speedup = collision checks to the first path, cold 1 / cold N; cpu = CPU "
                 "seconds on the critical path, warm 1 / warm or share N")
    return "\n".join(lines)


def plot(rows: Sequence[Row], cores: int, path: Path) -> None:
    import matplotlib  # noqa: PLC0415 (only --plot draws; the backend must be set before pyplot loads)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    names = list(dict.fromkeys(r.problem for r in rows))
    one = [_get(rows, n, "cold", 1) for n in names]
    many = [_get(rows, n, "cold", cores) for n in names]
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
    problems = {name: load_problem(PROBLEMS_DIR / f"{name}.cfg") for name in names}
    warm_up()
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    rows = []
    with WarmPlanner(problems, workers=1, seed=args.seed, mode="race") as warm1, \
            WarmPlanner(problems, workers=args.cores, seed=args.seed + 500, mode="race") as warm_n, \
            WarmPlanner(problems, workers=args.cores, seed=args.seed + 700, mode="share") as share_n:
        warm = {("warm", 1): warm1, ("warm", args.cores): warm_n, ("share", args.cores): share_n}
        cold_ms, warm_ms = overhead_ms(names[0], problems[names[0]], warm_n)
        for name in names:
            for row in measure(name, problems[name], warm, cores=(1, args.cores), runs=args.runs, seed=args.seed,
                               time_limit=args.time_limit):
                print(f"  {name} {row.mode} on {row.cores} core(s): median {row.median_solve_s:.3f} s, "
                      f"{row.success_rate:.0%} solved", flush=True)
                rows.append(row)
    print(table(rows, args.cores))
    print(f"per-request overhead ({names[0]}, {args.cores} workers, a request needing no search): "
          f"cold {cold_ms:.1f} ms, warm {warm_ms:.1f} ms")
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "motion_planning.json").write_text(json.dumps(
        {"rows": [asdict(r) for r in rows], "overhead_ms": {"cold": cold_ms, "warm": warm_ms}}, indent=1))
    plot(rows, args.cores, args.out / "motion_planning.png")
    print(f"wrote {args.out / 'motion_planning.png'} and {args.out / 'motion_planning.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
