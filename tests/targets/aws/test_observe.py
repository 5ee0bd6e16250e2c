"""compare(): the applied plan document against an observation of EC2, table-driven (pure, no cloud)."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import pytest

from fogiac import targets
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import plan_document
from fogiac.targets.aws.observe import INGRESS, compare

from .plans import write_manifest

MINE = "198.51.100.4/32"


@pytest.fixture(scope="module")
def applied(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    path = write_manifest(tmp_path_factory.mktemp("observe"), "seen", nodes=(("planner", "c5.large"),))
    plan = compile_plan(load_manifest(path))
    return plan_document(plan, targets.get("aws").declare(plan), manifest=path)


def _as_applied(doc: dict[str, Any]) -> dict[str, Any]:
    """What EC2 reports right after the apply: every planned rule, the operator's address filled in."""
    groups = []
    for row in (r for r in doc["resources"] if r["type"] == "aws:ec2/securityGroup:SecurityGroup"):
        rules = [r["inputs"] for r in doc["resources"] if r["type"] == INGRESS
                 and r["inputs"]["securityGroupId"] == f"<{row['name']}.id>"]
        groups.append({"group_id": f"sg-{len(groups)}", "name": row["inputs"]["name"], "ingress": [
            {"rule_id": f"sgr-{i}", "protocol": r["ipProtocol"], "from": r["fromPort"], "to": r["toPort"],
             "source": r["cidrIpv4"].replace("<operator>", MINE.removesuffix("/32")), "description": r["description"]}
            for i, r in enumerate(rules)]})
    return {"instances": [{"instance_id": "i-1", "host": "planner", "type": "c5.large", "state": "running",
                           "ami": "ami-0a1b2c3d4e5f60002"}], "security_groups": groups}


def _stopped(seen: dict[str, Any]) -> None:
    seen["instances"][0]["state"] = "stopped"


def _terminated(seen: dict[str, Any]) -> None:
    seen["instances"][0]["state"] = "terminated"


def _ssh_rule_gone(seen: dict[str, Any]) -> None:
    hosts = seen["security_groups"][0]
    hosts["ingress"] = [r for r in hosts["ingress"] if r["from"] != 22]


def _vpn_group_gone(seen: dict[str, Any]) -> None:
    seen["security_groups"] = [g for g in seen["security_groups"] if not g["name"].endswith("-vpn")]


def _ssh_widened(seen: dict[str, Any]) -> None:
    next(r for r in seen["security_groups"][0]["ingress"] if r["from"] == 22)["source"] = "0.0.0.0/0"


CASES: list[tuple[str, Callable[[dict[str, Any]], None], list[tuple[str, str]]]] = [
    ("as applied", lambda seen: None, []),
    ("stopped by autostop is not drift", _stopped, []),
    ("instance terminated", _terminated, [("seen-dev-host-planner", "deleted")]),
    ("operator's rule revoked", _ssh_rule_gone, [("seen-dev-hosts-in-tcp-22-operator-32", "deleted")]),
    ("VPN group deleted", _vpn_group_gone, [("seen-dev-sg-vpn", "deleted")]),
]


@pytest.mark.parametrize(("case", "change", "expected"), CASES, ids=[c[0] for c in CASES])
def test_compare(applied: dict[str, Any], case: str, change: Callable[[dict[str, Any]], None],
                 expected: list[tuple[str, str]]) -> None:
    seen = copy.deepcopy(_as_applied(applied))
    change(seen)
    assert [(d.name, d.status) for d in compare(applied, seen, operator_cidrs=[MINE])] == expected


def test_the_operator_rule_widened_in_the_console_is_its_rule_gone_and_one_added(applied: dict[str, Any]) -> None:
    """The operator's /32 is a placeholder offline; the address it resolved to at the apply decides."""
    seen = copy.deepcopy(_as_applied(applied))
    _ssh_widened(seen)
    found = compare(applied, seen, operator_cidrs=[MINE])
    assert [(d.name, d.status, d.detail) for d in found] == [
        ("seen-dev-hosts-in-tcp-22-operator-32", "deleted", ""),
        ("sgr-0", "added", "fogiac-seen-dev-hosts tcp port 22 from 0.0.0.0/0 (SSH from the operator)")]
    # A stack applied before fogiac recorded the address: its rule matches by description.
    assert compare(applied, copy.deepcopy(_as_applied(applied)), operator_cidrs=None) == []
