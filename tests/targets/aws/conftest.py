"""LocalStack for the AWS tests: started once per session from .localstack-venv, stopped at the end.

The venv comes from ``.ci/localstack.sh``; without it these tests skip and say so. LocalStack
listens on 127.0.0.1:4566 (another free loopback port if that one is taken). Its EC2 image list
is replaced (moto's ``MOTO_AMIS_PATH``) by AMIs named like the ones fogiac's plans query, so
preflight resolves images here as it does on AWS. It is started through ``localstack_main.py``, which
gives it Python 3.12's ``uuid.uuid5`` (its KMS needs it to create a key on 3.11).
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from typing import Any
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
VENV_PYTHON = REPO / ".localstack-venv" / "bin" / "python"
REGION = "us-west-2"

# Images named as fogiac.plan.compile.UBUNTU and NVIDIA query them; an older Ubuntu too, so "newest" matters.
AMIS = [
    {"ami_id": "ami-0a1b2c3d4e5f60001", "name": "ubuntu/images/hvm-ssd-gp3/ubuntu-noble-24.04-amd64-server-20240101",
     "owner_id": "099720109477", "creation_date": "2024-01-01T00:00:00.000Z"},
    {"ami_id": "ami-0a1b2c3d4e5f60002", "name": "ubuntu/images/hvm-ssd-gp3/ubuntu-noble-24.04-amd64-server-20250601",
     "owner_id": "099720109477", "creation_date": "2025-06-01T00:00:00.000Z"},
    {"ami_id": "ami-0a1b2c3d4e5f60003",
     "name": "Deep Learning Base OSS Nvidia Driver GPU AMI (Ubuntu 22.04) 20250601",
     "owner_id": "898082745236", "creation_date": "2025-06-01T00:00:00.000Z"},
]
NEWEST_UBUNTU = "ami-0a1b2c3d4e5f60002"


def _free_port(preferred: int) -> int:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", preferred))
            return preferred
        except OSError:
            s.bind(("127.0.0.1", 0))
            return int(s.getsockname()[1])


def _healthy(url: str) -> bool:
    try:
        with urllib.request.urlopen(f"{url}/_localstack/health", timeout=2) as response:
            return response.status == 200
    except OSError:
        return False


@pytest.fixture(scope="session")
def localstack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The endpoint URL of a LocalStack started for this session."""
    if not VENV_PYTHON.exists():
        pytest.skip(f"LocalStack venv missing ({VENV_PYTHON}); create it with .ci/localstack.sh")
    work = tmp_path_factory.mktemp("localstack")
    amis = work / "amis.json"
    amis.write_text(json.dumps([
        {**a, "state": "available", "public": True, "architecture": "x86_64", "virtualization_type": "hvm",
         "root_device_type": "ebs", "root_device_name": "/dev/sda1", "image_type": "machine",
         "hypervisor": "xen", "description": a["name"]} for a in AMIS
    ]))
    port = _free_port(4566)
    url = f"http://127.0.0.1:{port}"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AWS_", "LOCALSTACK_"))}
    env.update(GATEWAY_LISTEN=f"127.0.0.1:{port}", MOTO_AMIS_PATH=str(amis), SKIP_SSL_CERT_DOWNLOAD="1",
               DISABLE_EVENTS="1", LOCALSTACK_TELEMETRY="0", DISABLE_CORS_CHECKS="1",
               SERVICES="ec2,sts,acm,logs,iam,s3,kms", FILESYSTEM_ROOT=str(work / "fs"))
    log = (work / "localstack.log").open("wb")
    proc = subprocess.Popen([str(VENV_PYTHON), str(Path(__file__).with_name("localstack_main.py"))], cwd=work, env=env,
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 90
        while not _healthy(url):
            if proc.poll() is not None:
                pytest.fail(f"LocalStack exited with {proc.returncode}; see {work / 'localstack.log'}")
            if time.monotonic() > deadline:
                pytest.fail(f"LocalStack did not answer within 90 s; see {work / 'localstack.log'}")
            time.sleep(0.3)
        yield url
    finally:
        _stop(proc)
        log.close()


def _stop(proc: subprocess.Popen[bytes]) -> None:
    for sig, wait in ((signal.SIGTERM, 15), (signal.SIGKILL, 5)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def _point_at(localstack: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Point boto3 (and fogiac) at LocalStack with test keys; never at a real account."""
    for key in [k for k in os.environ if k.startswith("AWS_")]:
        monkeypatch.delenv(key)
    monkeypatch.setenv("AWS_ENDPOINT_URL", localstack)
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", "test")
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", "test")
    monkeypatch.setenv("AWS_DEFAULT_REGION", REGION)
    monkeypatch.setenv("AWS_EC2_METADATA_DISABLED", "true")
    monkeypatch.setenv("AWS_CONFIG_FILE", os.devnull)
    monkeypatch.setenv("AWS_SHARED_CREDENTIALS_FILE", os.devnull)


@pytest.fixture
def aws_env(localstack: str, monkeypatch: pytest.MonkeyPatch) -> str:
    _point_at(localstack, monkeypatch)
    monkeypatch.setenv("FOGIAC_OPERATOR_CIDR", "203.0.113.7/32")
    return localstack


@pytest.fixture(scope="session")
def _clients(localstack: str) -> dict[str, Any]:
    """One client per service for the session (making a boto3 client costs a second or two)."""
    from fogiac.targets.aws.api import client

    with pytest.MonkeyPatch.context() as monkeypatch:
        _point_at(localstack, monkeypatch)
        return {name: client(name, region=REGION) for name in ("ec2", "acm", "logs", "iam", "kms")}


@pytest.fixture
def ec2(aws_env: str, _clients: dict[str, Any]) -> Any:
    return _clients["ec2"]


@pytest.fixture
def acm(aws_env: str, _clients: dict[str, Any]) -> Any:
    return _clients["acm"]


@pytest.fixture
def logs(aws_env: str, _clients: dict[str, Any]) -> Any:
    return _clients["logs"]


@pytest.fixture
def iam(aws_env: str, _clients: dict[str, Any]) -> Any:
    return _clients["iam"]


@pytest.fixture
def kms(aws_env: str, _clients: dict[str, Any]) -> Any:
    return _clients["kms"]
