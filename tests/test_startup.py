"""Compiling loads what compiling needs: ``validate`` and ``plan`` for every built-in target and both
middlewares import no provisioning, no certificates, no templates and no cloud SDK.

Start-up time is what a user feels on every ``validate`` (and an editor's save hook); it is not
asserted here (tests never assert on wall-clock time), the modules that cost it are.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Modules that only ``up``, ``down``, ``status`` and provisioning need.
LIFECYCLE = ("fogiac.provision", "fogiac.lifecycle.sequence", "fogiac.certs", "fogiac.render", "fogiac.net.relay.deploy",
             "fogiac.net.zenoh.deploy", "fogiac.targets.aws.target", "fogiac.targets.hosts.target",
             "fogiac.targets.local.target", "boto3", "pulumi", "pulumi_aws", "stacks", "jinja2", "paramiko")

PROBE = """
import json, sys
from fogiac.cli import main
sys.argv = ["fogiac", *sys.argv[1:]]
try:
    main()
except SystemExit:
    pass
print(json.dumps(sorted(sys.modules)), file=sys.stderr)
"""


def _loaded(*argv: str) -> set[str]:
    done = subprocess.run([sys.executable, "-c", PROBE, *argv], cwd=ROOT, capture_output=True, text=True,
                          timeout=120, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    return set(json.loads(done.stderr.strip().splitlines()[-1]))


HOSTS_MANIFEST = """\
name: lab
cloud:
  provider: hosts
  hosts:
    - {name: gpu1, address: 192.0.2.10, user: lab, key: /nonexistent/key}
nodes:
  - name: talker
    image: ros:noetic-ros-core
"""


@pytest.mark.parametrize(("manifest", "target"), [
    ("examples/motion-planning.yaml", None),  # aws, relay
    ("examples/ros2-zenoh.yaml", None),  # aws, zenoh
    ("examples/motion-planning.yaml", "local"),
    ("hosts", None),
])
def test_validate_imports_no_lifecycle_module(manifest: str, target: str | None, tmp_path: Path) -> None:
    if manifest == "hosts":
        manifest = str(tmp_path / "fogiac.yaml")
        Path(manifest).write_text(HOSTS_MANIFEST)
    loaded = _loaded("validate", manifest, *(["--target", target] if target else []))
    assert "fogiac.plan.compile" in loaded  # it did compile
    assert sorted(m for m in loaded if any(m == p or m.startswith(p + ".") for p in LIFECYCLE)) == []
