"""Issue 33: a ``kill -9`` of ``up``, ``down`` or ``state migrate`` at each write it makes to the state store.

The real ``fogiac`` command, on the ``local`` target against a real roscore, with its state in the stack
folder or in an S3 bucket (LocalStack). ``$FOGIAC_TEST_SIGKILL_AFTER_STORE_WRITE=N`` (fogiac.store.wrote)
makes the process SIGKILL itself right after its Nth write to the store (lock taken, record written or
removed, lock dropped); the test walks N up from 1 until the command runs to its end, and after every kill
shows: the record parses and is a version the command wrote (its serial never goes back), the lock is
reported naming the dead process, ``fogiac state unlock`` breaks it, and the command run again completes.
With the S3 store, the other operator also removes what a killed ``up`` left, before the walk: ``up`` killed
with its node running and its hosts recorded (write 4) and once its record is finished but its lock held
(write 6); each time the other operator, with nothing on disk, breaks the lock and ``down`` leaves no process.

What is covered, one kill point per distinct write (each run replays the writes before its point, from what
the last kill left): ``up`` 7 (lock taken; record begun; hosts recorded before provisioning; hosts recorded
with their folders; edge recorded; record finished; lock dropped), ``down`` 3 (lock taken; what it took down
dropped from the record; the record marked removed), each ``state migrate`` 5 (source lock, destination lock,
record written there, destination lock dropped, source lock dropped). No two points hit the same write. The
other operator's reads after each kill are ``state show`` and ``state unlock`` in each store and ``status``.
Every command is a process of its own forked from one that has already imported fogiac
(tests/support/forkserver.py): each paying Python's start and fogiac's imports was most of the walks' time.
"""

from __future__ import annotations

import copy
import itertools
import json
import os
import signal
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fogiac.store import TEST_KILL_AFTER_WRITES
from tests.conftest import REPO
from tests.support.forkserver import ForkServer, forks_fixture

pytestmark = [pytest.mark.localstack, pytest.mark.ros]

MANIFEST = """\
name: {name}
cloud: {{provider: local}}
edge: {{ros_master: "{edge}"}}
nodes:
  - {{name: worker, machine: t3.small, command: [sleep, "3600"]}}
"""
MOST_WRITES = 12  # a command that still has not finished after this many is a bug of its own


class Member:
    """One operator's environment: a state folder, the shared store's URL or none (the folder store)."""

    def __init__(self, root: Path, url: str | None, edge: str, forks: ForkServer) -> None:
        self.name = f"kill{uuid.uuid4().hex[:6]}"
        self.stack = f"{self.name}-dev"
        self.cwd = root / "checkout"
        self.cwd.mkdir(parents=True)
        (self.cwd / "fogiac.yaml").write_text(MANIFEST.format(name=self.name, edge=edge))
        self.state = root / "state"
        self.url = url
        self.forks = forks
        self.said = root / "said"  # each command's output, a file each
        self.said.mkdir(exist_ok=True)
        self.count = itertools.count()

    def env(self, *, kill_after: int | None = None, url: str | None = None) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if k not in ("FOGIAC_STATE_URL", TEST_KILL_AFTER_WRITES)}
        env.update(FOGIAC_STATE_DIR=str(self.state), FOGIAC_STATE_PASSPHRASE="the lab's passphrase", COLUMNS="250",
                   PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
        if url or self.url:
            env["FOGIAC_STATE_URL"] = str(url or self.url)
        if kill_after is not None:
            env[TEST_KILL_AFTER_WRITES] = str(kill_after)
        return env

    def run(self, *args: str, kill_after: int | None = None, url: str | None = None) -> tuple[int, str, int]:
        """The command's exit status (``-9``: it killed itself), what it said, and its pid."""
        return self.forks.run(list(args), cwd=self.cwd, env=self.env(kill_after=kill_after, url=url),
                              out=self.said / f"{next(self.count)}.txt", timeout=300)

    def batch(self, calls: list[tuple[list[str], str | None]]) -> list[tuple[int, str]]:
        """Several read-only commands (argv, store URL), one after another: what each returned and said."""
        return [self.run(*argv, url=url)[:2] for argv, url in calls]

    def other(self, state: Path) -> Member:
        """Another operator of the same stack: their own state folder, the same manifest and store."""
        twin = copy.copy(self)
        twin.state = state
        return twin

    def record(self, url: str | None) -> dict[str, Any] | None:
        """The record ``fogiac state show`` reads in the store (None: it has none, or says it moved)."""
        code, out, _ = self.run(*self.show_argv(), url=url)
        return self.shown(code, out)

    def show_argv(self) -> list[str]:
        return ["state", "show", self.stack]

    @staticmethod
    def shown(code: int, out: str) -> dict[str, Any] | None:
        """What ``state show`` said: the record (None: it has none, or says it moved)."""
        if code != 0:
            assert "no record in" in out or "moved" in out, out
            return None
        shown = json.loads(out[out.index("{"):])
        assert isinstance(shown["record"], dict) and isinstance(shown["record"].get("serial"), int), shown
        return dict(shown["record"])

    def unlock_argv(self) -> list[str]:
        return ["state", "unlock", self.stack, "--yes"]

    def unlocked(self, code: int, out: str) -> str | None:
        """What ``state unlock`` said: the holder whose lock it broke (None: it was not locked)."""
        assert code == 0, out
        if "is not locked" in out:
            return None
        assert f"broke the lock of stack {self.stack!r}: " in out, out
        return out.split(": ", 1)[1].strip()


@pytest.fixture
def robot(tmp_path: Path) -> Iterator[str]:
    from tests.support.ros import ros_missing, roscore

    if why := ros_missing():
        pytest.skip(why)
    with roscore(tmp_path / "robot") as env:  # the robot's own master, which up connects the stack to
        yield env["ROS_MASTER_URI"]


forks = pytest.fixture(scope="module")(forks_fixture)  # every command of the module's walks starts from it


@pytest.fixture
def bucket(aws_env: str) -> str:
    import boto3

    name = f"fogiac-kill-{uuid.uuid4().hex[:10]}"
    boto3.client("s3").create_bucket(Bucket=name, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    return f"s3://{name}/lab"


def _killed_then_finished(member: Member, argv: list[str], stores: list[str | None], *,
                          serial: int | None = None, removes: bool = False, reader: Member | None = None) -> int:
    """Kill ``argv`` after each of its store writes in turn (each run starting from what the last kill left),
    checking what each kill leaves in ``stores`` (None: the folder), until a run finishes by itself; how many
    kill points there were. ``serial``: the record's before the command (None: it has none yet); ``removes``: the
    command may remove the record (``down``); ``reader``: the operator who reads the record and its status and
    breaks the lock after each kill (default: ``member``)."""
    reader = reader or member
    operation = "state migrate" if argv[0] == "state" else argv[0]
    unlocked = False  # the last kill came after the command dropped its lock: its last write
    for point in range(1, MOST_WRITES + 1):
        code, out, pid = member.run(*argv, kill_after=point)
        if code != -signal.SIGKILL:
            assert code == 0, f"{argv} after {point - 1} kill(s): {out}"
            return point - 1
        assert not unlocked, f"{argv} wrote to the store after dropping its lock (killed at write {point})"
        # the other operator's fogiac: state show in each store, status, state unlock in each store
        status = argv[0] != "state"  # status reads what the kill left (a migrate's: the store it reads says where)
        said = reader.batch([(reader.show_argv(), url) for url in stores]
                            + ([(["status", "fogiac.yaml", "--json"], None)] if status else [])
                            + [(reader.unlock_argv(), url) for url in stores])
        records = [r for r in (reader.shown(*s) for s in said[:len(stores)]) if r is not None]
        assert records or removes or serial is None, f"no record anywhere after a kill at write {point} of {argv}"
        for record in records:  # the version before the command or one it wrote, whole: never an older one
            assert serial is None or record["serial"] >= serial, (point, record["serial"], serial)
            serial = record["serial"]
        if status:
            code, out = said[len(stores)]
            assert code == 0 and "deployed" in json.loads(out[out.index("{"):]), out
        holders = [h for h in (reader.unlocked(*s) for s in said[-len(stores):]) if h is not None]
        unlocked = not holders
        for holder in holders:  # the lock names the dead process and what it was doing
            assert holder.startswith(f"{operation} by ") and f"(pid {pid}" in holder, holder
    pytest.fail(f"{argv} was still writing after {MOST_WRITES} writes")


def _deployed(member: Member, url: str | None = None) -> bool:
    code, out, _ = member.run("status", "fogiac.yaml", "--json", url=url)
    assert code == 0, out
    return bool(json.loads(out[out.index("{"):])["deployed"])


def _running(folder: Path) -> list[int]:
    """The processes working in ``folder`` (a local stack's sandboxes live in its operator's state folder)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            if entry.name.isdigit() and Path(os.readlink(entry / "cwd")).is_relative_to(folder):
                found.append(int(entry.name))
        except OSError:
            continue
    return found


def walk_up_and_down(robot: str, tmp_path: Path, url: str | None, forks: ForkServer) -> None:
    """``up`` then ``down``, each killed at every store write in turn; ``url``: the S3 store, None: the folder."""
    member = Member(tmp_path, url, robot, forks)
    # with a shared store another operator reads, unlocks and runs the command again
    other = member.other(tmp_path / "other-state") if url else member
    try:
        if url:  # the other operator removes what a killed up left: its nodes running, and all but the lock dropped
            for point in (4, 6):
                code, out, _ = member.run("up", "fogiac.yaml", "--yes", kill_after=point)
                assert code == -signal.SIGKILL, out
                assert _running(member.state), f"up killed at write {point} started no node"
                assert other.unlocked(*other.run(*other.unlock_argv())[:2]) is not None
                code, out, _ = other.run("down", "fogiac.yaml", "--yes")
                assert code == 0, f"the other operator's down after a kill at write {point} of up: {out}"
                left = {pid: Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")[:150]
                        for pid in _running(member.state)}
                assert not _deployed(member) and not left, f"left after a kill at write {point}: {left} {out}"
        points = _killed_then_finished(member, ["up", "fogiac.yaml", "--yes"], [url], reader=other)
        assert points >= 3, points  # the lock, the record (begun, applied, ...), the lock dropped
        assert _deployed(other)
        serial = (other.record(url) or {}).get("serial")
        points = _killed_then_finished(other, ["down", "fogiac.yaml", "--yes"], [url], serial=serial, removes=True,
                                       reader=member)
        assert points >= 2, points
        assert not _deployed(member)
    finally:
        member.run("state", "unlock", member.stack, "--yes")
        member.run("down", "fogiac.yaml", "--yes")


@pytest.mark.timeout(900)
def test_up_and_down_killed_at_each_store_write_leave_a_record_a_rerun_completes(
        robot: str, tmp_path: Path, bucket: str, forks: ForkServer) -> None:
    """The S3 store; the folder store's walk is tests/test_store_kill.py (it needs no emulator, so it runs
    beside this folder's one worker)."""
    walk_up_and_down(robot, tmp_path, bucket, forks)


@pytest.mark.timeout(900)
def test_state_migrate_killed_at_each_store_write_is_finished_by_a_rerun(
        bucket: str, robot: str, tmp_path: Path, forks: ForkServer) -> None:
    member = Member(tmp_path, None, robot, forks)
    try:
        code, out, _ = member.run("up", "fogiac.yaml", "--yes")
        assert code == 0, out
        serial = (member.record(None) or {}).get("serial")
        points = _killed_then_finished(member, ["state", "migrate", member.stack, "--to", bucket], [None, bucket],
                                       serial=serial)
        assert points >= 3, points
        assert _deployed(member, url=bucket)
        code, out, _ = member.run("status", "fogiac.yaml")
        assert code == 1 and f"its state moved to {bucket}" in out, out

        points = _killed_then_finished(member, ["state", "migrate", member.stack, "--to", "folder", "--from", bucket],
                                       [None, bucket], serial=serial)
        assert points >= 3, points
        assert _deployed(member)
        code, out, _ = member.run("down", "fogiac.yaml", "--yes")
        assert code == 0, out
        assert not _deployed(member)
    finally:
        for url in (None, bucket):
            member.run("state", "unlock", member.stack, "--yes", url=url)
            member.run("down", "fogiac.yaml", "--yes", url=url)
