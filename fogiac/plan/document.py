"""The plan document: what ``fogiac plan --json`` prints, ``--out`` saves and ``up`` records.

Versioned (``format_version``). The resources come from the target (:meth:`Target.declare`:
the aws target runs its stack programs under Pulumi's mocks; targets that create nothing
declare nothing). ``plan_digest`` covers the compiled plan and every declared resource, and
nothing that varies between runs (paths, versions), so equal digests mean nothing would change.

Version 2 adds what a reviewer compares besides resources: ``edge_master``, ``topics`` crossing
the edge, ``security_rules``, and each node's command, environment and topics; ``plan --json``
adds each resource's ``action`` against what it was compared with, and a ``changes`` object
(:mod:`fogiac.plan.diff`). Version 1 had the same top-level keys less those, every resource's
``action`` was ``create``, and there was no ``changes``. A version 1 document (an applied document
written before) is still read as the "before" side of a diff: its missing sections are skipped.

Within version 2, later fogiacs added (each skipped in a diff when the "before" document lacks it, so
an applied document of an earlier fogiac compares without a made-up change): ``pushed`` (every path
``up`` pushes, with its content digest), ``autostop``, ``relay`` (compression and queue size),
``registries``, each host's ``ssh`` (user, key, port) and ``runtime``, and ``edges`` (each edge's name and
entry, absent while the plan has only the one edge named after the stack, whose entry is ``edge_master``).
A fleet's document (``robots:``) also has ``robots`` (each robot's certificate, access rules, edge links and
share of the hour: :mod:`fogiac.plan.fleet`) and, in each node's row, whom it serves, its instances and each
robot's share of its hour; a one-robot document has neither.
A node's ``env`` shows values
known harmless as they are, any other as ``sha256:`` and 12 hex digits, and a named secret as
``[secret env:NAME]``: no value reaches a plan, the stack's record or a pull-request comment.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fogiac import __version__
from fogiac.net import middleware
from fogiac.plan import cost, fleet, pushed
from fogiac.plan.model import HostSpec, NodeSpec, Plan, Rule
from fogiac.state import LEGACY_FILES, StackState

FORMAT_VERSION = 2
# The document of the last successful up is the record's applied section (fogiac.deployment.read_applied);
# an older fogiac kept it in this file of the stack's folder, still read and migrated.
APPLIED_FILE = LEGACY_FILES[StackState.APPLIED]


# Env values a plan shows as they are: settings, not secrets. Anything else is shown as a digest, so a
# change still shows in a diff but the value never reaches a plan, the recorded state or a PR comment.
HARMLESS_ENV = frozenset({
    "ROS_DOMAIN_ID", "ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "RMW_IMPLEMENTATION",
    "ROS_PYTHON_VERSION", "ROSCONSOLE_FORMAT", "RCUTILS_CONSOLE_OUTPUT_FORMAT", "RCUTILS_COLORIZED_OUTPUT",
    "PYTHONUNBUFFERED", "PYTHONDONTWRITEBYTECODE", "LOG_LEVEL", "LOGLEVEL", "CUDA_VISIBLE_DEVICES",
    "NVIDIA_VISIBLE_DEVICES", "OMP_NUM_THREADS", "TZ", "LANG", "LC_ALL",
})
_SECRETISH = re.compile(r"TOKEN|SECRET|PASS|KEY|CREDENTIAL|AUTH|COOKIE|SESSION|PRIVATE|CERT", re.I)
_HARMLESS_VALUE = re.compile(
    r"^(-?[0-9]{1,6}(\.[0-9]+)?|true|false|yes|no|on|off|debug|info|warn|warning|error|fatal)$", re.I)
_SHOWN = re.compile(r"^(sha256:[0-9a-f]{12}|\[secret [^\]]*\])$")  # already as a plan shows it


def env_value(key: str, value: str) -> str:
    """How a plan shows one env value: as it is when known harmless, else ``sha256:`` and 12 hex digits."""
    if _SHOWN.match(value) or key in HARMLESS_ENV or (_HARMLESS_VALUE.match(value) and not _SECRETISH.search(key)):
        return value
    return "sha256:" + hashlib.sha256(value.encode()).hexdigest()[:12]


def shown_env(env: Mapping[str, Any], secrets: Mapping[str, str] | None = None) -> dict[str, str]:
    """A node's env as plans show it: harmless values whole, others as digests, secrets by reference.
    Idempotent, so a document recorded before values were hidden compares with one made now."""
    out = {str(k): env_value(str(k), str(v)) for k, v in env.items()}
    return dict(sorted({**out, **{k: f"[secret {ref}]" for k, ref in (secrets or {}).items()}}.items()))


def _node(node: NodeSpec, row: Mapping[str, Any]) -> dict[str, Any]:
    """A node's row: what :func:`fogiac.plan.cost.nodes` says of it (what it runs, where, its replicas), and what
    a reviewer compares besides (its command, environment and topics)."""
    return {**row, "command": list(node.command), "env": shown_env(dict(node.env), dict(node.secrets)),
            "in": list(node.topics_in), "out": list(node.topics_out)}


def _host(host: HostSpec, row: Mapping[str, Any]) -> dict[str, Any]:
    """A host's row: what :func:`fogiac.plan.cost.hosts` says of it (its machine, price and replica), and how
    fogiac reaches and runs it (user, key, port, runtime)."""
    return {**row, "ssh": {"user": host.user, "key": host.key, "port": host.port}, "runtime": host.runtime}


def autostop(plan: Plan) -> dict[str, Any] | None:
    """When the hosts stop themselves, and how; None: never (they cost until ``fogiac down``)."""
    stop = plan.autostop
    if stop is None:
        return None
    return {"idle_minutes": round(stop.idle_s / 60, 4), "action": stop.action, "power": stop.power}


def relay_settings(plan: Plan) -> dict[str, Any] | None:
    """How topics cross (compression per topic, the queue each topic may hold): one setting for the stack."""
    if not plan.routes:
        return None
    route = plan.routes[0]
    return {"compression": dict(route.compression), "queue_size": route.queue_size}


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


def edges(plan: Plan) -> list[dict[str, str]] | None:
    """Every edge with its identity and entry; None for the one edge of today's manifests (named after the
    stack), which ``edge_master`` describes whole: such documents keep their bytes and digests."""
    if len(plan.edges) == 1 and plan.is_default_edge(plan.edges[0]):
        return None
    return [{"name": edge.name, "entry": edge.entry} for edge in plan.edges]


def document(plan: Plan, resources: Sequence[Mapping[str, Any]], *, manifest_path: str,
             manifest_sha256: str) -> dict[str, Any]:
    priced = cost.rows(plan)
    served, robots = fleet.rows(plan)
    body = {
        "stack": plan.stack,
        "environment": plan.environment,
        "target": plan.target,
        "region": plan.region,
        "zone": plan.zone,
        "mode": plan.mode,
        "edge_master": plan.edge_master,
        **({"edges": listed} if (listed := edges(plan)) is not None else {}),
        "middleware": middleware_doc(plan),
        "stacks": list(dict.fromkeys(str(r["stack"]) for r in resources)),  # in the order the target declares
        "resources": [dict(r) for r in resources],
        "hosts": [_host(host, row) for host, row in zip(plan.hosts, priced.hosts, strict=True)],
        "nodes": [{**_node(node, row), **extra}
                  for node, row, extra in zip(plan.nodes, priced.nodes, served, strict=True)],
        **({"robots": robots} if robots is not None else {}),
        "topics": topics(plan),
        "security_rules": security_rules(plan),
        "pushed": pushed.pushed(plan),  # every path up pushes, with its content's digest
        "cost": priced.cost,
        **({"notes": list(plan.notes)} if plan.notes else {}),  # absent when none: documents as before
        "autostop": autostop(plan),
        "relay": relay_settings(plan),
        "registries": [{"server": server, "username": user, "password": f"[secret {ref}]"}
                       for server, user, ref in plan.registries],
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

    ``up`` records it as the stack record's applied section. Both sides must build it from the declared resources: the
    digest covers the offline placeholders (operator address, certificates, SSH key), not the
    real values ``up`` used.
    """
    sha = hashlib.sha256(manifest.read_bytes()).hexdigest()
    return document(plan, resources, manifest_path=str(manifest), manifest_sha256=sha)
