"""The plan document: what ``fogiac plan --json`` prints, ``--out`` saves and ``up`` records.

Versioned (``format_version``). The resources come from the target (:meth:`Target.declare`:
the aws target runs its stack programs under Pulumi's mocks; targets that create nothing
declare nothing). ``plan_digest`` covers the compiled plan and every declared resource, and
nothing that varies between runs (paths, versions), so equal digests mean nothing would change.

Version 2 adds what a reviewer compares besides resources: ``edge_master``, ``topics`` crossing
the edge, ``security_rules``, and each node's command, environment and topics; ``plan --json``
adds each resource's ``action`` against what it was compared with, and a ``changes`` object
(:mod:`fogiac.plan.diff`). Version 1 had the same top-level keys less those, every resource's
``action`` was ``create``, and there was no ``changes``. A version 1 document (an ``applied.json``
written before) is still read as the "before" side of a diff: its missing sections are skipped.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fogiac import __version__
from fogiac.net import middleware
from fogiac.plan import cost
from fogiac.plan.model import NodeSpec, Plan, Rule
from fogiac.state import StackState

FORMAT_VERSION = 2
APPLIED_FILE = StackState.APPLIED  # the document of the last successful up, in the stack's folder


def _node(node: NodeSpec) -> dict[str, Any]:
    return {**cost.node_row(node), "command": list(node.command), "env": dict(node.env),
            "in": list(node.topics_in), "out": list(node.topics_out)}


def topics(plan: Plan) -> list[dict[str, str]]:
    """The topics the edge relay carries, per host: ``to_cloud`` (robot -> node), ``to_edge``
    (node -> robot), ``either`` (relay.topics: whichever side publishes), ``*`` when discovered."""
    rows: list[dict[str, str]] = []
    for route in plan.routes:
        for direction, names in (("to_cloud", route.to_cloud), ("to_edge", route.to_edge), ("either", route.listed)):
            rows += [{"topic": name, "direction": direction, "host": route.host} for name in names]
        if route.auto:
            rows.append({"topic": "*", "direction": "either", "host": route.host})
    return rows


def _ports(rule: Rule) -> str:
    if rule.protocol == "-1":
        return "all"
    return str(rule.from_port) if rule.from_port == rule.to_port else f"{rule.from_port}-{rule.to_port}"


def security_rules(plan: Plan) -> list[dict[str, str]]:
    """Every security-group rule the plan opens, one flat row each (what a reviewer compares)."""
    return [{"group": group.name, "direction": direction, "protocol": "all" if rule.protocol == "-1" else rule.protocol,
             "ports": _ports(rule), "cidr": rule.cidr, "description": rule.description}
            for group in plan.security_groups
            for direction, rules in (("ingress", group.ingress), ("egress", group.egress)) for rule in rules]


def middleware_doc(plan: Plan) -> dict[str, Any]:
    """Which middleware carries the topics, and what it runs on each side."""
    carrier = middleware.get(plan.middleware)
    port = plan.routes[0].port if plan.routes else carrier.port  # the stack's own on shared lab machines
    return {"name": carrier.name, "ros_distro": plan.ros_distro, "port": port, "label": carrier.label,
            "edge": carrier.edge_side, "cloud": carrier.cloud_side}


def document(plan: Plan, resources: Sequence[Mapping[str, Any]], *, manifest_path: str,
             manifest_sha256: str) -> dict[str, Any]:
    body = {
        "stack": plan.stack,
        "environment": plan.environment,
        "target": plan.target,
        "region": plan.region,
        "zone": plan.zone,
        "mode": plan.mode,
        "edge_master": plan.edge_master,
        "middleware": middleware_doc(plan),
        "stacks": list(dict.fromkeys(str(r["stack"]) for r in resources)),  # in the order the target declares
        "resources": [dict(r) for r in resources],
        "hosts": cost.hosts(plan),
        "nodes": [{**_node(node), **row} for node, row in zip(plan.nodes, cost.nodes(plan), strict=True)],
        "topics": topics(plan),
        "security_rules": security_rules(plan),
        "cost": cost.cost(plan),
        **({"notes": list(plan.notes)} if plan.notes else {}),  # absent when none: documents as before
    }
    canonical = json.dumps({"plan": plan.digest(), **body}, sort_keys=True, separators=(",", ":"))
    return {
        "format_version": FORMAT_VERSION,
        "fogiac_version": __version__,
        "manifest": {"path": manifest_path, "sha256": manifest_sha256},
        **body,
        "plan_digest": hashlib.sha256(canonical.encode()).hexdigest(),
    }


def plan_document(plan: Plan, resources: Sequence[Mapping[str, Any]], *, manifest: Path) -> dict[str, Any]:
    """The document for ``plan`` and what its target declares (:meth:`Target.declare`).

    ``up`` saves it as APPLIED_FILE. Both sides must build it from the declared resources: the
    digest covers the offline placeholders (operator address, certificates, SSH key), not the
    real values ``up`` used.
    """
    sha = hashlib.sha256(manifest.read_bytes()).hexdigest()
    return document(plan, resources, manifest_path=str(manifest), manifest_sha256=sha)
