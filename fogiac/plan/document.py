"""The plan document: what ``fogiac plan --json`` prints, ``--out`` saves and ``up`` records.

Versioned (``format_version``). The resources come from the target (:meth:`Target.declare`:
the aws target runs its stack programs under Pulumi's mocks; targets that create nothing
declare nothing). ``plan_digest`` covers the compiled plan and every declared resource, and
nothing that varies between runs (paths, versions), so equal digests mean nothing would change.
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
from fogiac.plan.model import Plan

FORMAT_VERSION = 1
APPLIED_FILE = "applied.json"  # in stack_dir(stack): the document of the last successful up


def middleware_doc(plan: Plan) -> dict[str, Any]:
    """Which middleware carries the topics, and what it runs on each side."""
    carrier = middleware.get(plan.middleware)
    return {"name": carrier.name, "ros_distro": plan.ros_distro, "port": carrier.port, "label": carrier.label,
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
        "middleware": middleware_doc(plan),
        "stacks": list(dict.fromkeys(str(r["stack"]) for r in resources)),  # in the order the target declares
        "resources": [dict(r) for r in resources],
        "hosts": cost.hosts(plan),
        "nodes": cost.nodes(plan),
        "cost": cost.cost(plan),
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
