"""Sharing a request between warm workers: the first path cut into pieces, each finished by one worker."""

from __future__ import annotations

import math
import time

import pytest
from tests.workloads.motion_planning.mp_support import PROBLEMS

from fogiac.errors import WorkloadError
from workloads.motion_planning import Pose, load_problem, path_is_collision_free
from workloads.motion_planning.pool import WarmPlanner
from workloads.motion_planning.problem import validity_resolution
from workloads.motion_planning.share import join_reports, simplify_shares, split_path


def _line(n: int) -> list[Pose]:
    return [Pose(float(i), 0.0, 0.0) for i in range(n)]


def test_pieces_have_equal_sweep_and_share_their_joints() -> None:
    pieces = split_path(_line(9), 2, radius=1.0)
    assert pieces == [_line(9)[:5], _line(9)[4:]]
    assert [len(p) for p in split_path(_line(10), 3, radius=1.0)] == [4, 4, 4]
    assert split_path(_line(2), 4, radius=1.0) == [_line(2)]  # one segment: nothing to cut
    assert len(split_path(_line(3), 4, radius=1.0)) == 2  # cuts fall on vertices only
    # a half turn on the spot (pi * radius) weighs more than each unit move after it
    half_turn = (0.0, 0.0, math.sin(math.pi / 2), math.cos(math.pi / 2))
    turning = [Pose(0.0, 0.0, 0.0), *(Pose(float(i), 0.0, 0.0, *half_turn) for i in range(5))]
    assert [len(p) for p in split_path(turning, 2, radius=1.0)] == [2, 5]


def test_the_simplification_budget_is_shared_by_sweep() -> None:
    assert simplify_shares(split_path(_line(9), 2, radius=1.0), 0.5, radius=1.0) == [0.25, 0.25]
    assert simplify_shares([_line(4), _line(2)], 0.4, radius=1.0) == pytest.approx([0.3, 0.1])
    assert simplify_shares([[Pose(0.0, 0.0, 0.0)] * 2] * 2, 0.4, radius=1.0) == [0.2, 0.2]


def test_joined_reports() -> None:
    first = {"plan_time_s": 0.1, "checks": 10, "cpu_s": 1.0, "index": 1}
    a = {"solved": True, "status": "exact solution", "path": [(0,), (1,)], "cpu_s": 0.5, "simplify_time_s": 0.2,
         "repairs": 1, "clearance_queries": 3, "resolution": 0.1, "check_resolution": 0.01}
    b = {**a, "path": [(1,), (2,), (3,)], "cpu_s": 0.7, "repairs": 0}
    joined = join_reports(first, [a, b])
    assert joined["path"] == [(0,), (1,), (2,), (3,)] and joined["solved"]
    assert (joined["cpu_s"], joined["repairs"], joined["pieces"], joined["index"]) == (1.7, 1, 2, 1)
    unproven = join_reports(first, [a, {**b, "solved": False, "status": "unproven path", "path": []}])
    assert (unproven["solved"], unproven["status"], unproven["path"]) == (False, "unproven path", [])
    died = join_reports(first, [a, None])
    assert (died["solved"], died["path"]) == (False, [])


@pytest.mark.parametrize("mode", ["race", "share"])
def test_both_modes_answer_proven_paths(mode: str) -> None:
    # the straight move hits the wall beside the window, so there is a planned path to cut
    problem = load_problem(PROBLEMS / "easy.cfg").with_endpoints(Pose(-2.0, 2.0, 0.0), Pose(2.0, 2.0, 0.0))
    with WarmPlanner({"easy": problem}, workers=2, seed=5, mode=mode) as planner:
        solutions = [planner.solve("easy", time_limit=20) for _ in range(2)]
        straight = planner.solve("easy", start=problem.start, goal=Pose(-2.0, 1.0, 0.0))
    for s in solutions:
        assert s.solved and s.path[0] == problem.start and s.path[-1] == problem.goal
        assert s.pieces == (2 if mode == "share" else 1) and s.cpu_s > 0
        assert path_is_collision_free(problem, s.path, resolution=s.resolution / 5)
    # a free straight move is answered without a search: two poses, one piece
    assert straight.solved and straight.path == (problem.start, Pose(-2.0, 1.0, 0.0)) and straight.pieces == 1


def test_a_piece_that_cannot_be_proven_is_finished_whole() -> None:
    # The cut falls on the first path's middle pose, here inside the wall: neither piece can be
    # proven (a cut pose stays in the answer), the whole path can once it is shortcut past that pose.
    problem = load_problem(PROBLEMS / "easy.cfg")
    start, inside, goal = Pose(-2.0, 2.0, 0.0), Pose(-0.25, 2.0, 0.0), Pose(-2.0, 1.0, 0.0)
    assert not path_is_collision_free(problem, [inside], resolution=0.1)
    first = {"plan_time_s": 0.0, "checks": 0, "cpu_s": 0.0, "index": 0,
             "path": [(p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw) for p in (start, inside, goal)]}
    request = {"resolution": validity_resolution(problem), "simplify_time": 0.5}
    with WarmPlanner({"easy": problem}, workers=2, seed=3, mode="share") as planner:
        report = planner._finish_shared("easy", first, request, left=2.0, deadline=time.perf_counter() + 60)
        assert planner.refinished == 1
    path = [Pose(*p) for p in report["path"]]
    assert report["solved"] and report["pieces"] == 3
    assert path[0] == start and path[-1] == goal and inside not in path
    assert path_is_collision_free(problem, path, resolution=report["resolution"] / 5)


def test_an_unknown_mode_is_named() -> None:
    with pytest.raises(WorkloadError, match=r"^unknown mode 'fast'; valid: divide, race, share$"):
        WarmPlanner({"easy": load_problem(PROBLEMS / "easy.cfg")}, workers=1, mode="fast")
