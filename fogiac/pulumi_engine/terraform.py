"""A declared plan as Terraform plan JSON, for policy scanners (checkov, Trivy, OPA/conftest).

A Pulumi package bridged from a Terraform provider has a Terraform type for every resource and a
Terraform attribute for every input; the cloud's :class:`Provider` names its types and quirks, this
module shapes the document. Inputs become snake_case attributes, nested objects lists of objects
(as Terraform's JSON has blocks), maps stay maps. A value the offline plan shows as another
resource's placeholder (``<motion-dev-vpc.id>``) is unknown until apply, as in ``terraform show
-json``: it is left out of the planned values and named as a reference in ``configuration``, so a
scanner sees which resource guards or watches which.

Scanners read ``planned_values``, ``resource_changes`` and ``configuration``; the ``fogiac`` key is
ignored by them and carries the checks the cloud fails by design, each with its reason, for the CI
gate to pass to the scanner (``.ci/policy.sh``: ``checkov --skip-check``).
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from fogiac import __version__
from fogiac.errors import PlanError

FORMAT_VERSION = "1.2"  # Terraform's plan JSON format (terraform show -json, 1.5 and later)
TERRAFORM_VERSION = "1.9.0"  # the Terraform the document reads as; no Terraform runs

Doc = Mapping[str, Any]  # the plan document (``fogiac plan --json``)


@dataclass(frozen=True)
class Provider:
    """A Terraform provider as a cloud's Pulumi package is bridged from it."""

    name: str  # the provider's config key, e.g. "aws"
    source: str  # e.g. registry.terraform.io/hashicorp/aws
    types: Mapping[str, str]  # Pulumi type token -> Terraform resource type
    types_home: str  # where a missing type is added (named in the error)
    # Where Pulumi's name is not the snake_case of Terraform's (Pulumi pluralises repeated blocks).
    renamed: Mapping[tuple[str, str], str] = field(default_factory=dict)
    maps: frozenset[str] = frozenset()  # map attributes: keys kept as written
    config: Callable[[Doc], Mapping[str, Any]] = lambda doc: {}  # the provider block's expressions
    by_design: Callable[[Doc], list[dict[str, str]]] = lambda doc: []  # checks failed on purpose, with reasons

    def tf_type(self, token: str) -> str:
        try:
            return self.types[token]
        except KeyError:
            raise PlanError(f"no Terraform type known for {token!r}; add it to {self.types_home}") from None


_PLACEHOLDER = re.compile(r"^<([^<>]+)\.([A-Za-z]+)>$")  # <logical-name.attr>: another resource's output


def snake(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", name).lower()


def tf_name(logical: str) -> str:
    """A Terraform resource name for a Pulumi logical name (letters, digits, ``_`` and ``-``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", logical)


def _refs(value: Any, addresses: Mapping[str, str]) -> list[str]:
    """The addresses ``value`` (a placeholder, or a list of them) points at; [] when it is a constant."""
    items = value if isinstance(value, list) else [value]
    out: list[str] = []
    for item in items:
        match = _PLACEHOLDER.match(item) if isinstance(item, str) else None
        if match and match.group(1) in addresses:
            address = addresses[match.group(1)]
            out += [f"{address}.{snake(match.group(2))}", address]
    return out


def _convert(provider: Provider, tf: str, inputs: Mapping[str, Any],
             addresses: Mapping[str, str]) -> tuple[dict, dict, dict]:
    """(values, after_unknown, expressions) for one resource's (or nested block's) inputs."""
    values: dict[str, Any] = {}
    unknown: dict[str, Any] = {}
    expressions: dict[str, Any] = {}
    for key, value in inputs.items():
        attr = provider.renamed.get((tf, key), snake(key))
        if attr in provider.maps and isinstance(value, Mapping):
            values[attr] = dict(value)
            expressions[attr] = {"constant_value": dict(value)}
            continue
        blocks = [value] if isinstance(value, Mapping) else value
        if isinstance(blocks, list) and blocks and all(isinstance(b, Mapping) for b in blocks):
            converted = [_convert(provider, tf, b, addresses) for b in blocks]
            values[attr] = [c[0] for c in converted]
            if any(c[1] for c in converted):
                unknown[attr] = [c[1] for c in converted]
            expressions[attr] = [c[2] for c in converted]
            continue
        refs = _refs(value, addresses)
        if refs:
            unknown[attr] = [True] * len(value) if isinstance(value, list) else True
            expressions[attr] = {"references": refs}
        else:
            values[attr] = value
            expressions[attr] = {"constant_value": value}
    return values, unknown, expressions


def _before_inputs(row: Mapping[str, Any]) -> dict[str, Any]:
    """An updated or replaced resource's inputs before: its inputs with each changed path's old value."""
    inputs = copy.deepcopy(dict(row["inputs"]))
    for path, old in (row.get("before") or {}).items():
        *parents, leaf = str(path).split(".")
        here = inputs
        for key in parents:
            here = here.setdefault(key, {}) if isinstance(here.get(key, {}), dict) else {}
        if old is None:
            here.pop(leaf, None)
        else:
            here[leaf] = old
    return inputs


def _actions(action: str) -> list[str]:
    return {"replace": ["delete", "create"], "no-op": ["no-op"]}.get(action, [action])


def export(doc: Doc, provider: Provider) -> dict[str, Any]:
    """The plan document ``doc`` (``fogiac plan --json``) as Terraform plan JSON in ``provider``'s words."""
    rows = list(doc["resources"])
    addresses = {r["name"]: f"{provider.tf_type(r['type'])}.{tf_name(r['name'])}" for r in rows}
    planned: list[dict[str, Any]] = []
    changes: list[dict[str, Any]] = []
    configured: list[dict[str, Any]] = []
    for r in rows:
        tf, name = provider.tf_type(r["type"]), tf_name(r["name"])
        address = addresses[r["name"]]
        values, unknown, expressions = _convert(provider, tf, r["inputs"], addresses)
        head = {"address": address, "mode": "managed", "type": tf, "name": name}
        action = r.get("action", "create")
        before = _convert(provider, tf, _before_inputs(r), addresses)[0] if action in ("update", "replace") else values
        if action != "delete":
            planned.append({**head, "provider_name": provider.source, "schema_version": 0, "values": values,
                            "sensitive_values": {}})
        changes.append({**head, "provider_name": provider.source, "change": {
            "actions": _actions(action),
            "before": None if action == "create" else before,
            "after": None if action == "delete" else values,
            "after_unknown": unknown, "before_sensitive": False, "after_sensitive": {}}})
        configured.append({**head, "provider_config_key": provider.name, "expressions": expressions,
                           "schema_version": 0})
    return {
        "format_version": FORMAT_VERSION,
        "terraform_version": TERRAFORM_VERSION,
        "planned_values": {"root_module": {"resources": planned}},
        "resource_changes": changes,
        "configuration": {
            "provider_config": {provider.name: {"name": provider.name, "full_name": provider.source,
                                                "expressions": dict(provider.config(doc))}},
            "root_module": {"resources": configured},
        },
        "fogiac": {"version": __version__, "stack": doc["stack"], "plan_digest": doc["plan_digest"],
                   "by_design": provider.by_design(doc)},
    }
