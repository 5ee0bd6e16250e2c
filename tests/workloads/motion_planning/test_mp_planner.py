"""The planner's paths, re-checked independently; the race leaves no worker process behind."""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import pytest
from tests.workloads.motion_planning.mp_support import PROBLEMS, descendants

from fogiac.errors import WorkloadError
from workloads.motion_planning import Pose, load_problem, path_is_collision_free, solve
from workloads.motion_planning.generate_problems import GENERATORS, twisty
from workloads.motion_planning.paper_problems import GENERATORS as PAPER_GENERATORS, PAPER_DIR


@pytest.fixture(scope="module")
def easy():
    return load_problem(PROBLEMS / "easy.cfg")


@pytest.fixture(scope="module")
def small_twisty(tmp_path_factory: pytest.TempPathFactory):
    """One slotted plate turned 0 degrees and a wide slot: a real rotation problem, solved in ~1 s."""
    out = tmp_path_factory.mktemp("twisty")
    twisty(out, plates=1, slot=(3.0, 1.0))
    return load_problem(out / "twisty.cfg")


def _ends_match(problem, path) -> None:
    assert path[0].as_dict() == pytest.approx(problem.start.as_dict(), abs=1e-9)
    assert path[-1].as_dict() == pytest.approx(problem.goal.as_dict(), abs=1e-9)


def test_easy_path_is_collision_free(easy) -> None:
    solution = solve(easy, cores=1, time_limit=20, seed=1, mode="race")
    assert solution.solved and solution.status == "exact solution"
    assert solution.cores == 1 and solution.winner == 0
    assert solution.collision_checks > 0
    assert solution.resolution == pytest.approx(0.005 * 6 * 3**0.5 + 0.005 * 3.141592653589793 * easy.robot.radius())
    assert solution.check_resolution == pytest.approx(solution.resolution / 10)
    _ends_match(easy, solution.path)
    assert path_is_collision_free(easy, solution.path, resolution=0.01)


def test_small_twisty_path_is_collision_free(small_twisty) -> None:
    solution = solve(small_twisty, cores=2, time_limit=30, seed=5)
    assert solution.solved
    _ends_match(small_twisty, solution.path)
    assert path_is_collision_free(small_twisty, solution.path, resolution=0.01)


def test_a_seed_makes_one_core_repeatable(easy) -> None:
    first, second = (solve(easy, cores=1, time_limit=20, seed=0) for _ in range(2))  # 0 is a seed too
    assert first.solved and first.path == second.path
    assert first.collision_checks == second.collision_checks


def test_checker_catches_a_path_through_the_wall(easy) -> None:
    # Straight through the wall at x=0, beside the window (y=2): must be refused.
    through = [Pose(-2.0, 2.0, 0.0), Pose(2.0, 2.0, 0.0)]
    assert not path_is_collision_free(easy, through, resolution=0.01)
    # The same line through the window is fine; so is a single free pose.
    assert path_is_collision_free(easy, [Pose(-2.0, 0.0, 0.0), Pose(2.0, 0.0, 0.0)], resolution=0.01)
    assert not path_is_collision_free(easy, [Pose(0.0, 0.0, 5.0)], resolution=0.01)  # out of bounds


def test_two_workers_leave_no_process_behind(easy) -> None:
    solve(easy, cores=1, time_limit=10, seed=2)  # starts the fork server, which stays for reuse
    before = descendants(os.getpid())
    solution = solve(easy, cores=2, time_limit=10, seed=3)
    assert solution.solved and solution.cores == 2
    assert multiprocessing.active_children() == []
    assert descendants(os.getpid()) <= before


def test_start_in_collision_is_reported_not_raised(easy) -> None:
    stuck = easy.with_endpoints(Pose(0.0, 2.0, 0.0), easy.goal)  # inside the wall
    solution = solve(stuck, cores=2, time_limit=2, seed=1)
    assert not solution.solved
    assert solution.path == ()
    assert solution.status == "invalid start"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"planner": "rrtstar9"},
         r"^unknown planner 'rrtstar9'; valid: bkpiece, kpiece, lbkpiece, prm, rrt, rrtconnect$"),
        ({"cores": 0}, r"^cores must be at least 1, got 0$"),
        ({"time_limit": 0}, r"^time limit must be positive, got 0$"),
        ({"resolution": -0.5}, r"^resolution must be positive, got -0.5$"),
    ],
)
def test_bad_arguments(easy, kwargs: dict, message: str) -> None:
    with pytest.raises(WorkloadError, match=message):
        solve(easy, **kwargs)


@pytest.mark.parametrize(("generators", "folder"), [(GENERATORS, PROBLEMS), (PAPER_GENERATORS, PAPER_DIR)],
                         ids=["shipped", "paper"])
def test_shipped_problems_are_what_the_generator_writes(generators, folder: Path, tmp_path: Path) -> None:
    for make in generators.values():
        make(tmp_path)
    shipped = sorted(p.name for p in folder.iterdir() if p.suffix in (".cfg", ".stl"))
    assert shipped == sorted(p.name for p in tmp_path.iterdir())
    for name in shipped:
        assert (tmp_path / name).read_bytes() == (folder / name).read_bytes(), name
