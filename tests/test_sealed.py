"""Secrets sealed at rest under a passphrase (fogiac.sealed): round trips, what is refused and how, and a
stack folder's key material never readable in what a store would keep. The KMS provider is tested
against LocalStack's KMS in tests/targets/aws/test_sealed_kms.py (one emulator for every AWS test)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fogiac import certs, sealed
from fogiac.errors import StateError
from fogiac.net import hostkey
from fogiac.net.relay.tls import write_relay_lab
from fogiac.procs import free_port
from tests.conftest import REPO

PRIVATE_MARKERS = (b"PRIVATE KEY", b"OPENSSH PRIVATE", b"BEGIN RSA", b"-----BEGIN")


@pytest.fixture
def passphrase(monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.setenv(sealed.PASSPHRASE_ENV, "correct horse battery staple")
    return "correct horse battery staple"


def test_round_trips_and_each_seal_differs(passphrase: str) -> None:
    one, two = sealed.sealer_for(None), sealed.sealer_for(None)
    for data in (b"", b"x", bytes(range(256)) * 40, certs.new_ca("fogiac test CA").key_pem):
        blob = one.seal("certs/ca.key", data)
        assert sealed.is_sealed(blob)
        assert one.open("certs/ca.key", blob) == data
        assert two.open("certs/ca.key", blob) == data  # another sealer (another salt) opens it: the salt is in it
        assert one.seal("certs/ca.key", data) != blob  # a fresh nonce each time
    assert one.seal("n", b"data").startswith(b"fogiac-sealed 1 passphrase\n")


def test_without_the_passphrase_one_line_names_it(passphrase: str, monkeypatch: pytest.MonkeyPatch) -> None:
    blob = sealed.sealer_for(None).seal("ssh/id_ed25519", b"secret")
    monkeypatch.delenv(sealed.PASSPHRASE_ENV)
    with pytest.raises(StateError, match=r"^ssh/id_ed25519: the stack's secrets are sealed with a passphrase and "
                                         r"FOGIAC_STATE_PASSPHRASE is not set; set it to the stack's passphrase"):
        sealed.sealer_for(None).open("ssh/id_ed25519", blob)
    with pytest.raises(StateError, match="FOGIAC_STATE_PASSPHRASE is not set"):
        sealed.sealer_for(None).seal("ssh/id_ed25519", b"secret")


def test_a_wrong_passphrase_is_said_so(passphrase: str, monkeypatch: pytest.MonkeyPatch) -> None:
    blob = sealed.sealer_for(None).seal("certs/ca.key", b"secret")
    monkeypatch.setenv(sealed.PASSPHRASE_ENV, "Tr0ub4dor&3")
    with pytest.raises(StateError, match=r"^certs/ca.key: \$FOGIAC_STATE_PASSPHRASE is not the passphrase it was "
                                         r"sealed with; set the stack's passphrase to open it$"):
        sealed.sealer_for(None).open("certs/ca.key", blob)


ALTERED = r"^certs/ca.key: the sealed object does not open under this name \(altered since it was sealed, or copied " \
          r"from another name\); refused$"


def _flip(blob: bytes, at: int) -> bytes:
    return blob[:at] + bytes([blob[at] ^ 1]) + blob[at + 1:]


def test_a_tampered_blob_is_refused(passphrase: str) -> None:
    sealer = sealed.sealer_for(None)
    blob = sealer.seal("certs/ca.key", b"-----BEGIN PRIVATE KEY-----\nsecret\n")
    head = blob.index(b"\n", blob.index(b"\n") + 1) + 1
    tampered = [
        _flip(blob, len(blob) - 1),  # the tag
        _flip(blob, head + 20),  # the ciphertext
        _flip(blob, head),  # the nonce
        blob[:-1],  # truncated
        blob[:head + 20],  # cut to less than a tag
        blob.replace(b'"n":32768', b'"n":1073741824'),  # scrypt's cost raised past any sane bound
        blob.replace(b'"n":32768', b'"n":32767'),  # not a power of two
        blob.replace(b"\n{", b"\n[", 1),  # a header that is not an object
        blob.replace(b"passphrase\n", b"plaintext\n", 1),  # an unknown provider
    ]
    for bad in tampered:
        with pytest.raises(StateError, match=ALTERED):
            sealer.open("certs/ca.key", bad)


def test_a_blob_copied_to_another_name_does_not_open(passphrase: str) -> None:
    sealer = sealed.sealer_for(None)
    blob = sealer.seal("certs/client.key", b"the client's key")
    with pytest.raises(StateError, match=ALTERED):
        sealer.open("certs/ca.key", blob)
    assert sealer.open("certs/client.key", blob) == b"the client's key"


def test_plaintext_and_newer_formats_are_refused(passphrase: str) -> None:
    with pytest.raises(StateError, match=r"^certs/ca.key: not a sealed fogiac object \(stored in plaintext, or by "
                                         r"something else\); refused$"):
        sealed.open_blob("certs/ca.key", b"-----BEGIN PRIVATE KEY-----\n")
    blob = sealed.sealer_for(None).seal("certs/ca.key", b"x").replace(b"sealed 1 ", b"sealed 7 ", 1)
    with pytest.raises(StateError, match=r"^certs/ca.key: sealed by a newer fogiac \(sealed format 7, this one reads "
                                         r"1\); upgrade fogiac$"):
        sealed.open_blob("certs/ca.key", blob)


def test_key_material_by_name_and_by_content() -> None:
    for path in ("certs/ca.key", "certs/vpn.key", "certs/client.key", "certs/edge-lab.key", "certs/server.key",
                 "local/planner/certs/server.key", "ssh/id_ed25519", "pulumi-passphrase", "client.ovpn"):
        assert sealed.is_key_material(path), path
    for path in ("certs/ca.pem", "ssh/id_ed25519.pub", "known_hosts", "record.json", "host-keys.json",
                 "edge/relay-edge-planner.log"):
        assert not sealed.is_key_material(path, b"nothing secret"), path
    assert sealed.is_key_material("edge/copy.txt", b"x\n-----BEGIN OPENSSH PRIVATE KEY-----\n")
    assert sealed.is_key_material("notes", b"-----BEGIN EC PRIVATE KEY-----")


def _seal_folder(folder: Path) -> dict[str, bytes]:
    """Every file of a stack's folder sealed as a store would keep it: {relative path: blob}."""
    sealer = sealed.sealer_for(None)
    return {path.relative_to(folder).as_posix(): sealer.seal(path.relative_to(folder).as_posix(), path.read_bytes())
            for path in sorted(folder.rglob("*")) if path.is_file() and not path.is_symlink()}


def _assert_no_key_in(folder: Path, blobs: dict[str, bytes]) -> None:
    keys = [name for name in blobs if sealed.is_key_material(name, (folder / name).read_bytes())]
    plain = {name: (folder / name).read_bytes() for name in keys}
    assert keys and all(b"PRIVATE KEY" in data or name.endswith("pulumi-passphrase") for name, data in plain.items())
    for name, blob in blobs.items():
        assert not any(marker in blob for marker in PRIVATE_MARKERS), name
        for data in plain.values():  # not a line of any key, in any object
            assert all(line not in blob for line in data.splitlines() if len(line) > 16), name
    for name in keys:  # (a log may have grown meanwhile: compared are the keys)
        assert sealed.open_blob(name, blobs[name]) == plain[name]


def test_a_stack_folder_made_by_the_cert_functions_seals_to_no_key(passphrase: str, tmp_path: Path) -> None:
    folder = tmp_path / "lab-dev"
    certs.load_or_create_bundle("lab-dev", folder / "certs")
    certs.load_or_create_edges("lab-dev", folder / "certs", ["lab", None])
    write_relay_lab("lab-dev", folder / "certs")
    certs.load_or_create_ssh_key(folder / "ssh")
    hostkey.main(["new", str(folder / "local" / "planner" / "certs"), "planner"])  # a host's key, made where it runs
    (folder / "pulumi-passphrase").write_text("generated")
    assert (folder / "certs" / "ca.key").read_bytes().startswith(b"-----BEGIN PRIVATE KEY-----")
    blobs = _seal_folder(folder)
    assert {"certs/ca.key", "certs/edge-lab.key", "certs/server.key", "ssh/id_ed25519",
            "local/planner/certs/server.key"} <= set(blobs)
    _assert_no_key_in(folder, blobs)


@pytest.mark.ros
@pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")
def test_a_stack_folder_left_by_a_real_local_up_seals_to_no_key(passphrase: str, tmp_path: Path,
                                                                 _state_dir: Path) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
           "ROS_MASTER_URI": f"http://127.0.0.1:{free_port()}", "ROS_HOSTNAME": "127.0.0.1", "COLUMNS": "200"}

    def fogiac(*argv: str) -> None:
        done = subprocess.run([sys.executable, "-m", "fogiac", *argv], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == 0, done.stdout + done.stderr

    fogiac("init", "--name", "sealed")
    try:
        fogiac("up", "--target", "local", "--yes", "--start-edge-master")
        folder = _state_dir / "sealed-dev"
        blobs = _seal_folder(folder)
        assert {"certs/ca.key", "certs/client.key", "local/planner/certs/server.key"} <= set(blobs)
        _assert_no_key_in(folder, blobs)
    finally:
        fogiac("down", "--yes")
