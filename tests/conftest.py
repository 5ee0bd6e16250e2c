"""Shared fixtures: every test gets its own fogiac state directory.

And the scheduling that lets the suite run on several pytest-xdist workers (``.ci/test`` runs
``-n 4 --dist loadscope``): tests that share an expensive setup run on the worker that made it,
instead of every worker making its own copy.

- A module's tests run on one worker (xdist's loadscope), so a module- or class-scoped fixture (a
  deployed stack, a lab of SSH hosts, two roscores) is made once.
- The folders in ``SHARED_FOLDERS`` run on one worker each, because their tests share a session
  fixture that is slow to make or stands for one thing on the machine: one LocalStack emulator,
  one rendering of each SLAM sequence, one offline declaration of the stack plans.

(xdist's own ``xdist_group`` marks group nothing under pytest 9.2: xdist 3.8 renames
``item._nodeid``, which pytest 9.2 no longer reads. Hence a scheduler that groups by node id.)

Nothing else needs grouping: namespace names and the SSH lab's addresses are unique per process
(``tests/support/netns.py``, ``tests/provision/sshlab.py``), ports are free ones, and state,
certificates and containers are named after per-test folders or stacks.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"

# Folder -> the one xdist scope of all its tests (the session fixture they share, in its conftest.py).
SHARED_FOLDERS = {
    "tests/targets/aws/": "localstack",  # one emulator (about 20 s to start, 700 MB) for every AWS test
    "tests/workloads/slam/": "slam-sequences",  # desk, desk_full, loop: rendered frames (minutes of CPU)
    "tests/stacks/": "offline-plans",  # every example's stack program declared under Pulumi's mocks
}


@pytest.fixture(autouse=True)
def _state_dir(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    state = tmp_path_factory.mktemp("fogiac-state")
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(state))
    return state


# The LocalStack folder's fixtures that start or reach the emulator (tests/targets/aws/conftest.py): a module of
# that folder whose functions ask for none of them needs no emulator and is scheduled on its own.
EMULATOR_FIXTURES = re.compile(r"\bdef \w+\([^)]*\b(?:localstack|aws_env|ec2|acm|logs|iam|kms|_clients)\b[^)]*\)|"
                               r"usefixtures")


@functools.cache
def _needs_emulator(module: str) -> bool:
    try:
        return bool(EMULATOR_FIXTURES.search((REPO / module).read_text()))
    except OSError:
        return True


def scope_of(nodeid: str) -> str:
    """The xdist scope of a test: its shared folder's name, else its module (also a LocalStack folder's module
    that asks for no emulator fixture: it need not wait on the emulator's worker)."""
    module = nodeid.split("::", 1)[0]
    if module.startswith("tests/targets/aws/") and not _needs_emulator(module):
        return module
    return next((name for folder, name in SHARED_FOLDERS.items() if module.startswith(folder)), module)


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """``--dist loadscope``, with the scopes of ``scope_of``; any other ``--dist`` as xdist has it."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class _SharedSetupScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return scope_of(nodeid)

    return _SharedSetupScheduling(config, log)
