"""The getting-started page's walk-through (docs/getting-started.md, every line of every ``sh`` block;
the README's first-day block is the same lines), run line by line on the local target, with a Ctrl-C
in the middle of the first ``up``: every step says what happened, and nothing is left running."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fogiac.procs import free_port
from tests.conftest import REPO
from tests.support.procs import alive_pids

pytestmark = [pytest.mark.ros,
              pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")]


GETTING_STARTED = REPO / "docs" / "getting-started.md"


def command_lines(text: str) -> list[str]:
    """Every line of every ``sh`` fenced block, in order."""
    return [line for block in re.findall(r"^```sh\n(.*?)^```", text, flags=re.M | re.S)
            for line in block.splitlines() if line.strip()]


def readme_walkthrough() -> list[list[str]]:
    lines = command_lines(GETTING_STARTED.read_text())
    assert all(line.startswith(("fogiac ", "python ")) for line in lines), lines  # nothing the test cannot run
    return [shlex.split(line, comments=True) for line in lines]


def test_the_readme_shows_the_getting_started_lines() -> None:
    text = (REPO / "README.md").read_text()
    block = text[text.index("<!-- first-day:begin -->"):text.index("<!-- first-day:end -->")]
    assert command_lines(block) == command_lines(GETTING_STARTED.read_text())


def test_first_day_from_init_to_down(tmp_path: Path, _state_dir: Path) -> None:
    edge = f"http://127.0.0.1:{free_port()}"
    paths = [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]
    env = {**os.environ, "COLUMNS": "200", "PYTHONPATH": os.pathsep.join(paths), "ROS_MASTER_URI": edge,
           "ROS_HOSTNAME": "127.0.0.1"}

    def run(argv: list[str], timeout: float = 240) -> tuple[int, str]:
        argv = [sys.executable, "-m", "fogiac", *argv[1:]] if argv[0] == "fogiac" else [sys.executable, *argv[1:]]
        done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=timeout)
        return done.returncode, done.stdout + done.stderr

    said: dict[str, list[str]] = {}
    interrupted = False
    following: subprocess.Popen[str] | None = None  # `logs --follow`: runs on while the next lines run
    try:
        for argv in readme_walkthrough():
            line = shlex.join(argv)
            if following is not None and argv[:2] == ["fogiac", "up"]:  # the reader's Ctrl-C
                following.send_signal(signal.SIGINT)
                out, err = following.communicate(timeout=60)
                said["fogiac logs planner --follow"] = [out + err]
                assert following.returncode == 0, err
                following = None
            if "--follow" in argv:
                following = subprocess.Popen([sys.executable, "-m", "fogiac", *argv[1:]], cwd=tmp_path, env=env,
                                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                continue
            if argv[:2] == ["fogiac", "up"] and not interrupted:  # Ctrl-C once processes have started
                interrupted = True
                up = subprocess.Popen([sys.executable, "-m", "fogiac", *argv[1:]], cwd=tmp_path, env=env,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                deadline = time.monotonic() + 60
                while not list(_state_dir.rglob("edge-master.pid")) and up.poll() is None:
                    assert time.monotonic() < deadline
                    time.sleep(0.05)
                up.send_signal(signal.SIGINT)
                _, err = up.communicate(timeout=120)
                assert up.returncode == 130, err
                assert "stopped part-way; this is what it left:" in err and "`fogiac down fogiac.yaml` removes it" in err
                code, out = run(["fogiac", "status"])
                assert code == 0 and "partial: the last up did not finish" in out, out
            code, out = run(argv)
            assert code == 0, f"{line}\n{out}"
            said.setdefault(line, []).append(out)
            if argv[:2] == ["fogiac", "init"]:  # the robot's master for this test: a free port, not 11311
                manifest = tmp_path / "fogiac.yaml"
                manifest.write_text(manifest.read_text().replace("http://localhost:11311", edge))
    finally:
        if following is not None:
            following.kill()
            following.communicate()
        run(["fogiac", "down", "--yes"])
    assert said["fogiac init --name first-day"] == ["wrote fogiac.yaml; next: fogiac validate fogiac.yaml && "
                                                    "fogiac plan fogiac.yaml\n"]
    assert said["fogiac validate"] == ["fogiac.yaml: valid (1 node, 1 host, target aws)\n"]
    assert "no cloud resources (target local)" in said["fogiac plan --target local"][0]
    first_up = said["fogiac up --target local --yes --start-edge-master"][0]
    assert re.search(r"planner: relay 127\.0\.0\.1:\d+ <-> edge " + re.escape(edge), first_up)
    # issue 35 item 17: each step as it starts and ends (stderr), never half a minute of silence
    for step in (r"edge: robot's ROS master ok", r"planner: runtime (changed|ok)", r"planner: services (changed|ok)",
                 r"planner: health ok"):
        assert re.search(rf"^{step} \(\d+\.\ds\)$", first_up, re.M), first_up
    assert re.search(r"planner .* running", said["fogiac status"][0])
    assert said["fogiac logs planner"][0].strip()
    ls = said["fogiac ls"][0]
    assert re.search(r"first-day-dev\s*│ dev\s*│ local\s*│ up\s*│", ls), ls
    assert "at most $0.00 ($0.0000/h)" in ls and "off" in ls, ls  # a sandbox costs nothing; no autostop asked
    # what the node wrote while the client's request crossed, streamed as it came
    assert re.search(r"motion_planning: easy: path of \d+ poses", said["fogiac logs planner --follow"][0])
    assert re.fullmatch(r"easy: solved, \d+ poses; [\d.]+ s round trip, [\d.]+ s planning\n",
                        said["python -m workloads.motion_planning client easy"][0])
    assert "provisioning: no changes" in said["fogiac up --yes"][0]  # the second up follows the first
    first, second = said["fogiac down --yes"]
    assert re.search(r"first-day-dev: removed \d+ \(.*\); nothing left\n$", first), first
    assert second == "first-day-dev: not deployed; nothing to remove\n"
    assert alive_pids(_state_dir) == []
