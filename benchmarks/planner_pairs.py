"""Benchmark: the robot's best single core against the cloud's divided search, request by request.

    .venv/bin/python benchmarks/planner_pairs.py [--runs 5] [--cores 2] [--seed 1234] [--paper] [NAMES]

Per request the same seed goes to three warm planners, taking turns: OMPL's RRT-Connect on one
worker (``race``, what the robot ran before), the divided search on one worker (``divide``), and
the divided search on ``--cores`` workers. The divided search depends on the seed alone, so its
one-worker and N-worker runs search the very same trees: the work each of the N workers did
(collision checks, samples) is set against the one-worker total over N. Per problem it prints:

- the robot's baseline: whichever one-core planner had the lower median here (both medians shown);
- the cloud's median time and the speedup (ratio of medians; every pair is also printed);
- work per worker as a share of the one-worker total over N (1.00 = an exact split);
- the share of the search's wall time that was serial (merging, messages; and of its CPU seconds,
  drawing and merging the rounds, which load does not stretch) and the imbalance (waiting for a
  round's last tasks), medians; the search's CPU seconds on one worker over the
  busiest of N's (what load from other jobs does not stretch), and how many cores the N got;
- the speedup at 16 and 96 cores that these figures give by Amdahl's law: a projection, not a
  measurement (no machine with more than 2 cores was measured here).

``--curve 1,2,4,8,16`` measures the divided search alone on each worker count instead (for a machine
with that many cores), ``--runs`` 2 and a 30 s limit per search unless given: per problem and count
the median search and solve time, the speedup of each over the first count, the work per worker
(a share of that run's total over the count) and the total against the first count's, the serial
share (of the wall and of the CPU seconds), the imbalance, the cores the workers got (search, and
the whole solve), solved of runs; then an Amdahl projection to 96 cores from the last count. It
needs only numpy, ompl, python-fcl and trimesh beside this source tree (no fogiac install).
``--paper`` adds the paper-class problems (``problems/paper/``: apartment, home, twistycool); they
may also be named one by one.
Figures are ratios against baselines measured in the same run; the load average is printed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fogiac.procs import cpu_seconds  # noqa: E402
from workloads.motion_planning.paper_problems import PAPER_DIR  # noqa: E402
from workloads.motion_planning.planner import Solution, warm_up  # noqa: E402
from workloads.motion_planning.pool import WarmPlanner  # noqa: E402
from workloads.motion_planning.problem import PROBLEMS_DIR, Problem, load_problem  # noqa: E402
from workloads.motion_planning.rounds import Division  # noqa: E402
from workloads.motion_planning.share import Phases  # noqa: E402

PAIRS_RUNS = 5
CURVE_RUNS = 2  # six problems at 1, 2, 4, 8 and 16 workers in 3-4 minutes on 16 cores (twistycool: half of it)
CURVE_TIME_LIMIT = 30.0  # a search the curve gives up on counts as unsolved, at this time


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def describe(name: str, runs: list[tuple[Solution, Solution, Solution]], cores: int) -> list[str]:
    lines = []
    for race, one, many in runs:
        lines.append(f"  {name:<10} race 1w {race.solve_time_s:6.2f}s  divide 1w {one.solve_time_s:6.2f}s "
                     f"(search {one.plan_time_s:5.2f})  divide {cores}w {many.solve_time_s:6.2f}s "
                     f"(search {many.plan_time_s:5.2f}, pieces {many.pieces}, repairs {many.repairs})  "
                     f"{min(race.solve_time_s, one.solve_time_s) / many.solve_time_s:4.2f}x over the better one core")
    race_t = _median([r.solve_time_s for r, _, _ in runs])
    one_t = _median([o.solve_time_s for _, o, _ in runs])
    many_t = _median([m.solve_time_s for _, _, m in runs])
    best, best_name = (race_t, "race (RRT-Connect)") if race_t < one_t else (one_t, "divide")
    solved = [sum(s.solved for s in side) for side in zip(*runs, strict=True)]
    lines.append(f"  {name}: one core median race {race_t:.2f}s, divide {one_t:.2f}s (baseline: {best_name}); "
                 f"{cores} cores {many_t:.2f}s: speedup {best / many_t:.2f}x; search alone "
                 f"{_median([o.plan_time_s for _, o, _ in runs]) / _median([m.plan_time_s for _, _, m in runs]):.2f}x; "
                 f"solved {solved[0]}/{solved[1]}/{solved[2]} of {len(runs)}")
    split = [(one.division, many.division) for _, one, many in runs
             if one.division is not None and many.division is not None and one.solved and many.solved]
    if not split:
        return lines
    checks = [c * cores / sum(a.checks) for a, b in split for c in b.checks]
    # the same split in CPU seconds: tasks are claimed as workers free up, so time divides evenly even where one
    # worker's samples happened to need more collision checks than the other's (near walls checks cost less)
    seconds = [c * cores / a.cpu_s[0] for a, b in split if a.cpu_s[0] > 0 for c in b.cpu_s]
    spread = [max(abs(c * cores / sum(a.checks) - 1) for c in b.checks) for a, b in split]
    samples = [s * cores / sum(a.samples) for a, b in split if sum(a.samples) for s in b.samples]
    same = sum(sum(a.checks) == sum(b.checks) - sum(b.stolen_checks) for a, b in split)
    stolen = [sum(b.stolen_checks) / sum(a.checks) for a, b in split]
    cpu = [a.cpu_s[0] / max(b.cpu_s) for a, b in split]
    got = [sum(b.cpu_s) / b.wall_s for _, b in split]
    many_div = [b for _, b in split]
    lines.append(f"  {name}: work per worker / (one-worker total / {cores}): checks "
                 f"{min(checks):.2f}-{max(checks):.2f} (a run's widest: median {_median(spread):.0%}), samples "
                 f"{min(samples):.2f}-{max(samples):.2f}, CPU seconds {min(seconds, default=float('nan')):.2f}-"
                 f"{max(seconds, default=float('nan')):.2f}; "
                 f"same total checks as one worker (less those run twice, median {_median(stolen):.1%}) in {same} "
                 f"of {len(split)}; search CPU seconds, one worker / busiest of {cores}: median {_median(cpu):.2f}x "
                 f"(cores the {cores} workers got while searching: median {_median(got):.2f}); serial share median "
                 f"{_median([d.serial_share for d in many_div]):.1%} "
                 f"(max {max(d.serial_share for d in many_div):.1%}; of the CPU seconds "
                 f"{_median([d.serial_cpu_share for d in many_div]):.1%}), imbalance "
                 f"{_median([d.imbalance_s / d.wall_s for d in many_div]):.1%}; projection (Amdahl, these figures): "
                 f"{_median([d.projected_speedup(16) for d in many_div]):.1f}x at 16 cores, "
                 f"{_median([d.projected_speedup(96) for d in many_div]):.1f}x at 96 (from CPU seconds: "
                 f"{_median([d.projected_speedup_cpu(16) for d in many_div]):.1f}x, "
                 f"{_median([d.projected_speedup_cpu(96) for d in many_div]):.1f}x)")
    lines += round_lines(name, many_div)
    lines += phase_lines(name, [m.phases for _, _, m in runs if m.solved and m.phases is not None])
    return lines


def round_lines(name: str, divs: list[Division]) -> list[str]:
    """Per round of the divided search (medians over the runs): the CPU each worker spends drawing and merging
    it (every worker does it all), the tasks' CPU (all workers), and the merge's share of a worker's CPU per
    round; then what those per-sample costs give at 16 workers (batch 4 per worker beyond 8), by Amdahl's law:
    a projection, not a measurement."""
    rows = [(d.rounds, sum(d.samples), sum(d.serial_cpu_s) / len(d.cpu_s), sum(d.cpu_s) - sum(d.serial_cpu_s))
            for d in divs if d.rounds and sum(d.samples) and d.cpu_s]
    if not rows:
        return []
    n = len(divs[0].cpu_s)
    merge = _median([m / r for r, _, m, _ in rows])  # per worker per round
    tasks = _median([t / r for r, _, _, t in rows])  # all workers per round
    per_sample_m = _median([m / s for _, s, m, _ in rows])  # a worker's merge CPU per sample of the round
    per_sample_t = _median([t / s for _, s, _, t in rows])  # the tasks' CPU per sample
    at16 = per_sample_m / (per_sample_m + per_sample_t / 16)
    return [f"  {name}: per round (medians of {len(rows)}; {_median([float(r) for r, *_ in rows]):.0f} rounds, "
            f"{_median([s / r for r, s, _, _ in rows]):.0f} samples each): drawing and merging {merge * 1e3:.2f} ms "
            f"CPU per worker, tasks {tasks * 1e3:.2f} ms CPU over the {n} workers: the merge is "
            f"{merge / (merge + tasks / n):.1%} of a worker's CPU per round; projection (Amdahl from these per-sample "
            f"costs, not a measurement): {at16:.1%} at 16 workers, the search alone at most "
            f"{(per_sample_m + per_sample_t) / (per_sample_m + per_sample_t / 16):.1f}x there"]


def phase_lines(name: str, phases: list[Phases]) -> list[str]:
    """The solve's split by phase in CPU seconds (medians), and its serial share: the part one worker runs
    while the others wait, or every worker repeats (one copy counted), over one worker's equivalent."""
    if not phases:
        return []
    n = phases[0].workers

    def med(f: Callable[[Phases], float]) -> float:
        return _median([f(p) for p in phases])

    return [f"  {name}: the solve in CPU seconds, all {n} workers (medians of {len(phases)}): search "
            f"{med(lambda p: p.search_cpu_s):.3f} (of which drawing and merging, per worker "
            f"{med(lambda p: p.merge_cpu_s):.4f}), lift alone {med(lambda p: p.lift_cpu_s):.4f}, the caller's "
            f"thread {med(lambda p: p.parent_cpu_s):.4f}, finish "
            f"{med(lambda p: sum(p.finish_cpu_s)):.3f} (pieces per worker "
            f"{'/'.join(str(c) for c in phases[0].finish_claims) or '-'}); wall: solve "
            f"{med(lambda p: p.solve_wall_s):.3f} s, search {med(lambda p: p.search_wall_s):.3f}, lift alone "
            f"{med(lambda p: p.lift_wall_s):.4f}, finish {med(lambda p: p.finish_wall_s):.3f} (waiting for the "
            f"last piece {med(lambda p: p.finish_wait_s):.4f}); serial share of the solve's CPU seconds median "
            f"{med(lambda p: p.serial_cpu_share):.2%} (max {max(p.serial_cpu_share for p in phases):.2%}); "
            f"projection (Amdahl on that share, not a measurement): {med(lambda p: p.projected_speedup_cpu(16)):.1f}x "
            f"at 16 cores, {med(lambda p: p.projected_speedup_cpu(96)):.1f}x at 96"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("problems", nargs="*", default=["cubicles", "maze", "twisty"])
    parser.add_argument("--runs", type=int, default=None,
                        help=f"requests per problem and worker count (default {PAIRS_RUNS}; {CURVE_RUNS} with --curve)")
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1234)
    parser.add_argument("--paper", action="store_true", help="add apartment, home and twistycool (problems/paper/)")
    parser.add_argument("--curve", default="", help="worker counts, e.g. 1,2,4,8,16: the measured curve instead")
    parser.add_argument("--time-limit", type=float, default=None,
                        help=f"per search (default: the cfg's; {CURVE_TIME_LIMIT:g} s with --curve)")
    args = parser.parse_args()
    warm_up()
    paths = {name: next((d / f"{name}.cfg" for d in (PROBLEMS_DIR, PAPER_DIR) if (d / f"{name}.cfg").exists()),
                        PROBLEMS_DIR / f"{name}.cfg") for name in args.problems}
    if args.paper:
        paths.update({p.stem: p for p in sorted(PAPER_DIR.glob("*.cfg"))})
    problems = {name: load_problem(path) for name, path in paths.items()}
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    if args.curve:
        curve(problems, [int(n) for n in args.curve.split(",")], runs=args.runs or CURVE_RUNS, seed=args.seed,
              time_limit=args.time_limit or CURVE_TIME_LIMIT)
    else:
        pairs(problems, cores=args.cores, runs=args.runs or PAIRS_RUNS, seed=args.seed)
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


def pairs(problems: dict[str, Problem], *, cores: int, runs: int, seed: int) -> None:
    with WarmPlanner(problems, workers=1, seed=seed, mode="race") as race, \
            WarmPlanner(problems, workers=1, seed=seed, mode="divide") as one, \
            WarmPlanner(problems, workers=cores, seed=seed, mode="divide") as many:
        for name in problems:
            done = []
            for run in range(runs):
                s = seed + 1000 * run
                done.append((race.solve(name, seed=s), one.solve(name, seed=s), many.solve(name, seed=s)))
            print("\n".join(describe(name, done, cores)), flush=True)


def curve(problems: dict[str, Problem], counts: list[int], *, runs: int, seed: int,
          time_limit: float | None) -> None:
    """The divided search on each worker count, the same seeds (the same searches up to 8 workers; beyond,
    a bigger batch per round). Per problem and count, printed as measured (one warm pool per count, every
    problem loaded once): median search and solve time and their speedup over the first count, the work
    per worker, the serial share and imbalance of the search, and the cores the workers got over the
    whole solve (search, lift and finish). For a machine with that many cores."""
    first: dict[str, tuple[float, float, float]] = {}
    last: dict[str, list[Division]] = {}
    for n in counts:
        with WarmPlanner(problems, workers=n, seed=seed, mode="divide") as planner:
            for name in problems:
                rows = [_timed(planner, name, seed + 1000 * run, time_limit) for run in range(runs)]
                sols = [s for s, _ in rows]
                # an unsolved request counts at the time it took (about the limit), not as a 0 s search
                search = _median([s.plan_time_s if s.solved else s.solve_time_s for s in sols])
                solve = _median([s.solve_time_s for s in sols])
                divs = [d for s in sols if s.solved and (d := s.division) is not None and d.checks]
                checks = _median([float(sum(d.checks) - sum(d.stolen_checks)) for d in divs])
                search0, solve0, checks0 = first.setdefault(name, (search, solve, checks))
                # each worker's checks over its run's total / n (1.00: an exact split), and the median run's
                # total against the first count's (above 1: the bigger batch beyond 8 workers cost extra work)
                split = [c * n / sum(d.checks) for d in divs for c in d.checks if sum(d.checks)]
                print(f"  {name:<10} {n:>3} workers: search {search:6.2f}s ({search0 / search:5.2f}x), solve "
                      f"{solve:6.2f}s ({solve0 / solve:5.2f}x); work per worker "
                      f"{min(split, default=0):.2f}-{max(split, default=0):.2f} of total/{n}, total "
                      f"{checks / checks0 if checks0 else float('nan'):.2f}x {counts[0]} worker's; serial share "
                      f"{_median([d.serial_share for d in divs]):.1%} (of the CPU seconds "
                      f"{_median([d.serial_cpu_share for d in divs]):.1%}), imbalance "
                      f"{_median([d.imbalance_s / d.wall_s for d in divs if d.wall_s]):.1%}; cores used: search "
                      f"{_median([sum(d.cpu_s) / d.wall_s for d in divs if d.wall_s]):.2f}, solve "
                      f"{_median([c for _, c in rows]):.2f}; solved {sum(s.solved for s in sols)}/{runs}",
                      flush=True)
                # per round and per phase at this count: on a many-core machine, where the merge's share and the
                # solve's serial CPU are measured rather than projected
                phases = [s.phases for s in sols if s.solved and s.phases is not None]
                for line in round_lines(name, divs) + phase_lines(name, phases):
                    print(f"  {n:>3} workers {line.strip()}", flush=True)
                last[name] = divs
    for name, divs in last.items():
        if divs:
            print(f"  {name:<10} projection (Amdahl, {counts[-1]} workers' figures): "
                  f"{_median([d.projected_speedup(96) for d in divs]):.1f}x at 96 cores (from CPU seconds: "
                  f"{_median([d.projected_speedup_cpu(96) for d in divs]):.1f}x)", flush=True)


def _timed(planner: WarmPlanner, name: str, seed: int, time_limit: float | None) -> tuple[Solution, float]:
    """A solve, and the cores its workers got over it (their CPU seconds over its wall seconds)."""
    pids = planner.pids()
    cpu = sum(map(cpu_seconds, pids))
    solution = planner.solve(name, seed=seed, time_limit=time_limit)
    used = sum(map(cpu_seconds, pids)) - cpu
    return solution, used / solution.solve_time_s if solution.solve_time_s > 0 else 0.0


if __name__ == "__main__":
    main()
