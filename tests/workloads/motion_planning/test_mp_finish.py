"""The divided finish: the found path's pieces claimed from a shared counter, lifted, simplified and proven
by all the workers, with no step where one worker lifts the whole path while the others wait."""

from __future__ import annotations

import pytest
from tests.workloads.motion_planning.mp_support import PROBLEMS

from workloads.motion_planning import Pose, load_problem, path_is_collision_free
from workloads.motion_planning.pool import FINISH_PIECES_PER_WORKER, WarmPlanner
from workloads.motion_planning.share import Phases, cut_indices, split_path


def test_cut_indices_are_where_split_path_cuts() -> None:
    line = [Pose(float(i), 0.0, 0.0) for i in range(10)]
    assert cut_indices(line, 3, radius=1.0) == [0, 3, 6, 9]
    assert [line[a:b + 1] for a, b in zip([0, 3, 6], [3, 6, 9], strict=True)] == split_path(line, 3, radius=1.0)
    assert cut_indices(line[:2], 4, radius=1.0) == [0, 1]  # one segment: one piece


def test_the_serial_share_counts_one_copy_of_the_merges_and_the_lone_lift() -> None:
    # 2 workers: search 4.0 CPU s of which 0.1 per worker drawing and merging; a lone lift of 0.05; finish 1.0 + 0.9
    phases = Phases(2, 3.0, 2.0, 4.0, 0.1, 0.06, 0.05, 1.0, (1.0, 0.9), (0.95, 0.85), (3, 3))
    assert phases.total_cpu_s == pytest.approx(5.95)
    assert phases.serial_cpu_s == pytest.approx(0.15)
    # one worker's equivalent: 5.95 less the second copy of the merges (0.1) = 5.85
    assert phases.serial_cpu_share == pytest.approx(0.15 / 5.85)
    assert phases.finish_wait_s == pytest.approx(0.1)
    share = 0.15 / 5.85
    assert phases.projected_speedup_cpu(16) == pytest.approx(1 / (share + (1 - share) / 16))


def test_two_workers_claim_the_pieces_and_the_answer_is_proven() -> None:
    # the straight move hits the wall beside the window, so there is a planned path to cut
    problem = load_problem(PROBLEMS / "easy.cfg").with_endpoints(Pose(-2.0, 2.0, 0.0), Pose(2.0, 2.0, 0.0))
    with WarmPlanner({"easy": problem}, workers=2, seed=5, mode="divide") as planner:
        solutions = [planner.solve("easy", time_limit=20, seed=s) for s in (1, 2, 3)]
        refinished = planner.refinished
    for s in solutions:
        assert s.solved and s.path[0] == problem.start and s.path[-1] == problem.goal
        assert path_is_collision_free(problem, s.path, resolution=s.resolution / 5)
        phases = s.phases
        assert phases is not None and phases.workers == 2
        assert phases.lift_cpu_s == 0.0 and phases.lift_wall_s == 0.0  # no worker lifted the whole path alone
        assert 1 <= s.pieces <= FINISH_PIECES_PER_WORKER * 2 + (refinished > 0)
        if not refinished:  # every piece claimed by exactly one worker
            assert sum(phases.finish_claims) == s.pieces and len(phases.finish_cpu_s) == 2
        assert 0.0 < phases.serial_cpu_share < 1.0


def test_one_worker_lifts_then_finishes_the_whole_path() -> None:
    problem = load_problem(PROBLEMS / "easy.cfg").with_endpoints(Pose(-2.0, 2.0, 0.0), Pose(2.0, 2.0, 0.0))
    with WarmPlanner({"easy": problem}, workers=1, seed=5, mode="divide") as planner:
        s = planner.solve("easy", time_limit=20, seed=1)
    assert s.solved and s.pieces == 1 and s.phases is not None and s.phases.finish_claims == (1,)
    assert path_is_collision_free(problem, s.path, resolution=s.resolution / 5)
