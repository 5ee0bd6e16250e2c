"""fogiac.targets.aws.offline: declaration order, determinism, and nothing written for a plan (redaction is the
engine's: tests/pulumi_engine/test_offline.py)."""

from __future__ import annotations

from pathlib import Path

from fogiac.plan import document as plan_document
from fogiac.targets.aws.offline import OfflinePlan, declare

from .conftest import EXAMPLES, GPU, compiled, write_manifest


def test_declaration_order_network_first(offline: dict[str, OfflinePlan]) -> None:
    names = [r.name for r in offline["minimal"].resources]
    assert names[:3] == ["minimal-dev", "minimal-dev-vpc", "minimal-dev-igw"]
    assert names.index("minimal-dev-endpoint") < names.index("minimal-dev-vpn-association")
    assert [r.stack for r in offline["minimal"].resources] == sorted(
        (r.stack for r in offline["minimal"].resources), key=["network", "compute"].index
    )


LAB = """\
name: lab
cloud:
  provider: hosts
  hosts:
    - name: gpu-box
      address: 192.0.2.10
      key: id_lab
      gpus: 1
nodes:
  - name: planner
    machine: c5.4xlarge
    workload: motion_planning
"""


def test_other_targets_declare_nothing(tmp_path: Path) -> None:
    assert declare(compiled(EXAMPLES / "minimal.yaml", target="local")).resources == ()
    (tmp_path / "id_lab").write_text("not a real key\n")
    lab = declare(compiled(write_manifest(tmp_path, "lab", LAB)))
    assert lab.resources == ()
    assert [h.name for h in lab.plan.hosts] == ["gpu-box"]


def test_a_plan_writes_nothing(_state_dir: Path) -> None:
    declare(compiled(EXAMPLES / "minimal.yaml"))
    assert list(_state_dir.iterdir()) == []


def document(offline: OfflinePlan, **where: str) -> dict:
    """The plan document of an offline declaration, as ``fogiac plan`` builds it."""
    rows = [r.to_dict() for r in offline.resources if r.custom]
    return plan_document.document(offline.plan, rows, **where)


def test_same_manifest_same_digest_whatever_its_path(tmp_path: Path) -> None:
    first = write_manifest(tmp_path, "a", GPU)
    second = write_manifest(tmp_path, "b", GPU)
    one = document(declare(compiled(first)), manifest_path=str(first), manifest_sha256="x")
    two = document(declare(compiled(second)), manifest_path=str(second), manifest_sha256="y")
    assert one["plan_digest"] == two["plan_digest"]
    assert one["resources"] == two["resources"]
    changed = write_manifest(tmp_path, "c", GPU.replace("disk_gb: 100", "disk_gb: 120"))
    three = document(declare(compiled(changed)), manifest_path=str(changed), manifest_sha256="z")
    assert three["plan_digest"] != one["plan_digest"]


def test_document_shape(offline: dict[str, OfflinePlan]) -> None:
    doc = document(offline["minimal"], manifest_path="m.yaml", manifest_sha256="abc")
    assert doc["format_version"] == 2
    assert doc["stacks"] == ["network", "compute"]
    assert doc["manifest"] == {"path": "m.yaml", "sha256": "abc"}
    assert {r["action"] for r in doc["resources"]} == {"create"}
    assert len(doc["resources"]) == 31  # components are not resources AWS creates
    assert doc["cost"]["hourly_usd"] == round(sum(line["total"] for line in doc["cost"]["lines"]), 4)
    assert [line["item"] for line in doc["cost"]["lines"]][1:] == [
        "Client VPN subnet association", "Client VPN connection (the edge)"
    ]

