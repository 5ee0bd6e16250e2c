"""The shared state store against LocalStack's S3: compare-and-swap on the record's ETag, the lock as an
object created only if absent, the stack folder's files synced through the sealer, and the factory.

Every store here is a real :class:`S3Store` with its own boto3 client and its own local cache, as two
members' machines would have; the bucket is LocalStack's, which implements S3's conditional writes.
"""

from __future__ import annotations

import json
import stat
import threading
import uuid
from pathlib import Path
from typing import Any

import pytest

from fogiac.errors import LockHeld, StateError
from fogiac.state import StackState, default_store
from fogiac.store import FolderStore, StaleRecord, open_store
from fogiac.sealed import sealer_for
from fogiac.targets.aws.s3store import S3Store

pytestmark = pytest.mark.localstack


class Reversed:
    """A sealer whose output is readable in a test (where the bytes went); the real one is fogiac.sealed's."""

    def seal(self, name: str, data: bytes) -> bytes:
        return b"SEALED:" + name.encode() + b":" + data[::-1]

    def open(self, name: str, blob: bytes) -> bytes:
        head = b"SEALED:" + name.encode() + b":"
        assert blob.startswith(head), "opened with another file's name"
        return blob[len(head):][::-1]


@pytest.fixture(autouse=True)
def _passphrase(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FOGIAC_STATE_PASSPHRASE", "the lab's passphrase")  # fogiac.sealed's, without kms_key


@pytest.fixture
def bucket(aws_env: str) -> str:
    import boto3

    name = f"fogiac-state-{uuid.uuid4().hex[:12]}"
    boto3.client("s3").create_bucket(Bucket=name, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    return name


def _objects(bucket: str) -> dict[str, bytes]:
    import boto3

    s3 = boto3.client("s3")
    keys = [o["Key"] for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket)
            for o in page.get("Contents", [])]
    return {key: s3.get_object(Bucket=bucket, Key=key)["Body"].read() for key in keys}


def _member(bucket: str, root: Path, sealer: Any = None) -> S3Store:
    return S3Store(f"s3://{bucket}/lab", cache=root, sealer=sealer or sealer_for(None))


def test_a_stale_put_is_refused_and_creation_happens_once(bucket: str, tmp_path: Path) -> None:
    a, b = _member(bucket, tmp_path / "a"), _member(bucket, tmp_path / "b")
    first = a.put("demo-dev", {"n": 1}, expected=None)
    with pytest.raises(StaleRecord, match="changed since it was read"):
        b.put("demo-dev", {"n": 99}, expected=None)  # created already: If-None-Match refuses
    read_by_b = b.get("demo-dev")
    assert read_by_b.document == {"n": 1} and read_by_b.version == first
    a.put("demo-dev", {"n": 2}, expected=first)
    with pytest.raises(StaleRecord):
        b.put("demo-dev", {"n": 3}, expected=read_by_b.version)  # b read the older one
    assert a.get("demo-dev").document == {"n": 2}
    assert a.list() == b.list() == ["demo-dev"]
    assert a.where("demo-dev") == f"s3://{bucket}/lab/demo-dev/record.json"


def test_two_writers_racing_never_lose_an_update(bucket: str, tmp_path: Path) -> None:
    writes, refused = 12, []

    def writer(name: str) -> None:
        state = StackState("race-dev", store=_member(bucket, tmp_path / name))
        done = 0
        while done < writes:
            try:
                state.update(lambda d: d.__setitem__("deployment", [*(d.get("deployment") or []), name]))
                done += 1
            except StaleRecord:
                refused.append(name)  # read again and retry, as a command run again would

    threads = [threading.Thread(target=writer, args=(n,)) for n in ("a", "b")]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=240)
    record = _member(bucket, tmp_path / "c").get("race-dev").document
    assert record is not None
    assert sorted(record["deployment"]) == ["a"] * writes + ["b"] * writes, "an update was lost"
    assert record["serial"] == 2 * writes


def test_the_lock_is_one_object_naming_its_holder_and_only_a_match_breaks_it(bucket: str, tmp_path: Path) -> None:
    a, b = _member(bucket, tmp_path / "a"), _member(bucket, tmp_path / "b")
    alice = {"user": "alice", "host": "lab-1", "pid": 4242, "operation": "up", "since": "2026-01-01T00:00:00Z"}
    bob = {**alice, "user": "bob", "host": "lab-2"}
    assert a.acquire("lock-dev", alice) is None
    assert b.acquire("lock-dev", bob) == alice
    b.break_lock("lock-dev", bob)  # names another holder: nothing is broken
    assert b.lock_holder("lock-dev") == alice
    b.release("lock-dev", bob)  # b holds nothing: nothing is dropped
    assert a.lock_holder("lock-dev") == alice
    b.break_lock("lock-dev", alice)
    assert b.lock_holder("lock-dev") is None
    assert b.acquire("lock-dev", bob) is None
    a.release("lock-dev", alice)  # a's lock was broken and taken: a's release leaves bob's (If-Match)
    assert a.lock_holder("lock-dev") == bob


def test_a_second_member_is_refused_naming_the_first_and_nothing_reclaims_it(
        bucket: str, tmp_path: Path) -> None:
    a = StackState("held-dev", store=_member(bucket, tmp_path / "a"))
    b = StackState("held-dev", store=_member(bucket, tmp_path / "b"))
    with a.lock(operation="up"):
        with pytest.raises(LockHeld) as refused:
            with b.lock(operation="up"):
                pass
    said = str(refused.value)
    assert "up by " in said and "@" in said and "fogiac state unlock held-dev" in said, said
    # a holder whose process is gone (same host here) is still not taken over: only `state unlock` breaks it
    store = _member(bucket, tmp_path / "c")
    assert store.acquire("held-dev", {"pid": 2 ** 22 + 7, "host": "x", "operation": "up"}) is None
    with pytest.raises(LockHeld, match="pid 4194311"):
        with b.lock(operation="down"):
            pass


def test_the_stack_files_travel_sealed_with_their_modes(bucket: str, tmp_path: Path) -> None:
    a = StackState("files-dev", store=_member(bucket, tmp_path / "a", Reversed()))
    with a.lock(operation="up"):
        (a.ensure() / "certs").mkdir(mode=0o700)
        (a.certs / "ca.key").write_bytes(b"-----BEGIN PRIVATE KEY-----\nsecret\n")
        (a.certs / "ca.key").chmod(0o600)
        a.known_hosts.write_text("h0 ssh-ed25519 AAAA\n")
        (a.folder / ".scratch.tmp").write_text("never synced")
        a.set("deployment", {"state": "partial"})  # the record write pushes the files
    objects = _objects(bucket)
    assert set(objects) == {"lab/files-dev/record.json", "lab/files-dev/files/certs/ca.key",
                            "lab/files-dev/files/known_hosts"}
    assert all(b"secret" not in body for key, body in objects.items()), "a key left unsealed"

    b = StackState("files-dev", store=_member(bucket, tmp_path / "b", Reversed()))
    key = b.certs / "ca.key"
    assert key.read_bytes() == b"-----BEGIN PRIVATE KEY-----\nsecret\n"
    assert stat.S_IMODE(key.stat().st_mode) == 0o600 and stat.S_IMODE(b.folder.stat().st_mode) == 0o700
    with b.lock(operation="down"):
        b.known_hosts.unlink()
    assert "lab/files-dev/files/known_hosts" not in _objects(bucket)
    again = StackState("files-dev", store=_member(bucket, tmp_path / "a", Reversed()))  # a's next command
    assert (again.certs / "ca.key").exists() and not again.known_hosts.exists()


def test_the_factory_keeps_the_folder_by_default_and_names_a_bad_url(
        bucket: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("FOGIAC_STATE_URL", raising=False)
    assert isinstance(default_store(), FolderStore)
    monkeypatch.setenv("FOGIAC_STATE_URL", f"s3://{bucket}/team")
    store = default_store()
    assert isinstance(store, S3Store) and store.url == f"s3://{bucket}/team" and default_store() is store
    for bad, said in (("ftp://x/y", "no state store for ftp://"), ("s3://", "expected s3://BUCKET/PREFIX"),
                      ("bucket/prefix", "expected s3://BUCKET/PREFIX")):
        with pytest.raises(StateError, match=said):
            open_store(bad)
    with pytest.raises(StateError, match="does not exist"):
        S3Store(f"s3://{bucket}-missing/x").get("demo-dev")


def test_a_record_moved_away_says_where_it_went(bucket: str, tmp_path: Path) -> None:
    store = _member(bucket, tmp_path / "a")
    store.mark_moved("gone-dev", "the folder /home/alice/.fogiac/gone-dev", "alice@lab-1")
    with pytest.raises(StateError, match="moved from s3://.* to the folder /home/alice"):
        store.get("gone-dev")
    record = json.loads(_objects(bucket)["lab/gone-dev/moved.json"])
    assert record["by"] == "alice@lab-1"


def test_pulumi_state_follows_the_store(bucket: str, monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.pulumi_engine.workspace import workspace_env

    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE", "test")
    monkeypatch.delenv("FOGIAC_STATE_URL", raising=False)
    assert workspace_env("demo-dev")["PULUMI_BACKEND_URL"].startswith("file://")
    monkeypatch.setenv("FOGIAC_STATE_URL", f"s3://{bucket}/team")
    assert workspace_env("demo-dev")["PULUMI_BACKEND_URL"] == f"s3://{bucket}/team"
    assert not StackState("demo-dev").target_file("pulumi").exists(), "a folder backend was made beside it"


def test_a_url_named_outright_seals_under_the_members_kms_key(monkeypatch: pytest.MonkeyPatch) -> None:
    """``state migrate --to s3://...`` and ``state ... --url`` open the store by its URL: ``$FOGIAC_STATE_KMS_KEY``
    (or the manifest's ``state.kms_key``, for the manifest's URL) still seals what goes there, not the passphrase."""
    from fogiac import store

    monkeypatch.delenv("FOGIAC_STATE_URL", raising=False)
    monkeypatch.setenv("FOGIAC_STATE_KMS_KEY", "alias/lab-state")
    named = open_store("s3://lab-state/robots")
    assert isinstance(named, S3Store) and named.kms_key == "alias/lab-state"
    assert isinstance(named.sealer, type(sealer_for("alias/lab-state")))  # KmsSealer: made lazily, no call yet
    monkeypatch.delenv("FOGIAC_STATE_KMS_KEY")
    store.configure("s3://lab-state/robots", "alias/manifest-key")
    try:
        assert getattr(open_store("s3://lab-state/robots"), "kms_key", None) == "alias/manifest-key"
        assert getattr(open_store("s3://lab-state/elsewhere"), "kms_key", "?") is None  # another store: not its key
    finally:
        store.configure(None)
