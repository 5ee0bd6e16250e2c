"""Manifests and their offline plans, shared by the stack tests (each plan runs once per session)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.plan.compile import compile_plan
from fogiac.manifest.schema import load_manifest
from fogiac.targets.aws.offline import OfflinePlan, declare
from fogiac.plan.model import Plan

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

PROXY = """\
name: proxied
cloud:
  provider: aws
  region: us-east-1
  zone: us-east-1b
network:
  mode: proxy
  vpc_cidr: 10.20.0.0/20
  ssh_from: [198.51.100.0/24, 203.0.113.7/32]
nodes:
  - name: planner
    machine: c5.4xlarge
    workload: motion_planning
    spot: true
    disk_gb: 50
"""

# Proxy mode with flow logs on and one more TCP port open to the internet (MQTT over TLS).
FLOWS = PROXY.replace("name: proxied", "name: flows").replace(
    "  mode: proxy\n", "  mode: proxy\n  flow_logs: true\n  egress_tcp: [443, 80, 8883]\n"
)

GPU = """\
name: grasp
cloud:
  provider: aws
  region: us-west-2
  autostop: {idle_minutes: 15, action: terminate}
network:
  ssh_from: [203.0.113.7/32]
tags:
  team: robots
nodes:
  - name: dexnet
    machine: g4dn.xlarge
    image: ghcr.io/example/dexnet:1
    gpu: true
    disk_gb: 100
  - name: helper
    machine: t3.medium
    image: ros:noetic-ros-core
  - name: helper2
    machine: t3.medium
    image: ros:noetic-ros-core
"""


def write_manifest(directory: Path, name: str, text: str) -> Path:
    path = directory / f"{name}.yaml"
    path.write_text(text)
    return path


def compiled(path: Path, **kwargs: str) -> Plan:
    return compile_plan(load_manifest(path), **kwargs)


@pytest.fixture(scope="session")
def manifests(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    directory = tmp_path_factory.mktemp("manifests")
    return {
        "minimal": EXAMPLES / "minimal.yaml",
        "proxy": write_manifest(directory, "proxy", PROXY),
        "gpu": write_manifest(directory, "gpu", GPU),
        "flows": write_manifest(directory, "flows", FLOWS),
    }


@pytest.fixture(scope="session")
def offline(manifests: dict[str, Path]) -> dict[str, OfflinePlan]:
    return {key: declare(compiled(path)) for key, path in manifests.items()}
