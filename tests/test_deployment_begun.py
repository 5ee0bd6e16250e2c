"""``up`` records its deployment before it checks the robot's side (:func:`fogiac.deployment.begun`): if that check
fails nothing was made, so the record goes back to what it was; interrupted instead, it stays partial for ``down``.

Real stack folders under the test's ``FOGIAC_STATE_DIR``; the check is the block's own exception.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac import deployment
from fogiac.errors import FogiacError
from fogiac.manifest.revision import load_revision
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.state import StackState

MINIMAL = Path(__file__).resolve().parents[1] / "examples" / "minimal.yaml"


def _plan() -> Plan:
    return compile_plan(load_revision(str(MINIMAL)).manifest, target="local")


def test_a_first_up_whose_robot_side_fails_leaves_no_stack_folder() -> None:
    plan = _plan()
    with pytest.raises(FogiacError, match="no master"), deployment.begun(plan, MINIMAL, existed=False):
        record = deployment.read(plan.stack)
        assert record is not None and record.partial
        raise FogiacError("no master")
    assert not StackState(plan.stack).exists()


def test_a_removed_stack_whose_robot_side_fails_is_removed_again() -> None:
    plan = _plan()
    deployment.begin(plan, MINIMAL)
    deployment.removed(plan.stack)
    with pytest.raises(FogiacError), deployment.begun(plan, MINIMAL, existed=True):
        raise FogiacError("no master")
    record = deployment.read(plan.stack)
    assert record is not None and not record.exists


def test_an_unrecorded_folder_whose_robot_side_fails_keeps_the_folder_without_a_deployment() -> None:
    plan = _plan()
    StackState(plan.stack).set(StackState.EDGES, [])  # the folder exists, no deployment recorded
    with pytest.raises(FogiacError), deployment.begun(plan, MINIMAL, existed=True):
        raise FogiacError("no master")
    assert StackState(plan.stack).exists() and deployment.read(plan.stack) is None


def test_an_interrupted_up_stays_partial_and_a_good_check_keeps_the_record() -> None:
    plan = _plan()
    with pytest.raises(KeyboardInterrupt), deployment.begun(plan, MINIMAL, existed=False):
        raise KeyboardInterrupt
    record = deployment.read(plan.stack)
    assert record is not None and record.partial
    with deployment.begun(plan, MINIMAL, existed=True):
        pass
    record = deployment.read(plan.stack)
    assert record is not None and record.partial
