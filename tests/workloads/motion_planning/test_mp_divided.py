"""The divided search: k workers share one search (counted, not timed), seeded, merged in order."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from tests.workloads.motion_planning.mp_support import PROBLEMS

from workloads.motion_planning import Pose, load_problem, path_is_collision_free
from workloads.motion_planning.divided import Trees, as_array, batch_size, merge_round
from workloads.motion_planning.paper_problems import PAPER_DIR
from workloads.motion_planning.pool import WarmPlanner
from workloads.motion_planning.rounds import LAG, Division


@pytest.fixture(scope="module")
def planners() -> Iterator[tuple[WarmPlanner, WarmPlanner]]:
    problems = {"cubicles": load_problem(PROBLEMS / "cubicles.cfg")}
    with WarmPlanner(problems, workers=1, seed=2, mode="divide") as one, \
            WarmPlanner(problems, workers=2, seed=9, mode="divide") as two:
        yield one, two


@pytest.mark.parametrize("seed", [21, 4021])
def test_two_workers_do_one_workers_search_between_them(planners: tuple[WarmPlanner, WarmPlanner],
                                                        seed: int) -> None:
    """Same seed: the same trees, so the same total of collision checks and samples, split between two."""
    one, two = planners
    alone, shared = one.solve("cubicles", seed=seed), two.solve("cubicles", seed=seed)
    assert alone.solved and shared.solved
    a, b = alone.division, shared.division
    assert a is not None and b is not None
    assert (len(a.checks), len(b.checks)) == (1, 2)
    # a task still running after the others were done may be run again by a waiting worker (its
    # worker parked by the kernel): the same outcome, its checks counted apart
    assert (sum(b.checks) - sum(b.stolen_checks), sum(b.samples), b.rounds) == (a.checks[0], a.samples[0], a.rounds)
    # the rounds merged, and LAG more whose tasks ran while the last merged round's were finishing
    assert a.rounds > 1 and a.samples[0] == (a.rounds + LAG) * batch_size(1)
    # claimed one at a time: each worker did a real part of it (not a copy of the whole, not nothing)
    assert all(0.25 * a.checks[0] < c < 0.75 * a.checks[0] for c in b.checks)
    assert all(s > 0 for s in b.samples)
    problem = load_problem(PROBLEMS / "cubicles.cfg")
    assert path_is_collision_free(problem, shared.path, resolution=shared.resolution / 5)
    assert path_is_collision_free(problem, alone.path, resolution=alone.resolution / 5)


def test_a_seed_repeats_the_search_and_another_changes_it(planners: tuple[WarmPlanner, WarmPlanner]) -> None:
    one, _ = planners
    first, again, other = (one.solve("cubicles", seed=s) for s in (77, 77, 78))
    assert first.division is not None and again.division is not None and other.division is not None
    assert (first.division.checks, first.division.rounds) == (again.division.checks, again.division.rounds)
    assert first.division.checks != other.division.checks


def test_a_straight_move_needs_no_search(planners: tuple[WarmPlanner, WarmPlanner]) -> None:
    _, two = planners
    start = load_problem(PROBLEMS / "cubicles.cfg").start
    goal = Pose(start.x + 0.4, start.y, start.z)
    solution = two.solve("cubicles", start=start, goal=goal, seed=1)
    assert solution.solved and solution.division is not None and solution.division.rounds == 0
    assert solution.path[0] == start and solution.path[-1] == goal


def _pose(x: float) -> np.ndarray:
    return as_array(Pose(x, 0.0, 0.0))


def test_the_merge_keeps_task_order_and_joins_the_lowest_task() -> None:
    """Results arrive in any order; nodes are numbered in task order, a chain hangs off its origin."""
    trees = Trees(_pose(0.0), _pose(10.0))
    results = [  # (task, tree, near, new, y, chain, joined, goes on)
        (2, 0, 0, _pose(2.0), 0, [_pose(8.0)], False, True),
        (0, 1, 0, _pose(9.0), 0, [], False, False),
        (1, 0, 0, None, -1, [], False, False),  # did not move
    ]
    merge, pending, path = merge_round(trees, results)
    assert path is None
    assert trees.poses[0][:, 0].tolist() == [0.0, 2.0] and trees.parents[0].tolist() == [-1, 0]
    assert trees.poses[1][:, 0].tolist() == [10.0, 9.0, 8.0] and trees.parents[1].tolist() == [-1, 0, 0]
    assert pending == [(0, 1, 2)]  # the goal tree's node 2 (x = 8) goes on toward the start tree's node 1
    assert [len(p) for _, p in merge] == [1, 2]
    joined = [(1, 0, 1, None, 2, [], True, False),  # the connect going on reached x = 2 ...
              (0, 0, 1, _pose(4.0), 2, [], True, False)]  # ... and so did a new node; task 0 wins
    _, _, path = merge_round(trees, joined)
    assert path is not None and [p.x for p in path] == [0.0, 2.0, 4.0, 8.0, 10.0]


def test_figures_and_projection() -> None:
    reports = [{"checks": 60, "samples": 30, "rounds": 7, "busy_s": 3.0, "wait_s": 0.5, "stolen_checks": 0,
                "cpu_s": 3.2, "serial_cpu_s": 0.1},
               {"checks": 40, "samples": 34, "rounds": 6, "busy_s": 2.0, "wait_s": 1.5, "stolen_checks": 10,
                "cpu_s": 3.1, "serial_cpu_s": 0.2}]
    d = Division.from_reports(reports, wall_s=4.5)
    assert (d.checks, d.samples, d.rounds, d.stolen_checks) == ((60, 40), (30, 34), 7, (0, 10))
    # waiting for a round's last tasks, averaged: 1 s; serial: the rest of the wall beside the average task time
    assert d.imbalance_s == pytest.approx(1.0) and d.serial_s == pytest.approx(4.5 - 2.5 - 1.0)
    assert d.serial_share == pytest.approx(1.0 / 4.5)
    # and in CPU seconds, which other jobs' load does not stretch: samples and merge over the search's CPU
    assert d.serial_cpu_share == pytest.approx(0.3 / 6.3)
    # Amdahl: 2 s serial (imbalance counted in) stays; 5 s of tasks less the 10% run twice (0.5 s) divide
    assert d.projected_speedup(16) == pytest.approx((2.0 + 4.5) / (2.0 + 4.5 / 16))
    # on CPU seconds: one worker's serial CPU (0.15 s) stays; the rest (6.0 s, less the 10% run twice) divides
    assert d.projected_speedup_cpu(16) == pytest.approx((0.15 + 5.4) / (0.15 + 5.4 / 16))


def test_blocked_motions_stop_short_of_the_wall() -> None:
    """A node at the last pose a blocked motion passed touches the wall; as a path vertex it can be neither
    lifted clear nor proven (home, seed 1234: "unproven path" after 3 failed repairs). Backed off, it is."""
    problem = load_problem(PAPER_DIR / "home.cfg")
    with WarmPlanner({"home": problem}, workers=1, seed=3, mode="divide") as planner:
        solution = planner.solve("home", seed=1234)
    assert solution.solved and solution.repairs == 0, (solution.status, solution.repairs)
    assert path_is_collision_free(problem, solution.path, resolution=solution.resolution / 5)
