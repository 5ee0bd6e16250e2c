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
from tests.support.first_day import install_lines, wanted, wheelhouse
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


class _AnyAnswer(str):
    """The page's sample answer, compared by its shape (the poses and times are the machine's)."""

    def __eq__(self, other: object) -> bool:
        return isinstance(other, str) and re.fullmatch(
            r"easy: solved, \d+ poses; [\d.]+ s round trip, [\d.]+ s planning\n", other) is not None

    __hash__ = str.__hash__


ANY_ANSWER = _AnyAnswer()


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
    followed = tmp_path.parent / f"{tmp_path.name}-followed.log"  # what it printed, read while it runs
    try:
        for argv in readme_walkthrough():
            line = shlex.join(argv)
            if following is not None and argv[:2] == ["fogiac", "up"]:  # the reader's Ctrl-C
                # the reader presses Ctrl-C once the request's lines have streamed (on a loaded machine the
                # follower may still be starting when the client is done: a Ctrl-C then is not the page's)
                deadline = time.monotonic() + 120
                while "path of" not in followed.read_text() and following.poll() is None:
                    assert time.monotonic() < deadline, followed.read_text()
                    time.sleep(0.1)
                following.send_signal(signal.SIGINT)
                _, err = following.communicate(timeout=60)
                said["fogiac logs planner --follow"] = [followed.read_text() + err]
                assert following.returncode == 0, err
                following = None
            if "--follow" in argv:
                following = subprocess.Popen([sys.executable, "-m", "fogiac", *argv[1:]], cwd=tmp_path, env=env,
                                             stdout=followed.open("w"), stderr=subprocess.PIPE, text=True)
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
    answer = r"easy: solved, \d+ poses; [\d.]+ s round trip, [\d.]+ s planning\n"
    assert re.fullmatch(answer, said["python -m workloads.motion_planning client easy"][0])
    # every output the page shows is what these commands printed (issue 35 item 25; numbers are the machine's)
    shown = re.findall(r"^```text\n(.*?)^```", GETTING_STARTED.read_text(), flags=re.M | re.S)
    assert shown == [said["fogiac validate"][0], ANY_ANSWER, said["fogiac down --yes"][1]], shown
    assert re.fullmatch(answer, shown[1])
    assert "provisioning: no changes" in said["fogiac up --yes"][0]  # the second up follows the first
    first, second = said["fogiac down --yes"]
    assert re.search(r"first-day-dev: removed \d+ \(.*\); nothing left\n$", first), first
    assert second == "first-day-dev: not deployed; nothing to remove\n"
    assert alive_pids(_state_dir) == []


# -- the same day in an environment made as the page says (issue 35: not the CI's full install) ----------------

@pytest.mark.fresh_venv
@pytest.mark.timeout(2400)
def test_first_day_in_an_environment_made_as_the_page_says(tmp_path: Path, _state_dir: Path) -> None:
    """The install block's lines, in order, in an empty folder: its venv (with Debian's rospy), fogiac with the
    extras the docs recommend (``aws,ssh``, not ``all``) and the planner's requirements, from the wheels kept
    here (the install is the page's; only pip's source is local, and pip leaves byte-compiling to Python, which
    compiles what the commands import: compiling every module of every package, pulumi_aws's thousands, was
    two thirds of the install's CPU); then the page's commands with that venv's ``fogiac`` and ``python``, and
    the planner's answer."""
    lines = install_lines()
    assert lines[:3] == ["python3 -m venv --system-site-packages .venv", "source .venv/bin/activate",
                         "pip install -e '.[aws,ssh]'"], lines
    planner = shlex.split(lines[3])
    from fogiac.provision import workload  # noqa: PLC0415

    assert planner[:2] == ["pip", "install"] and planner[2:] == workload.recipe("motion_planning").requirements()
    wheels = wheelhouse(wanted())
    offline = ["--no-index", "--find-links", str(wheels)]
    venv = tmp_path / ".venv"
    subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", str(venv)], check=True)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-compile", *offline]
    subprocess.run([*pip, "-e", f"{REPO}[aws,ssh]"], check=True, timeout=1200)
    subprocess.run([*pip, *planner[2:]], check=True, timeout=600)

    edge = f"http://127.0.0.1:{free_port()}"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(PATH=f"{venv / 'bin'}:{env.get('PATH', '/usr/bin:/bin')}", VIRTUAL_ENV=str(venv), COLUMNS="200",
               ROS_MASTER_URI=edge, ROS_HOSTNAME="127.0.0.1")
    said: dict[str, str] = {}
    try:
        for argv in readme_walkthrough():
            if "--follow" in argv:
                continue  # the first test follows the logs; here the environment is what is under test
            done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
            said[shlex.join(argv)] = done.stdout + done.stderr
            assert done.returncode == 0, f"{shlex.join(argv)}\n{done.stdout}{done.stderr}"
            if argv[:2] == ["fogiac", "init"]:
                manifest = tmp_path / "fogiac.yaml"
                manifest.write_text(manifest.read_text().replace("http://localhost:11311", edge))
    finally:
        subprocess.run(["fogiac", "down", "--yes"], cwd=tmp_path, env=env, capture_output=True, timeout=300)
    assert re.fullmatch(r"easy: solved, \d+ poses; [\d.]+ s round trip, [\d.]+ s planning\n",
                        said["python -m workloads.motion_planning client easy"])
    assert alive_pids(_state_dir) == []
