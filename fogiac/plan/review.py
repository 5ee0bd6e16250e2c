"""A :class:`~fogiac.plan.diff.PlanDiff` as a reviewer reads it: terminal lines, or a pull-request comment.

Pure text, no terminal codes. The comment leads with what a reviewer must not miss: the summary
line, changes that widen exposure, the security-rule changes and the cost change; resources,
hosts, nodes and topics follow. Every value is whole; secrets are ``[secret]`` as the documents
hold them.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from typing import Any

from fogiac.plan.diff import InputChange, PlanDiff, ResourceChange, Section
from fogiac.plan.drift import VERB, Drift

SYMBOL = {"create": "+", "update": "~", "replace": "-/+", "delete": "-"}
NO_CHANGES = "No changes. Your infrastructure matches the configuration."


def _value(value: Any) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}={_value(v)}" for k, v in value.items()) + "}"
    return str(value)


def resource_lines(change: ResourceChange, *, key_inputs: tuple[str, ...] = ()) -> list[str]:
    """``~ TYPE NAME`` then one indented line per changed input (``path: old -> new``)."""
    lines = [f"{SYMBOL[change.action]} {change.type} {change.name}"]
    if change.action == "create":
        lines += [f"    {k}: {_value(change.inputs[k])}" for k in key_inputs if k in change.inputs]
    for c in change.changes:
        lines += _input_lines(c)
    return lines


def _input_lines(c: InputChange) -> list[str]:
    """``path: old -> new``; a multi-line text (cloud-init) as its changed lines only."""
    note = "  # forces replacement" if c.forces_replacement else ""
    texts = (c.before, c.after)
    if all(isinstance(t, str) for t in texts) and any("\n" in t for t in texts):
        changed = [line for line in difflib.ndiff(c.before.splitlines(), c.after.splitlines())
                   if line[:2] in ("- ", "+ ")]
        return [f"    {c.path}: text, {len(changed)} line(s) differ{note}"] + [f"        {line}" for line in changed]
    return [f"    {c.path}: {_value(c.before)} -> {_value(c.after)}{note}"]


def _rule(row: Mapping[str, Any]) -> str:
    return f"{row['group']} {row['direction']} {row['protocol']} {row['ports']} {row['cidr']} ({row['description']})"


def _topic(row: Mapping[str, Any]) -> str:
    arrow = {"to_cloud": "robot -> cloud", "to_edge": "cloud -> robot", "either": "either direction"}
    return f"{row['topic']} ({arrow.get(str(row['direction']), row['direction'])}, host {row['host']})"


def _host(row: Mapping[str, Any]) -> str:
    spot = row.get("spot_usd_per_hour") if row.get("spot") else None
    where = "".join(f", {row[k]}" for k in ("replica", "zone") if row.get(k))  # a replica's host: which, where
    if spot is None:
        return f"{row['name']} ({row['machine']}, ${row['usd_per_hour']:.4f}/h{where})"
    return (f"{row['name']} ({row['machine']}, spot, about ${spot:.4f}/h est., ${row['usd_per_hour']:.4f}/h "
            f"on-demand{where})")


def _node(row: Mapping[str, Any]) -> str:
    hosts = ", ".join(row["replica_hosts"]) if row.get("replica_hosts") else row["host"]
    return f"{row['name']} on {hosts} ({row['kind']}: {row['runs']})"


def section_lines(section: Section, show: Any) -> list[str]:
    lines = [f"+ {show(r)}" for r in section.added] + [f"- {show(r)}" for r in section.removed]
    for c in section.changed:
        lines.append(f"~ {c.key}")
        lines += [f"    {name}: {_value(before)} -> {_value(after)}" for name, before, after in c.fields]
    return lines


def drift_lines(drift: Drift) -> list[str]:
    """``! TYPE NAME changed outside fogiac`` then ``input: applied -> cloud`` per changed input."""
    mark = {"changed": "!", "deleted": "x", "added": "!+"}[drift.status]
    lines = [f"{mark} {drift.type} {drift.name} {VERB[drift.status]}" + (f": {drift.detail}" if drift.detail else "")]
    return lines + [f"    {path}: {_value(applied)} (applied) -> {_value(cloud)} (cloud)"
                    for path, applied, cloud in drift.changes]


def cost_line(diff: PlanDiff) -> str:
    """The hour before and after; with spot hosts on either side, at their spot estimate (dated) and
    at on-demand, the most they cost."""
    before, after = diff.expected_before, diff.expected_after
    delta = after - before
    sign = "+" if delta >= 0 else "-"
    line = f"hourly cost: ${before:.4f} -> ${after:.4f} ({sign}${abs(delta):.4f})"
    if not diff.has_spot:
        return line
    return (f"{line}, spot hosts at the catalogue's spot estimate of {diff.spot_as_of}; "
            f"at on-demand prices ${diff.cost_before:.4f} -> ${diff.cost_after:.4f}")


def sections(diff: PlanDiff) -> list[tuple[str, list[str]]]:
    """(title, lines) for each part of the diff that is not empty, in the order a reviewer reads."""
    out = [("exposure widened", [f"! {line}" for line in diff.exposure]),
           (f"drift (the cloud as refreshed at {diff.refreshed_at})",
            [line for d in diff.drift for line in drift_lines(d)]),
           ("security rules", section_lines(diff.security_rules, _rule)),
           ("cost", [cost_line(diff)] if (diff.cost_before, diff.spot_before) != (diff.cost_after, diff.spot_after)
            else []),
           ("resources", [line for r in diff.changed_resources for line in resource_lines(r)]),
           ("hosts", section_lines(diff.hosts, _host)),
           ("nodes", section_lines(diff.nodes, _node)),
           ("topics crossing the edge", section_lines(diff.topics, _topic)),
           ("settings", [f"~ {k}: {_value(b)} -> {_value(a)}" for k, b, a in diff.settings])]
    return [(title, lines) for title, lines in out if lines]


def terminal(diff: PlanDiff, *, against: str) -> list[str]:
    """The diff for a terminal or CI log; the Terraform summary line last."""
    if diff.empty:
        return [f"compared with {against}", NO_CHANGES]
    lines = [f"compared with {against}"]
    for title, body in sections(diff):
        lines += ["", f"{title}:"] + [f"  {line}" for line in body]
    return lines + ["", diff.summary()]


def comment(diff: PlanDiff, *, stack: str, against: str) -> str:
    """The pull-request comment (GitHub markdown)."""
    head = f"### fogiac plan: `{stack}` against `{against}`\n\n"
    if diff.empty:
        return head + f"**{NO_CHANGES}**\n"
    parts = [head + f"**{diff.summary()}**  \n{cost_line(diff)}\n"]
    for title, body in sections(diff):
        if title == "cost":
            continue  # already under the summary
        if title == "exposure widened":
            parts.append("> [!WARNING]\n> **Exposure widened**\n" + "".join(f"> - {line[2:]}\n" for line in body))
        else:
            parts.append(f"#### {title}\n\n```diff\n" + "\n".join(body) + "\n```\n")
    return "\n".join(parts)
