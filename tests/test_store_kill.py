"""Issue 33's ``kill -9`` walk of ``up`` and ``down`` against the folder store (the default): the same walk as
the S3 store's in tests/targets/aws/test_shared_state_kill.py, here because it needs no LocalStack and that
folder's tests all run on the one worker that holds the emulator."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.forkserver import ForkServer
from tests.targets.aws.test_shared_state_kill import forks, robot, walk_up_and_down

pytestmark = pytest.mark.ros
__all__ = ["forks", "robot"]  # the fixtures, found by pytest in this module's names


@pytest.mark.timeout(900)
def test_up_and_down_killed_at_each_folder_store_write_leave_a_record_a_rerun_completes(robot: str,
                                                                                       tmp_path: Path,
                                                                                       forks: ForkServer) -> None:
    walk_up_and_down(robot, tmp_path, None, forks)
