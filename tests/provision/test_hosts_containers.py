"""The hosts target's container runtime on two lab machines: the grasp-planning example, end to end.

Two network-namespace hosts with their own sshd run podman (they share this machine's image
storage, so an image built once is found by its digest on both). Like a lab's machines they reach
no public index: their login environment points pip at the lab's mirror, which this test serves
over HTTP on the hosts' link (``.ci/lab-wheels.sh``'s folder: fogiac's and the workloads' wheels,
torch's CPU build among them), and fogiac passes those settings into the image builds.

``fogiac up`` of ``examples/grasp-planning.yaml`` (on the hosts, CPU in the container, beside a
user's ``build:`` node on the second host) answers a depth image published on the robot's master
with a grasp; a second ``up`` builds and restarts nothing; changing one file of the grasp workload
rebuilds and restarts the grasp image only.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
import threading
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from fogiac.resources import package_dir
from tests.conftest import EXAMPLES
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import gateway, lab_skip_reason, ssh_lab
from tests.provision.test_plain_user import WHEELS, ask_grasp
from tests.targets.test_local_containers import _why_not as containers_skip_reason

STACK = "grasp-planning-dev"
DOCKERFILE = """FROM ros:noetic-ros-core
COPY word.txt /opt/word.txt
CMD ["sh", "-c", "exec rostopic pub -r 5 /word std_msgs/String \\"data: $(cat /opt/word.txt)\\""]
"""


def _why_not() -> str | None:
    reason = lab_skip_reason() or ros_skip_reason() or containers_skip_reason()
    if reason:
        return reason
    if not list(WHEELS.glob("torch-2.13.0*.whl")):
        return f"needs the lab's package mirror with torch's CPU wheel ({WHEELS}: bash .ci/lab-wheels.sh)"
    return None


pytestmark = [pytest.mark.root, pytest.mark.ros, pytest.mark.skipif(_why_not() is not None, reason=_why_not() or "")]


class _Quiet(SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 (the base class's name)
        pass


@contextmanager
def _mirror(address: str, port: int) -> Iterator[str]:
    """The lab's package mirror: the wheel folder as a pip find-links page at http://address:port/."""
    server = ThreadingHTTPServer((address, port), functools.partial(_Quiet, directory=str(WHEELS)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://{address}:{port}/"
    finally:
        server.shutdown()
        server.server_close()


def _manifest(root: Path, *, hosts: list[tuple[str, str]], key: Path, edge_port: int) -> Path:
    """The shipped example, on two lab hosts: the grasp node built from its workload recipe on h0, CPU only."""
    app_dir = root / "app"
    app_dir.mkdir()
    (app_dir / "Dockerfile").write_text(DOCKERFILE)
    (app_dir / "word.txt").write_text("from the second host\n")
    machines = "".join(f"    - {{name: {name}, address: {address}, user: root, key: {key}}}\n"
                       for name, address in hosts)
    text = (EXAMPLES / "grasp-planning.yaml").read_text()
    for old, new in (
        ("  provider: aws\n  region: us-east-1\n", f"  provider: hosts\n  runtime: container\n  hosts:\n{machines}"),
        ("network:\n", f'edge: {{ros_master: "http://127.0.0.1:{edge_port}"}}\nnetwork:\n'),
        ("    gpu: true\n", "    gpu: false\n    host: h0\n"),
        ("relay:\n", "  - name: word\n    machine: t3.small\n    host: h1\n    build: {context: app}\n"
                     "    topics: {out: [/word]}\nrelay:\n"),
    ):
        assert old in text, old
        text = text.replace(old, new)
    manifest = root / "fogiac.yaml"
    manifest.write_text(text)
    return manifest


def _inspect(name: str, field: str) -> str:
    return subprocess.run(["podman", "inspect", "--format", f"{{{{{field}}}}}", name], capture_output=True,
                          text=True, check=True).stdout.strip()


def _echo(edge_port: int, topic: str) -> str:
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge_port}", "ROS_HOSTNAME": "127.0.0.1"}
    return subprocess.run(["rostopic", "echo", "-n", "1", topic], env=env, capture_output=True, text=True,
                          timeout=90).stdout


def _edited_workloads(into: Path) -> Path:
    """A copy of the shipped workloads with one grasp-planning file changed (uniquely: a rerun rebuilds too)."""
    shutil.copytree(package_dir("workloads"), into / "workloads", ignore=shutil.ignore_patterns("__pycache__"))
    node = into / "workloads" / "grasp_planning" / "node.py"
    node.write_text(node.read_text() + f"# changed by the hosts container test ({uuid.uuid4().hex})\n")
    return into


KEEP = "localhost/fogiac-test-keep/grasp_planning:shipped"


def test_grasp_example_in_containers_on_two_lab_hosts_builds_once_and_rebuilds_one_image(
        tmp_path: Path, _state_dir: Path) -> None:
    edge_port, mirror_port = free_port(), free_port()
    address = gateway(0)
    env = {"PIP_NO_INDEX": "1", "PIP_FIND_LINKS": f"http://{address}:{mirror_port}/", "PIP_TRUSTED_HOST": address}
    runner = CliRunner()
    grasp, word = f"fogiac-{STACK}-grasp", f"fogiac-{STACK}-word"
    image = rebuilt = ""
    with ssh_lab(tmp_path / "lab", 2, env=env) as (hosts, key), _mirror(address, mirror_port):
        manifest = _manifest(tmp_path, hosts=[(h.name, h.address) for h in hosts], key=key, edge_port=edge_port)
        try:
            up = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
            assert up.exit_code == 0, up.output
            image = _inspect(grasp, ".ImageName")
            assert image.startswith("localhost/fogiac/grasp_planning:"), image
            history = subprocess.run(["podman", "history", "--no-trunc", "--format", "{{.CreatedBy}}", image],
                                     capture_output=True, text=True, check=True).stdout
            assert "PIP_FIND_LINKS" not in history and address not in history, "the mirror is in the image history"
            # The edit below makes fogiac replace this image (older digests go); a second name keeps it, so the
            # next run finds it (its digest follows the workload's files only) and skips torch's install.
            subprocess.run(["podman", "tag", image, KEEP], check=True, capture_output=True)
            answer = ask_grasp(edge_port, cwd=tmp_path)
            assert "error" not in answer and 0.0 <= answer["quality"] <= 1.0, answer
            assert _echo(edge_port, "/word").startswith('data: "from the second host"')
            pids = {h.name: set(h.ns.pids()) for h in hosts}
            grasp_pid, word_pid = int(_inspect(grasp, ".State.Pid")), int(_inspect(word, ".State.Pid"))
            assert grasp_pid in pids["h0"] and word_pid in pids["h1"], "each node runs on its own lab host"
            started = {name: _inspect(name, ".State.StartedAt") for name in (grasp, word)}
            word_image = _inspect(word, ".ImageName")

            again = runner.invoke(app, ["up", str(manifest), "--yes"])
            assert again.exit_code == 0 and "no changes" in again.output, again.output
            assert {name: _inspect(name, ".State.StartedAt") for name in (grasp, word)} == started

            # One file of the grasp workload changed, as a user editing their checkout: that image only.
            code = _edited_workloads(tmp_path / "code")
            changed = subprocess.run([sys.executable, "-m", "fogiac", "up", str(manifest), "--yes"],
                                     env={**os.environ, "PYTHONPATH": str(code), "COLUMNS": "250"},
                                     capture_output=True, text=True, timeout=900, cwd=tmp_path)
            assert changed.returncode == 0, changed.stdout[-3000:] + changed.stderr[-3000:]
            rebuilt = _inspect(grasp, ".ImageName")
            assert rebuilt.startswith("localhost/fogiac/grasp_planning:") and rebuilt != image, (image, rebuilt)
            rows = {line.split()[1]: line for line in changed.stdout.splitlines()
                    if line.startswith(("│ h0 ", "│ h1 "))}
            assert "images" in rows["h0"] and "services" in rows["h0"], changed.stdout  # rebuilt, restarted
            assert "images" not in rows["h1"] and "services" not in rows["h1"], changed.stdout  # pushed code only
            assert _inspect(grasp, ".State.StartedAt") != started[grasp], "the grasp node runs its new image"
            assert (_inspect(word, ".State.StartedAt"), _inspect(word, ".ImageName")) == (started[word], word_image)
            answer = ask_grasp(edge_port, cwd=tmp_path)
            assert "error" not in answer and 0.0 <= answer["quality"] <= 1.0, answer
        finally:
            down = runner.invoke(app, ["down", str(manifest), "--yes"])
            if rebuilt:  # the edited image is this run's alone; the shipped one stays for the next run
                subprocess.run(["podman", "rmi", rebuilt], capture_output=True)
            if image and subprocess.run(["podman", "image", "exists", KEEP]).returncode == 0:
                subprocess.run(["podman", "tag", KEEP, image], capture_output=True)
                subprocess.run(["podman", "rmi", KEEP], capture_output=True)  # the second name only
    assert down.exit_code == 0, down.output
    listed = subprocess.run(["podman", "ps", "-aq", "--filter", f"label=fogiac.stack={STACK}"], capture_output=True,
                            text=True, check=True).stdout
    assert listed.strip() == "", "down left containers"
