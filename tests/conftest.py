"""Shared fixtures: every test gets its own fogiac state directory.

And the grouping that lets the suite run on several pytest-xdist workers (``.ci/test`` runs
``-n 4 --dist loadgroup``): a test that shares an expensive setup runs on the worker that made it,
instead of every worker making its own copy.

- Tests of one module that use a module- or class-scoped fixture of the tests' own (a deployed
  stack, a lab of SSH hosts, two roscores) run together, so the module's setup happens once.
- Tests that use one of ``SHARED_SETUPS`` (session fixtures that are slow to make or that stand for
  one thing on the machine) run together: one LocalStack emulator, one rendering of each SLAM
  sequence, one offline declaration of the stack plans.

Without xdist the marks do nothing. Nothing else needs grouping: namespace names and the SSH
lab's addresses are unique per process (``tests/support/netns.py``, ``tests/provision/sshlab.py``),
ports are free ones, and state, certificates and containers are named after per-test folders or
stacks.
"""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
TESTS = Path(__file__).resolve().parent

# Session fixture -> the xdist group of every test that uses it (directly or through other fixtures).
SHARED_SETUPS = {
    "localstack": "localstack",  # one emulator (about 20 s to start, 700 MB) for every AWS test
    "desk": "slam-sequences", "desk_full": "slam-sequences", "loop": "slam-sequences",  # rendered frames
    "offline": "offline-plans",  # every example's stack program declared under Pulumi's mocks
}


@pytest.fixture(autouse=True)
def _state_dir(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    state = tmp_path_factory.mktemp("fogiac-state")
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(state))
    return state


def _group(item: pytest.Item) -> str | None:
    """The xdist group ``item`` belongs to, or None when it may run on any worker."""
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return None
    shared = sorted({SHARED_SETUPS[name] for name in info.names_closure if name in SHARED_SETUPS})
    if shared:
        return "+".join(shared)
    for name in info.names_closure:
        for definition in info.name2fixturedefs.get(name, ()):
            if definition.scope in ("module", "class") and _ours(definition.func):
                return item.nodeid.split("::", 1)[0]
    return None


def _ours(func: object) -> bool:
    code = getattr(func, "__code__", None)
    return code is not None and Path(code.co_filename).resolve().is_relative_to(TESTS)


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook reads the marks
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        group = _group(item)
        if group is not None:
            item.add_marker(pytest.mark.xdist_group(group))
