"""Two members of a lab share one stack through the S3 state store (LocalStack), on the ``hosts`` target.

Each operator has a home and a state folder of their own, the same ``FOGIAC_STATE_URL`` and the same
``FOGIAC_STATE_KMS_KEY`` (a LocalStack KMS key: the stack's key material is sealed under it, no passphrase
is set); every verb is the real ``fogiac`` command in a process of its own (forked from one that has
already imported fogiac, tests/support/forkserver.py, but for ``ssh``'s typed input and the ``up`` that waits
at its question on a terminal: a fresh Python each). The lab host is a network
namespace with its own sshd (``tests/provision/sshlab.py``), and ``up`` provisions it over SSH as on a
lab's server.

- A deploys from the local folder, migrates the stack to the bucket (the folder then says where it
  went; every key object is sealed under the KMS key); B, with nothing on disk, sees it running, plans no
  change, reads the node's log and opens a shell on its host (the host keys pinned at ``up`` come from the
  bucket: ``ssh`` checks them strictly); A's ``up`` waiting at its question holds the lock and
  B's ``up`` is refused naming A; A migrates back to the folder and out again; B's ``down`` removes it
  and leaves the host clean; A's ``status`` says not deployed.
- A ``kill -9`` of A's ``up`` once the record says it began: B's ``status`` reads the record, B's
  ``down`` is refused naming A's dead lock, ``fogiac state unlock`` breaks it (naming it), B's ``down``
  completes and the host is clean.
"""

from __future__ import annotations

import importlib.util
import itertools
import json
import os
import pty
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fogiac.procs import free_port
from tests.provision.conftest import hosts_manifest, make_workspace, ros_skip_reason
from tests.provision.sshlab import LabHost, lab_skip_reason, ssh_lab
from tests.provision.test_plain_user import MIRROR, WHEELS
from tests.support.forkserver import ForkServer, forks_fixture

pytestmark = [pytest.mark.localstack, pytest.mark.root, pytest.mark.ros]

_REASON = lab_skip_reason() or ros_skip_reason() or (
    None if (WHEELS / ".stamp").exists() else f"needs the lab's package mirror ({WHEELS}: bash .ci/lab-wheels.sh)")
if _REASON:
    pytest.skip(_REASON, allow_module_level=True)

REPO = Path(__file__).resolve().parents[3]


class Operator:
    """One lab member: a home and a state folder of their own, their own checkout of the manifest."""

    def __init__(self, root: Path, name: str, manifest: Path, url: str, kms_key: str, forks: ForkServer) -> None:
        self.home, self.state = root / name / "home", root / name / "state"
        self.home.mkdir(parents=True)
        self.state.mkdir(parents=True)
        self.checkout = root / name / "checkout"
        self.checkout.mkdir()
        self.manifest = self.checkout / "fogiac.yaml"
        self.manifest.write_text(manifest.read_text())
        make_workspace(self.checkout / "ws")  # the lab's repository, as each member checked it out
        self.url = url
        self.kms_key = kms_key
        self.forks = forks
        self.said = root / name / "said"  # each forked command's output, a file each
        self.said.mkdir()
        self.count = itertools.count()

    def env(self, *, shared: bool = True) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items()
               if k not in ("FOGIAC_STATE_URL", "FOGIAC_STATE_DIR", "FOGIAC_STATE_PASSPHRASE")}
        env.update(HOME=str(self.home), FOGIAC_STATE_DIR=str(self.state), COLUMNS="250",
                   FOGIAC_STATE_KMS_KEY=self.kms_key,  # seals the stack's key material (fogiac.sealed)
                   PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
        if shared:
            env["FOGIAC_STATE_URL"] = self.url
        return env

    def argv(self, *args: str) -> list[str]:
        return [sys.executable, "-m", "fogiac", *args]

    def run(self, *args: str, shared: bool = True, timeout: float = 600, input: str | None = None) -> tuple[int, str]:
        if input is None:
            return self.forks.run(list(args), cwd=self.checkout, env=self.env(shared=shared),
                                  out=self.said / f"{next(self.count)}.txt", timeout=timeout)[:2]
        done = subprocess.run(self.argv(*args), cwd=self.checkout, env=self.env(shared=shared), capture_output=True,
                              text=True, timeout=timeout, input=input)
        return done.returncode, done.stdout + done.stderr

    def start(self, *args: str, stdin: Any = subprocess.DEVNULL) -> subprocess.Popen[str]:
        return subprocess.Popen(self.argv(*args), cwd=self.checkout, env=self.env(), stdin=stdin,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


forks = pytest.fixture(scope="module")(forks_fixture)  # the operators' commands start from it


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[tuple[LabHost, Path]]:
    with ssh_lab(tmp_path / "lab", 1, env=MIRROR) as (hosts, key):  # pip on the host: the lab's local mirror
        yield hosts[0], key


@pytest.fixture
def team(lab: tuple[LabHost, Path], kms: Any, tmp_path: Path,
         forks: ForkServer) -> Iterator[tuple[Operator, Operator, str, LabHost]]:
    import boto3

    host, key = lab
    bucket = f"fogiac-lab-{uuid.uuid4().hex[:10]}"
    boto3.client("s3").create_bucket(Bucket=bucket, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    alias = f"alias/fogiac-lab-{uuid.uuid4().hex[:8]}"  # the lab's state key, as docs/guides/teams.md makes it
    kms.create_alias(AliasName=alias, TargetKeyId=kms.create_key(Description="fogiac state")["KeyMetadata"]["KeyId"])
    name = f"shared{uuid.uuid4().hex[:6]}"
    manifest = hosts_manifest(tmp_path / "fogiac.yaml", hosts=[(host.name, host.address)], key=key,
                              workspace=Path("ws"), name=name)
    manifest.write_text(manifest.read_text().replace(
        "nodes:\n", f'edge: {{ros_master: "http://127.0.0.1:{free_port()}"}}\nnodes:\n', 1))
    url = f"s3://{bucket}/lab"
    a, b = (Operator(tmp_path, who, manifest, url, alias, forks) for who in ("a", "b"))
    stack = f"{name}-dev"
    try:
        yield a, b, stack, host
    finally:  # whoever can still see the stack takes it down
        for who, shared in ((b, True), (a, True), (a, False)):
            who.run("state", "unlock", stack, "--yes", shared=shared, timeout=120)
            who.run("down", str(who.manifest), "--yes", shared=shared)
        shutil.rmtree(Path("/root/.fogiac") / stack, ignore_errors=True)  # the empty folder teardown leaves


def _objects(bucket_url: str) -> dict[str, bytes]:
    import boto3

    bucket, _, prefix = bucket_url.removeprefix("s3://").partition("/")
    s3 = boto3.client("s3")
    keys = [o["Key"] for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket, Prefix=prefix)
            for o in page.get("Contents", [])]
    return {key: s3.get_object(Bucket=bucket, Key=key)["Body"].read() for key in keys}


def _wait_for(what: str, check: Any, proc: subprocess.Popen[str], timeout: float = 300) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = check()
        if found:
            return found
        if proc.poll() is not None:
            pytest.fail(f"the up ended ({proc.returncode}) before {what}: {proc.stdout.read() if proc.stdout else ''}")
        time.sleep(0.2)
    pytest.fail(f"no {what} within {timeout} s")


def _clean(host: LabHost, stack: str) -> None:
    """Nothing of the stack on the lab host: no folder, no process of its own (sshd stays)."""
    folder = Path("/root/.fogiac") / stack  # the host's base: ~/.fogiac/<stack>/<host> (the lab shares this disk)
    assert not (folder / host.name).exists() and not list(folder.rglob("*")), "down left files on the host"
    left = []
    for pid in host.ns.pids():
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if stack in cmdline or "ros" in cmdline:
            left.append(cmdline)
    assert left == [], left


def _status(op: Operator, *, shared: bool = True) -> tuple[int, dict[str, Any] | str]:
    code, out = op.run("status", str(op.manifest), "--json", shared=shared)
    try:
        return code, json.loads(out[out.index("{"):])
    except ValueError:
        return code, out


@pytest.mark.timeout(900)
def test_two_members_share_a_stack_through_the_bucket(team: tuple[Operator, Operator, str, LabHost]) -> None:
    a, b, stack, host = team
    code, out = a.run("up", str(a.manifest), "--yes", "--start-edge-master", shared=False)
    assert code == 0, out

    code, out = a.run("state", "migrate", stack, "--to", a.url, shared=False)
    assert code == 0 and f"to {a.url}/{stack}/record.json" in out, out
    code, out = a.run("status", str(a.manifest), shared=False)
    assert code == 1 and f"its state moved to {a.url}" in out and "FOGIAC_STATE_URL" in out, out
    objects = _objects(a.url)
    assert any(key.endswith("/files/certs/ca.key") for key in objects), "the stack's files stayed behind"
    if importlib.util.find_spec("fogiac.sealed") is not None:  # the sealer is wired: no key leaves in the clear
        assert [k for k, body in objects.items() if b"PRIVATE KEY" in body or b"OPENSSH" in body] == []
        sealed = {k: body.split(b"\n", 2)[:2] for k, body in objects.items() if body.startswith(b"fogiac-sealed ")}
        assert any(k.endswith("/files/certs/ca.key") for k in sealed), sorted(objects)
        assert all(line == b"fogiac-sealed 1 kms" and json.loads(header)["key"] == a.kms_key
                   for line, header in sealed.values()), sealed  # under the lab's KMS key, not a passphrase

    assert not [f for folder in (b.home, b.state) for f in folder.rglob("*")], "B starts with nothing on disk"
    code, said = _status(b)
    assert code == 0 and isinstance(said, dict) and said["deployed"] and not said["partial"], said
    assert [(h["host"], h["nodes"]) for h in said["hosts"]] == [(host.name, [{"node": f"talker-{host.name}"}])], said
    code, out = b.run("plan", str(b.manifest), "--detailed-exitcode")
    assert code == 0, out
    # B reaches the node's host with what the bucket holds: its log, and a shell in its folder there
    code, out = b.run("logs", f"talker-{host.name}", str(b.manifest), "-n", "50")
    assert code == 0 and "process[fog_talker-1]: started with pid" in out, out
    code, out = b.run("ssh", f"talker-{host.name}", str(b.manifest), input="echo from-b-$((6*7)); pwd\nexit\n",
                      timeout=120)
    assert code == 0 and "from-b-42" in out and f"/{stack}/{host.name}\n" in out, out
    code, out = b.run("state", "ls")
    assert code == 0 and stack in out and "hosts" in out and "root@" in out, out

    # A's up waits at its question (a terminal), holding the lock: B's up is refused with A named.
    leader, follower = pty.openpty()
    waiting = a.start("up", str(a.manifest), stdin=follower)
    os.close(follower)
    try:
        holder = _wait_for("lock", lambda: _objects(a.url).get(f"lab/{stack}/lock.json"), waiting)
        assert json.loads(holder)["operation"] == "up"
        code, out = b.run("up", str(b.manifest), "--yes")
        assert code == 1 and f"stack {stack!r} is locked: up by " in out and f"pid {waiting.pid}" in out, out
        assert "fogiac state unlock" in out, out
        os.write(leader, b"n\n")
        said_a = waiting.communicate(timeout=120)[0]
    finally:
        os.close(leader)
        if waiting.poll() is None:
            os.killpg(waiting.pid, signal.SIGKILL)
    assert waiting.returncode == 1 and "not applied" in said_a, said_a
    assert f"lab/{stack}/lock.json" not in _objects(a.url), "the lock stayed after the up ended"

    # back to A's folder and out again: status follows the state wherever it is
    code, out = a.run("state", "migrate", stack, "--to", "folder")
    assert code == 0, out
    code, out = b.run("status", str(b.manifest))
    assert code == 1 and "moved from" in out and "to the folder" in out, out
    code, said = _status(a, shared=False)
    assert code == 0 and isinstance(said, dict) and said["deployed"], said
    code, out = a.run("state", "migrate", stack, "--to", a.url, shared=False)
    assert code == 0, out

    code, out = b.run("down", str(b.manifest), "--yes")
    assert code == 0, out
    _clean(host, stack)
    code, said = _status(a)
    assert code == 0 and isinstance(said, dict) and said["deployed"] is False, said


@pytest.mark.timeout(900)
def test_a_killed_up_is_finished_by_another_member_after_state_unlock(
        team: tuple[Operator, Operator, str, LabHost]) -> None:
    a, b, stack, host = team
    up = a.start("up", str(a.manifest), "--yes", "--start-edge-master")
    try:
        def provisioning() -> bool:
            raw = _objects(a.url).get(f"lab/{stack}/record.json")
            return bool(raw) and "hosts" in json.loads(raw or b"{}")

        _wait_for("record of the provisioned host", provisioning, up)
    finally:
        os.killpg(up.pid, signal.SIGKILL)
        up.wait(timeout=30)

    code, said = _status(b)
    assert code == 0 and isinstance(said, dict) and said["deployed"], said
    code, out = b.run("down", str(b.manifest), "--yes")
    assert code == 1 and "is locked: up by " in out and f"pid {up.pid}" in out, out
    code, out = b.run("state", "unlock", stack, "--yes")
    assert code == 0 and f"broke the lock of stack {stack!r}: up by " in out, out
    code, out = b.run("down", str(b.manifest), "--yes")
    assert code == 0, out
    _clean(host, stack)
    code, said = _status(a)
    assert code == 0 and isinstance(said, dict) and said["deployed"] is False, said
