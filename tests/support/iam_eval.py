"""A small static evaluator of IAM policy documents, for the shipped policy's tests.

LocalStack's IAM answers ``SimulatePrincipalPolicy`` with an error (checked: see
``tests/targets/aws/test_iam.py``), so the conditions the policy relies on are evaluated here, by
IAM's documented rules, for the parts of the language the shipped documents use: Allow and Deny,
``Action``/``NotAction`` and ``Resource``/``NotResource`` with ``*`` and ``?`` wildcards (case-insensitive
actions, case-sensitive ARNs), policy variables ``${key}`` from the request, and the condition operators
``StringEquals``, ``StringNotEquals``, ``StringLike``, ``Null`` with the ``ForAllValues:`` and
``ForAnyValue:`` qualifiers. An explicit Deny wins, else any Allow allows, else the request is implicitly
denied. Anything else in a document is refused, so a new operator cannot pass unevaluated.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

OPERATORS = ("StringEquals", "StringNotEquals", "StringLike", "Null")


def _pattern(glob: str, *, case: bool) -> re.Pattern[str]:
    body = "".join(".*" if c == "*" else "." if c == "?" else re.escape(c) for c in glob)
    return re.compile(f"^{body}$", 0 if case else re.IGNORECASE | re.DOTALL)


def _listed(value: Any) -> list[str]:
    return [value] if isinstance(value, str) else list(value)


def _substitute(text: str, context: Mapping[str, Sequence[str]]) -> str:
    def one(m: re.Match[str]) -> str:
        found = context.get(m.group(1))
        return found[0] if found else "\x00unset"  # an unset variable matches nothing
    return re.sub(r"\$\{([^}]+)\}", one, text)


def _condition(operator: str, key: str, wanted: Any, context: Mapping[str, Sequence[str]]) -> bool:
    qualifier, _, base = operator.rpartition(":")
    if base not in OPERATORS or qualifier not in ("", "ForAllValues", "ForAnyValue"):
        raise ValueError(f"operator {operator!r} is not evaluated here")
    have = context.get(key)
    wanted_values = [_substitute(w, context) for w in _listed(wanted)]
    if base == "Null":
        return (have is None) == (wanted_values[0] == "true")
    if have is None:
        return qualifier == "ForAllValues" or base == "StringNotEquals" and qualifier == ""

    def matches(value: str) -> bool:
        if base == "StringLike":
            return any(_pattern(w, case=True).match(value) for w in wanted_values)
        equal = value in wanted_values
        return not equal if base == "StringNotEquals" else equal

    if qualifier == "ForAllValues":
        return all(matches(v) for v in have)
    if qualifier == "ForAnyValue":
        return any(matches(v) for v in have)
    return matches(have[0]) if len(have) == 1 else any(matches(v) for v in have)


def _applies(statement: Mapping[str, Any], action: str, resource: str,
             context: Mapping[str, Sequence[str]]) -> bool:
    unknown = set(statement) - {"Sid", "Effect", "Action", "NotAction", "Resource", "NotResource", "Condition"}
    if unknown:
        raise ValueError(f"statement {statement.get('Sid')}: {sorted(unknown)} are not evaluated here")
    if "Action" in statement:
        hit = any(_pattern(a, case=False).match(action) for a in _listed(statement["Action"]))
    else:
        hit = not any(_pattern(a, case=False).match(action) for a in _listed(statement["NotAction"]))
    if not hit:
        return False
    resources = [_substitute(r, context) for r in _listed(statement.get("Resource", statement.get("NotResource")))]
    on = any(_pattern(r, case=True).match(resource) for r in resources)
    if on != ("Resource" in statement):
        return False
    return all(_condition(op, key, wanted, context)
               for op, keys in statement.get("Condition", {}).items() for key, wanted in keys.items())


def decide(document: Mapping[str, Any], action: str, resource: str,
           context: Mapping[str, Sequence[str]] | None = None) -> str:
    """``allowed``, ``explicitDeny`` or ``implicitDeny`` (the simulator's words) for one request."""
    context = context or {}
    effects = {s["Effect"] for s in document["Statement"] if _applies(s, action, resource, context)}
    return "explicitDeny" if "Deny" in effects else "allowed" if "Allow" in effects else "implicitDeny"
