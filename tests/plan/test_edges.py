"""Edges as a list: today's manifests make one edge named after the stack, whose plan, document, files and
processes are those of before; a plan with more edges lists them, and each edge has its own certificate."""

from __future__ import annotations

import dataclasses
import stat
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.x509.oid import NameOID

from fogiac.certs import (
    edge_identity,
    edge_role,
    load_bundle,
    load_or_create_bundle,
    load_or_create_edges,
)
from fogiac.errors import CertError, PlanError
from fogiac.manifest.schema import load_manifest
from fogiac.net.relay.deploy import edge_argv, edge_suffix
from fogiac.net.zenoh import tls as zenoh_tls
from fogiac.net.zenoh.config import access_control
from fogiac.net.zenoh.deploy import edge_router_id
from fogiac.plan.compile import compile_plan
from fogiac.plan.diff import diff_documents
from fogiac.plan.document import document
from fogiac.plan.model import EdgeSpec, Plan
from tests.conftest import EXAMPLES


def _plan(name: str = "motion-planning", target: str | None = None) -> Plan:
    return compile_plan(load_manifest(EXAMPLES / f"{name}.yaml"), target=target)


def _two(plan: Plan) -> Plan:
    return dataclasses.replace(plan, edges=plan.edges + (EdgeSpec("arm2", "http://10.0.0.7:11311"),))


def _doc(plan: Plan) -> dict:
    return document(plan, [], manifest_path="m.yaml", manifest_sha256="0" * 64)


@pytest.mark.parametrize("name", ["motion-planning", "minimal"])
def test_a_manifest_makes_one_edge_named_after_the_stack(name: str) -> None:
    plan = _plan(name)
    (edge,) = plan.edges
    assert edge == EdgeSpec(name=plan.stack, entry=plan.edge_master, shorthand=True) and plan.is_default_edge(edge)
    assert edge.named is None  # its certificate and files keep the names of before
    assert edge.entry == load_manifest(EXAMPLES / f"{name}.yaml").edge.ros_master
    assert _plan("ros2-zenoh").edges[0].entry.startswith("tcp/")  # ROS 2: the edge Zenoh router's endpoint


def test_one_edge_keeps_the_plan_and_document_of_before() -> None:
    """The plan's dict and the document say ``edge_master`` and no ``edges``: applied documents and digests of
    stacks made before edges were a list compare equal (no test or doc fixes a digest; this fixes the shape)."""
    plan = _plan()
    out = plan.to_dict()
    assert "edges" not in out and out["edge_master"] == plan.edge_master
    doc = _doc(plan)
    assert "edges" not in doc and doc["edge_master"] == plan.edge_master
    assert diff_documents(doc, _doc(plan)).settings == ()


def test_more_edges_are_listed_and_change_the_digest_and_the_diff() -> None:
    one = _plan()
    two = _two(one)
    assert two.edge_master == one.edge_master and [e.name for e in two.edges] == [one.stack, "arm2"]
    assert list(two.to_dict()["edges"]) == [{"name": one.stack, "entry": one.edge_master, "shorthand": True},
                                            {"name": "arm2", "entry": "http://10.0.0.7:11311", "shorthand": False}]
    assert two.digest() != one.digest()
    doc = _doc(two)
    assert doc["edges"][1] == {"name": "arm2", "entry": "http://10.0.0.7:11311"}
    assert doc["plan_digest"] != _doc(one)["plan_digest"]
    (setting,) = diff_documents(_doc(one), doc).settings
    assert setting[0] == "edges" and len(setting[1]) == 1 and len(setting[2]) == 2
    (removed,) = diff_documents(doc, _doc(one)).settings  # the other way: the edge goes
    assert removed[0] == "edges" and len(removed[2]) == 1


def test_the_shorthand_edge_keeps_its_names_when_a_plan_is_renamed() -> None:
    """A plan copied under another stack name (as tests and older-named stacks do) keeps its one edge the
    shorthand one: the same files, processes and document as before."""
    plan = dataclasses.replace(_plan(), stack="other-dev")
    assert plan.is_default_edge(plan.edges[0]) and "edges" not in plan.to_dict() and "edges" not in _doc(plan)


def test_edge_names_are_unique_and_there_is_at_least_one() -> None:
    plan = _plan()
    with pytest.raises(PlanError, match="two edges named 'arm2'"):
        dataclasses.replace(plan, edges=(EdgeSpec("arm2", "a"), EdgeSpec("arm2", "b")))
    with pytest.raises(PlanError, match="at least one edge"):
        dataclasses.replace(plan, edges=())


def test_an_entry_override_moves_only_the_first_edge() -> None:
    two = _two(_plan())
    assert two.edges_at(None) == two.edges and two.edges_at(two.edge_master) == two.edges
    moved = two.edges_at("http://127.0.0.1:22222")
    assert [e.entry for e in moved] == ["http://127.0.0.1:22222", "http://10.0.0.7:11311"]
    assert [e.name for e in moved] == [e.name for e in two.edges]


def _cn(pem: bytes) -> str:
    return str(x509.load_pem_x509_certificate(pem).subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value)


def test_each_edge_has_its_own_certificate_and_the_first_keeps_its_files(tmp_path: Path) -> None:
    folder = tmp_path / "certs"
    old = load_or_create_bundle("robot-dev", folder)  # a stack folder as fogiac made it before edges were a list
    pairs = load_or_create_edges("robot-dev", folder, [None, "arm2"])  # None: the manifest's edge: block
    assert pairs[None] == old.client and _cn(old.client.cert_pem) == "client.robot-dev.fogiac"
    assert _cn(pairs["arm2"].cert_pem) == edge_identity("robot-dev", "arm2") == "arm2.edge.robot-dev.fogiac"
    assert edge_identity("robot-dev", None) == "client.robot-dev.fogiac"
    assert edge_role("robot-dev", None) == "client" and edge_role("robot-dev", "arm2") == "edge-arm2"
    assert (folder / "edge-arm2.pem").read_bytes() == pairs["arm2"].cert_pem
    assert stat.S_IMODE((folder / "edge-arm2.key").stat().st_mode) == 0o600
    x509.load_pem_x509_certificate(pairs["arm2"].cert_pem).verify_directly_issued_by(
        x509.load_pem_x509_certificate(old.ca.cert_pem))
    again = load_or_create_edges("robot-dev", folder, [None, "arm2"])
    assert again == pairs and load_bundle(folder) == old  # kept, never reissued
    with pytest.raises(CertError, match="one DNS label"):
        load_or_create_edges("robot-dev", folder, ["Arm_2"])


def test_each_edge_runs_its_own_relays_and_routers_with_its_own_names(tmp_path: Path) -> None:
    two = _two(_plan("motion-planning", "local"))
    first, second = two.edges
    route = two.routes[0]
    kwargs = {"stack": two.stack, "connect": "127.0.0.1:1", "certs": tmp_path, "stats": tmp_path / "s.json"}
    before = edge_argv(route, master=first.entry, **kwargs)  # type: ignore[arg-type]
    assert edge_argv(route, master=first.entry, edge=first.named, **kwargs) == before  # type: ignore[arg-type]
    assert "--client" not in before and edge_suffix(two, first) == ""
    other = edge_argv(route, master=second.entry, edge=second.named, **kwargs)  # type: ignore[arg-type]
    assert other[other.index("--client") + 1] == "edge-arm2" and edge_suffix(two, second) == "@arm2"
    assert other[other.index("--name") + 1] != before[before.index("--name") + 1]
    # Zenoh: the first edge keeps its certificate's name and router id; a cloud router accepts both edges.
    assert zenoh_tls.edge_name(two.stack, first.named) == zenoh_tls.edge_name(two.stack)
    assert edge_router_id(two.stack, first.named) == edge_router_id(two.stack)
    assert edge_router_id(two.stack, "arm2") != edge_router_id(two.stack)
    names = [zenoh_tls.edge_name(two.stack, e.named) for e in two.edges]
    acl = access_control(route, edge_name=names)
    (edge_subject,) = [s for s in acl["subjects"] if s["id"] == "edge"]
    assert edge_subject["cert_common_names"] == names
