"""The teams guide's lock lines (docs/guides/teams.md) are what two members sharing a stack through the bucket
read (issue 35, item 25: every command output the docs show is produced by a test).

Member A's ``fogiac up`` waits at its question, holding the stack's lock in the bucket (LocalStack's S3); B's
``fogiac up --yes`` is refused naming A; A's process is killed (``kill -9``: gone, its lock left behind), and
``fogiac state unlock`` breaks the lock, naming what it breaks. Each is the real ``fogiac`` in a process of its
own, on the local target (the lock is the store's, whatever the target). Each page block marked ``output
checked by`` this test must be what its command printed, shown as ``tests/docs/blocks.py`` shows a run (the
folder and user@host a reader's, times and pids masked).
"""

from __future__ import annotations

import os
import pty
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from tests.docs.blocks import REPO, blocks, displayed, normalise

pytestmark = pytest.mark.localstack

TEAMS = REPO / "docs" / "guides" / "teams.md"
MANIFEST = """\
name: motion-planning
cloud: {provider: local}
nodes:
  - name: planner
    machine: c5.4xlarge
    workload: motion_planning
    topics: {in: [/motion_planning/request], out: [/motion_planning/path]}
"""


def test_the_teams_guide_shows_what_each_member_reads(aws_env: str, tmp_path: Path) -> None:
    import boto3

    bucket = f"fogiac-docs-{uuid.uuid4().hex[:10]}"
    boto3.client("s3").create_bucket(Bucket=bucket, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "fogiac.yaml").write_text(MANIFEST)
    paths = [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]

    def env(member: str) -> dict[str, str]:
        state = tmp_path / member / "state"
        state.mkdir(parents=True, exist_ok=True)
        return {**os.environ, "FOGIAC_STATE_URL": f"s3://{bucket}/robots", "FOGIAC_STATE_DIR": str(state),
                "FOGIAC_STATE_PASSPHRASE": "the lab's passphrase", "PYTHONPATH": os.pathsep.join(paths),
                "PYTHONUNBUFFERED": "1", "COLUMNS": "100"}

    def run(member: str, *args: str) -> tuple[int, str]:
        done = subprocess.run([sys.executable, "-m", "fogiac", *args], cwd=lab, env=env(member),
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
        return done.returncode, displayed(done.stdout, lab)

    def locked() -> bool:
        listed = boto3.client("s3").list_objects_v2(Bucket=bucket, Prefix="robots/motion-planning-dev/lock")
        return bool(listed.get("Contents"))

    said: dict[str, str] = {}
    leader, follower = pty.openpty()
    holder = subprocess.Popen([sys.executable, "-m", "fogiac", "up", "fogiac.yaml"], cwd=lab, env=env("alice"),
                              stdin=follower, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    os.close(follower)
    try:
        deadline = time.monotonic() + 240
        while not locked():
            assert holder.poll() is None, "A's up ended before it asked"
            assert time.monotonic() < deadline, "A's up took no lock"
            time.sleep(0.2)
        code, said["fogiac up --yes"] = run("bob", "up", "--yes")
        assert code == 1, said
        os.killpg(holder.pid, signal.SIGKILL)  # the laptop closed mid-up: the lock stays, naming a gone process
        holder.wait(timeout=30)
        assert locked()
        code, said["fogiac state unlock motion-planning-dev --yes"] = run("bob", "state", "unlock",
                                                                          "motion-planning-dev", "--yes")
        assert code == 0 and not locked(), said
    finally:
        os.close(leader)
        if holder.poll() is None:
            os.killpg(holder.pid, signal.SIGKILL)
            holder.wait(timeout=30)

    shown = [b for b in blocks(TEAMS) if b.kind == "checked" and b.field("test").startswith(
        "tests/targets/aws/test_docs_locks.py")]
    assert sorted(b.field("checked") for b in shown) == sorted(said), "the page's marked blocks and this test's runs"
    for block in shown:
        assert normalise(block.body) == normalise(said[block.field("checked")]), (block.where, said)
