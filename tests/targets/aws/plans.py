"""Manifests and plans for the AWS tests: each test names its own stack, so tests share one LocalStack."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from fogiac.plan.compile import compile_plan
from fogiac.manifest.schema import load_manifest
from fogiac.plan.model import Plan


def manifest_text(name: str, *, nodes: tuple[tuple[str, str], ...] = (("talker", "t3.small"),),
                  zone: str | None = None, mode: str = "vpn", region: str = "us-west-2") -> str:
    lines = [f"name: {name}", "cloud:", "  provider: aws", f"  region: {region}"]
    if zone:
        lines.append(f"  zone: {zone}")
    lines += ["network:", f"  mode: {mode}", "nodes:"]
    for node, machine in nodes:
        gpu = "    gpu: true\n" if machine.startswith(("g4", "g5", "p3")) else ""
        lines.append(f"  - name: {node}\n    machine: {machine}\n    image: ros:noetic-ros-core\n{gpu}".rstrip())
    return "\n".join(lines) + "\n"


def write_manifest(tmp_path: Path, name: str, **kwargs: object) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(manifest_text(name, **kwargs))  # type: ignore[arg-type]
    return path


def make_plan(tmp_path: Path, name: str, **kwargs: object) -> Plan:
    return compile_plan(load_manifest(write_manifest(tmp_path, name, **kwargs)))


def with_region(plan: Plan, region: str) -> Plan:
    """A crafted plan for a region the manifest would refuse (preflight must refuse it too)."""
    return dataclasses.replace(plan, region=region, zone=f"{region}a")
