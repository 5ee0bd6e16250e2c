"""The stack lock trusts a pid only with its start time, as the supervisor's pid files do (issue 26 item 27).

A lock left by a crashed ``up`` names a pid; after a reboot or enough forks that pid names another,
unrelated process, and bare liveness kept the stack locked for good.
"""

from __future__ import annotations

import json
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.errors import LockHeld
from fogiac.procs import start_time
from fogiac.state import StackState, stack_lock


@pytest.fixture
def other() -> Iterator[subprocess.Popen[bytes]]:
    """A live process that is not the one the lock names (a reused pid)."""
    proc = subprocess.Popen(["sleep", "60"])
    yield proc
    proc.kill()
    proc.wait()


def _left(stack: str, **holder: object) -> Path:
    folder = StackState(stack).ensure()
    path = folder / StackState.LOCK
    path.write_text(json.dumps({"host": socket.gethostname(), "operation": "up", "since": "then", **holder}))
    return path


def test_a_lock_whose_pid_was_reused_is_taken_over(_state_dir: Path, other: subprocess.Popen[bytes]) -> None:
    started = start_time(other.pid)
    assert started is not None
    path = _left("robot-dev", pid=other.pid, started=str(int(started) - 1))  # the crashed up started earlier
    with stack_lock("robot-dev", operation="down"):
        assert json.loads(path.read_text())["operation"] == "down"
    assert not path.exists()


def test_a_lock_whose_process_lives_is_held(_state_dir: Path, other: subprocess.Popen[bytes]) -> None:
    _left("robot-dev", pid=other.pid, started=start_time(other.pid))
    with pytest.raises(LockHeld, match=rf"locked by up \(pid {other.pid} on "), stack_lock("robot-dev", operation="up"):
        pass
    _left("robot-dev", pid=other.pid)  # written by an older fogiac, without a start time: liveness alone
    with pytest.raises(LockHeld), stack_lock("robot-dev", operation="up"):
        pass


def test_the_lock_records_its_start_time(_state_dir: Path) -> None:
    with stack_lock("robot-dev", operation="up"):
        holder = json.loads((StackState("robot-dev").folder / StackState.LOCK).read_text())
        assert holder["started"] == start_time(holder["pid"]) is not None


def test_an_unreadable_lock_is_named_in_one_line(_state_dir: Path) -> None:
    path = StackState("robot-dev").ensure() / StackState.LOCK
    path.write_text('["\\u001b[2J"]')
    with pytest.raises(LockHeld, match=r"locked by \? \(pid \?"), stack_lock("robot-dev", operation="up"):
        pass
    _left("robot-dev", pid=1, operation="up\x1b[2J\nfake line")
    with pytest.raises(LockHeld) as info, stack_lock("robot-dev", operation="up"):
        pass
    assert "\x1b" not in str(info.value) and "\n" not in str(info.value)
