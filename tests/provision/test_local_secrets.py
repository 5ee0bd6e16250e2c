"""A secret's value stays with the node that asked for it on the ``local`` target (issue 35 item 5).

Sandboxes dropped only variables whose names looked like credentials, so a secret read from
``env:SOME_NAME`` reached every sandbox: its value sat in both sandboxes' roslaunch logs (0644) and in
the other node's environment. A real two-sandbox stack runs here with such a secret: the value is in
the asking node's process environment and its 0600 file, and nowhere else (no other file under the
state folder or the ROS home, no other process of the stack), and every file holding it is the
operator's alone (0600: roslaunch logs the asking node's environment).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from tests.provision.conftest import make_workspace, ros_skip_reason

pytestmark = [pytest.mark.ros, pytest.mark.skipif(bool(ros_skip_reason()), reason=ros_skip_reason() or "")]

VALUE = "s3cr3t-value-7f1c2b9e"  # what the secret's source holds
SOURCE = "LAB_MAP_LICENCE"  # a name no credential pattern catches
MANIFEST = f"""name: keep
cloud: {{provider: local}}
nodes:
  - name: asker
    machine: t3.small
    launch: {{package: fogtest, file: talker.launch, workspace: ws}}
    env: {{API_VALUE: {{secret: env:{SOURCE}}}}}
  - name: other
    machine: t3.small
    launch: {{package: fogtest, file: talker.launch, workspace: ws}}
"""


def _environ(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/environ").read_bytes()
    except OSError:
        return b""


def _stack_processes(state: Path) -> dict[int, str]:
    """{pid: command line} of every process whose command line or working folder is in ``state``."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            args = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            cwd = os.readlink(entry / "cwd")
        except OSError:
            continue
        if str(state) in args or cwd.startswith(str(state)):
            found[int(entry.name)] = args
    return found


def test_a_secret_reaches_only_the_node_that_asked(tmp_path: Path, _state_dir: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(SOURCE, VALUE)
    ros_home = tmp_path / "ros-home"  # where a roslaunch that is not told otherwise writes its logs
    monkeypatch.setenv("ROS_HOME", str(ros_home))
    make_workspace(tmp_path / "ws")
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(MANIFEST)
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["provision", str(manifest), "--health-timeout", "40"])
        assert up.exit_code == 0, up.output
        sandboxes = _state_dir / "keep-dev" / "local"
        holders = {p: args for p, args in _stack_processes(_state_dir).items() if VALUE.encode() in _environ(p)}
        assert holders, "the asking node never got its secret"
        asker = str(sandboxes / "asker")
        assert all(asker in args or os.readlink(f"/proc/{p}/cwd").startswith(asker) for p, args in holders.items()), \
            holders
        assert all(SOURCE.encode() not in _environ(p) for p in _stack_processes(_state_dir)), "the source travelled"
        files = [p for root in (_state_dir, ros_home) for p in root.rglob("*")
                 if p.is_file() and not p.is_symlink() and VALUE.encode() in p.read_bytes()]
        # its 0600 file, and the asking node's own roslaunch log (roslaunch logs its environment): 0600 too
        assert sandboxes / "asker" / "env" / "node-asker.secret.sh" in files
        assert all(f.is_relative_to(sandboxes / "asker") for f in files), files
        assert {f.name: stat.S_IMODE(f.stat().st_mode) & 0o077 for f in files} == {f.name: 0 for f in files}
    finally:
        down = runner.invoke(app, ["provision", str(manifest), "--teardown"])
        assert down.exit_code == 0, down.output
