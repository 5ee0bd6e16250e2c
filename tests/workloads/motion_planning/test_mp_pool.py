"""The warm planner: workers outlive requests, dead ones are replaced, none is left behind."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator

import pytest
from tests.workloads.motion_planning.mp_support import PROBLEMS, descendants

from fogiac.errors import WorkloadError
from workloads.motion_planning import Pose, load_problem, path_is_collision_free
from workloads.motion_planning.planner import warm_up
from workloads.motion_planning.pool import WarmPlanner


@pytest.fixture(scope="module")
def warm() -> Iterator[WarmPlanner]:
    with WarmPlanner({"easy": load_problem(PROBLEMS / "easy.cfg")}, workers=2, seed=3) as planner:
        yield planner


def test_workers_serve_many_requests_with_their_own_endpoints(warm: WarmPlanner) -> None:
    pids = warm.pids()
    first = warm.solve("easy", time_limit=20)
    start, goal = Pose(-2.0, -1.0, 1.0), Pose(2.0, 1.0, -1.0)
    second = warm.solve("easy", start=start, goal=goal, time_limit=20, resolution=0.03)
    assert first.solved and second.solved and warm.pids() == pids
    assert (first.cores, second.resolution, second.check_resolution) == (2, 0.03, pytest.approx(0.003))
    assert second.path[0] == start and second.path[-1] == goal
    problem = load_problem(PROBLEMS / "easy.cfg").with_endpoints(start, goal)
    assert path_is_collision_free(problem, second.path, resolution=0.005)


def test_a_dead_worker_is_replaced(warm: WarmPlanner) -> None:
    before = warm.pids()
    os.kill(before[0], signal.SIGKILL)
    # the request right after the kill is answered by the survivor or by the replacement; by the
    # next one the dead worker has been replaced either way
    assert warm.solve("easy", time_limit=20).solved
    assert warm.solve("easy", time_limit=20).solved
    assert warm.replaced == 1 and warm.pids()[0] != before[0] and warm.pids()[1] == before[1]


def test_a_request_during_another_waits_its_turn(warm: WarmPlanner) -> None:
    answers: list[bool] = []
    threads = [threading.Thread(target=lambda: answers.append(warm.solve("easy", time_limit=20).solved))
               for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert answers == [True, True, True]


def test_bad_requests_are_named(warm: WarmPlanner) -> None:
    with pytest.raises(WorkloadError, match=r"^unknown problem 'maze'; known: easy$"):
        warm.solve("maze")
    with pytest.raises(WorkloadError, match=r"^resolution must be positive, got 0$"):
        warm.solve("easy", resolution=0.0)


def test_closing_leaves_no_worker_behind() -> None:
    warm_up()  # the fork server stays for reuse; it is not a worker
    before = descendants(os.getpid())
    planner = WarmPlanner({"easy": load_problem(PROBLEMS / "easy.cfg")}, workers=2, seed=1)
    assert len(planner.pids()) == 2 and set(planner.pids()) <= descendants(os.getpid()) - before
    planner.close()
    assert descendants(os.getpid()) <= before


def test_a_seeded_request_draws_the_same_search_in_any_worker() -> None:
    """A request's seed fixes its search: worker 0 of two planners with other histories (and other
    start-up seeds) needs exactly the same collision checks to its first path; another seed, others."""
    problems = {"cubicles": load_problem(PROBLEMS / "cubicles.cfg")}
    with WarmPlanner(problems, workers=1, seed=5) as a, WarmPlanner(problems, workers=1, seed=6) as b:
        a.solve("cubicles", time_limit=30)  # a's worker has planned before; b's has not
        first, again = a.solve("cubicles", time_limit=30, seed=77), b.solve("cubicles", time_limit=30, seed=77)
        other = b.solve("cubicles", time_limit=30, seed=78)
    assert first.solved and again.solved and other.solved
    assert first.collision_checks == again.collision_checks > 0
    assert other.collision_checks != first.collision_checks
