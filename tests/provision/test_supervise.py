"""The supervisor on its own: restart with backoff, idempotent start, clean stop."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Iterator

import pytest

from fogiac.provision import supervise

SUPERVISE = Path(supervise.__file__)


def _sup(run_dir: Path, *args: str) -> str:
    done = subprocess.run([sys.executable, str(SUPERVISE), *args[:2], "--dir", str(run_dir), *args[2:]],
                          capture_output=True, text=True, timeout=60)
    return done.stdout.strip()


def _status(run_dir: Path, name: str) -> dict:
    return json.loads(_sup(run_dir, "status", name))


def _wait(predicate, timeout: float = 15.0) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


@pytest.fixture
def run_dir(tmp_path: Path) -> Iterator[Path]:
    folder = tmp_path / "run"
    yield folder
    _sup(folder, "stop-all", "")


def test_start_is_idempotent_and_a_killed_child_is_restarted(run_dir: Path) -> None:
    assert _sup(run_dir, "start", "sleeper", "--", "sleep", "300").startswith("started ")
    first = _status(run_dir, "sleeper")
    assert first["running"] and first["restarts"] == 0
    assert _sup(run_dir, "start", "sleeper", "--", "sleep", "300") == f"running {first['pid']}"
    os.kill(first["child"], signal.SIGKILL)
    assert _wait(lambda: _status(run_dir, "sleeper")["restarts"] == 1 and _status(run_dir, "sleeper")["child"])
    second = _status(run_dir, "sleeper")
    assert second["pid"] == first["pid"] and second["child"] != first["child"]
    assert "exited with -9; restart 1 in 1s" in (run_dir / "sleeper.log").read_text()


@pytest.mark.parametrize("recorded", ["{pid}", "{pid} 1"])
def test_a_stale_pid_file_naming_another_process_is_neither_trusted_nor_signalled(run_dir: Path,
                                                                                  recorded: str) -> None:
    """A pid file from before a reboot names a pid an unrelated process now has (old format, or
    the right pid with another start time)."""
    bystander = subprocess.Popen(["sleep", "300"], start_new_session=True)
    try:
        run_dir.mkdir(parents=True)
        for suffix in ("pid", "child"):
            (run_dir / f"svc.{suffix}").write_text(recorded.format(pid=bystander.pid) + "\n")
        assert not _status(run_dir, "svc")["running"]
        assert _sup(run_dir, "stop", "svc") == "not running"
        assert bystander.poll() is None
        assert _sup(run_dir, "start", "svc", "--", "sleep", "300").startswith("started ")
        assert _status(run_dir, "svc")["pid"] != bystander.pid
        assert _sup(run_dir, "stop", "svc") == "stopped" and bystander.poll() is None
    finally:
        bystander.kill()
        bystander.wait()


def test_stop_kills_the_whole_tree_and_removes_pid_files(run_dir: Path) -> None:
    _sup(run_dir, "start", "tree", "--", "bash", "-c", "setsid sleep 300 & echo grandchild $!; wait")
    assert _wait(lambda: "grandchild" in (run_dir / "tree.log").read_text())
    grandchild = int((run_dir / "tree.log").read_text().split("grandchild ")[1].split()[0])
    status = _status(run_dir, "tree")
    assert _sup(run_dir, "stop", "tree") == "stopped"
    for pid in (status["pid"], status["child"], grandchild):
        assert not supervise.pid_alive(pid)
    assert sorted(p.name for p in run_dir.iterdir()) == ["tree.log", "tree.state"]
    assert _sup(run_dir, "stop", "tree") == "not running"


def test_health_reports_a_crash_loop_with_the_last_log_line(run_dir: Path) -> None:
    _sup(run_dir, "start", "broken", "--", "bash", "-c", "echo cannot open config.yaml; exit 3")
    ok, detail = supervise.health(run_dir, "broken", check="node", master="http://127.0.0.1:9", timeout=1.5)
    assert not ok
    assert detail.endswith("; log: cannot open config.yaml")
