"""A :class:`~fogiac.plan.diff.PlanDiff` as a reviewer reads it: terminal lines, or a pull-request comment.

Pure text, no terminal codes. The comment leads with what a reviewer must not miss: the summary
line, changes that widen exposure, the security-rule changes and the cost change; resources,
hosts, nodes and topics follow. Every value is whole; secrets are ``[secret]`` as the documents
hold them.
"""

from __future__ import annotations

import difflib
import html
import re
from collections.abc import Mapping
from typing import Any

from fogiac.plan.cost import HOURS_PER_MONTH, per_month
from fogiac.plan.diff import InputChange, PlanDiff, ResourceChange, Section, autostop_words
from fogiac.plan.drift import VERB, Drift

# What must never reach a terminal or a comment as it is: C0 and C1 controls (ESC starts colour, OSC 8 links and
# cursor moves; CR and BS overwrite what is shown), DEL, and the bidirectional controls that reorder what a
# reviewer reads (Trojan Source), with the zero-width and separator characters that hide text.
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200b-\u200f\u2028-\u202e\u2060-\u2069\ufeff]")
# Markdown's inline punctuation, backslash-escaped in comment text outside code (CommonMark allows it before any
# ASCII punctuation): no emphasis, link, image, raw HTML, comment, heading or table cell from a value.
_MARKDOWN = re.compile(r"([\\`*_{}\[\]<#|~&])")


def _escape(match: re.Match[str]) -> str:
    char = match.group(0)
    names = {"\t": "\\t", "\n": "\\n", "\r": "\\r", "\x1b": "\\e"}
    if char in names:
        return names[char]
    return f"\\x{ord(char):02x}" if ord(char) <= 0xFF else f"\\u{ord(char):04x}"


def visible(text: str) -> str:
    """``text`` with every control, bidirectional and invisible character shown as an escape (``\\e``,
    ``\\x9b``, ``\\u202e``): printed, it moves no cursor, colours nothing and reorders nothing."""
    return _CONTROL.sub(_escape, text)


def md_text(text: str) -> str:
    """A line for comment text outside code: visible, and every markdown character escaped."""
    return _MARKDOWN.sub(r"\\\1", visible(text))


def md_code(text: str) -> str:
    """``text`` as an inline code span that no backtick in it can close (CommonMark: a longer fence)."""
    text = visible(text)
    ticks = "`" * (max((len(run) for run in re.findall("`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{ticks}{pad}{text}{pad}{ticks}"


def md_block(lines: list[str], info: str = "diff") -> str:
    """Lines as a fenced code block that none of them can close: each made visible (so none holds a line
    break), and a fence longer than any run of backticks in them."""
    body = [visible(line) for line in lines]
    longest = max((len(run) for line in body for run in re.findall("`+", line)), default=0)
    fence = "`" * max(3, longest + 1)
    return f"{fence}{info}\n" + "\n".join(body) + f"\n{fence}\n"


def visible_doc(value: Any) -> Any:
    """A document (or any JSON value) with every string in it :func:`visible`, keys included: what a
    terminal is shown of it."""
    if isinstance(value, str):
        return visible(value)
    if isinstance(value, Mapping):
        return {visible(str(k)): visible_doc(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [visible_doc(v) for v in value]
    return value


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
    price = "cost unknown" if row["usd_per_hour"] is None else f"${row['usd_per_hour']:.4f}/h"
    if spot is None:
        return f"{row['name']} ({row['machine']}, {price}{where})"
    return f"{row['name']} ({row['machine']}, spot, about ${spot:.4f}/h est., {price} on-demand{where})"


def _node(row: Mapping[str, Any]) -> str:
    hosts = ", ".join(row["replica_hosts"]) if row.get("replica_hosts") else row["host"]
    return f"{row['name']} on {hosts} ({row['kind']}: {row['runs']}){_serves(row)}"


def _serves(row: Mapping[str, Any]) -> str:
    """A fleet node's robots, instances and each robot's share of its hour; nothing for a one-robot plan's node."""
    if "serves" not in row:
        return ""
    robots, count = list(row["serves"]), row.get("instances", 1)
    share = row.get("usd_per_hour_per_robot")
    each = "cost unknown" if share is None else f"${share:.4f}/h per robot"
    return (f", serves {len(robots)} robot{'s' if len(robots) != 1 else ''} ({', '.join(robots)}), "
            f"{count} instance{'s' if count != 1 else ''}{' (one per robot)' if count != 1 else ' (shared)'}, {each}")


def _pushed(row: Mapping[str, Any]) -> str:
    return f"{row['node']} {row['what']} {row['path']} (sha256 {str(row['sha256'])[:12]})"


def _robot(row: Mapping[str, Any], verb: str) -> list[str]:
    """An added (or removed) robot, as what it is: its certificate, its access rules and its edge links.
    A fleet document of an older fogiac names the robot and its entry only."""
    lines = [f"robot {row['name']} (ROS master {row.get('entry')})"]
    if "certificate" in row:
        issued = "issued by the stack's CA" if verb == "add" else "no longer accepted by any cloud end"
        lines.append(f"    certificate {row['certificate']} ({issued})")
    if "access" in row:
        lines.append(f"    access rules: {'may' if verb == 'add' else 'no longer'} cross "
                     f"{', '.join(str(t) for t in row['access'])}")
    if "edge_links" in row:
        hosts = [str(h) for h in row["edge_links"]]
        run = "started" if verb == "add" else "stopped"
        lines.append(f"    edge process on this machine: linked to {', '.join(hosts) or 'no host'} ({run})")
    if row.get("instances"):  # its own instances of the per-robot nodes, each beside the host's other processes
        run = "started" if verb == "add" else "stopped"
        lines.append(f"    per-robot instances: {', '.join(str(i) for i in row['instances'])} ({run}; the host's "
                     "other processes untouched)")
    return lines


def robot_lines(section: Section) -> list[str]:
    """Robots added, removed or changed: each its certificate, access rules and edge process, no host."""
    lines = []
    for row in section.added:
        first, *rest = _robot(row, "add")
        lines += [f"+ {first}", *rest]
    for row in section.removed:
        first, *rest = _robot(row, "remove")
        lines += [f"- {first}", *rest]
    for c in section.changed:
        lines.append(f"~ robot {c.key}")
        lines += [f"    {name}: {_value(before)} -> {_value(after)}" for name, before, after in c.fields]
    return lines


def _robots_touch_no_host(diff: PlanDiff) -> list[str]:
    """Said where robots come or go and no host changes: what a reviewer checks before a fleet's ``up``."""
    if diff.robots.empty or not diff.hosts.empty or any(r.action == "replace" for r in diff.resources):
        return []
    names = [f"+{r['name']}" for r in diff.robots.added] + [f"-{r['name']}" for r in diff.robots.removed]
    said = f"robots {', '.join(names)}: " if names else "robots changed: "
    instances = any(r.get("instances") for r in (*diff.robots.added, *diff.robots.removed))
    what = "access rules, edge processes and per-robot instances" if instances else "access rules and edge processes"
    return [said + f"certificates, {what} only; no host is replaced or restarted "
            "(0 hosts to replace)"]


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


def _plus(unknown: int) -> str:
    """`` plus 2 unknown`` after a sum that leaves out prices the catalogue lacks (never read as $0)."""
    return f" plus {unknown} unknown" if unknown else ""


def cost_line(diff: PlanDiff) -> str:
    """The hour before and after; with spot hosts on either side, at their spot estimate (dated) and
    at on-demand, the most they cost."""
    before, after = diff.expected_before, diff.expected_after
    delta = after - before
    sign = "+" if delta >= 0 else "-"
    line = (f"hourly cost: ${before:.4f}{_plus(diff.unknown_before)} -> ${after:.4f}{_plus(diff.unknown_after)} "
            f"({sign}${abs(delta):.4f}{' of what is known' if diff.unknown_before or diff.unknown_after else ''})")
    if not diff.has_spot:
        return line
    return (f"{line}, spot hosts at the catalogue's spot estimate of {diff.spot_as_of}; "
            f"at on-demand prices ${diff.cost_before:.4f} -> ${diff.cost_after:.4f}")


def month_line(diff: PlanDiff) -> str:
    """The month (730 h) before and after, at the hour :func:`cost_line` shows, and the autostop in force."""
    before, after = per_month(diff.expected_before), per_month(diff.expected_after)
    delta = after - before
    sign = "+" if delta >= 0 else "-"
    line = (f"monthly cost if left running ({HOURS_PER_MONTH} h): ${before:.2f}{_plus(diff.unknown_before)} -> "
            f"${after:.2f}{_plus(diff.unknown_after)} "
            f"({sign}${abs(delta):.2f})")
    if diff.has_spot:
        line += f", at on-demand prices ${per_month(diff.cost_before):.2f} -> ${per_month(diff.cost_after):.2f}"
    return line + (f"; {autostop_words(diff.autostop)}" if diff.autostop_known else "")


def _short_type(type_: str) -> str:
    return type_.rsplit(":", 1)[-1]


def consequences(diff: PlanDiff) -> list[str]:
    """What the riskiest changes mean, in words: each replacement, and a shutdown that now deletes."""
    lines = []
    for r in diff.resources:
        if r.action == "replace":
            why = "; ".join(r.because) or "its inputs changed"
            lines.append(f"{r.name} ({_short_type(r.type)}) is replaced, not updated ({why}): it is deleted and a new "
                         "one created with new ids; for a machine that is downtime while the new one starts, and "
                         "its disk and what is on it are lost")
        for c in r.changes:
            if c.path.lower().endswith("shutdownbehavior") and c.after == "terminate":
                lines.append(f"{r.name}: shutdown behaviour {_value(c.before)} -> terminate: a shutdown (autostop's "
                             "included) now deletes the machine and its disk instead of stopping it")
    for name, before, after in diff.settings:
        if name == "autostop" and isinstance(after, Mapping) and after.get("action") == "terminate" and (
                not isinstance(before, Mapping) or before.get("action") != "terminate"):
            lines.append("autostop now terminates the hosts: an idle stack is deleted with its disks, not stopped")
    return lines + _robots_touch_no_host(diff)


def sections(diff: PlanDiff) -> list[tuple[str, list[str]]]:
    """(title, lines) for each part of the diff that is not empty, in the order a reviewer reads."""
    costs = (diff.cost_before, diff.spot_before) != (diff.cost_after, diff.spot_after)
    out = [("exposure widened", [f"! {line}" for line in diff.exposure]),
           ("cost while idle raised", [f"! {line}" for line in diff.cost_risk]),
           ("what this does", [f"! {line}" for line in consequences(diff)]),
           (f"drift (the cloud as refreshed at {diff.refreshed_at})",
            [line for d in diff.drift for line in drift_lines(d)]),
           ("security rules", section_lines(diff.security_rules, _rule)),
           ("cost", [cost_line(diff), month_line(diff)] if costs else []),
           ("resources", [line for r in diff.changed_resources for line in resource_lines(r)]),
           ("robots (certificate, access rules, edge process)", robot_lines(diff.robots)),
           ("hosts", section_lines(diff.hosts, _host)),
           ("nodes", section_lines(diff.nodes, _node)),
           ("topics crossing the edge", section_lines(diff.topics, _topic)),
           ("pushed to the hosts", section_lines(diff.pushed, _pushed)),
           # a fleet's edges are its robots, said above
           ("settings", [f"~ {k}: {_value(b)} -> {_value(a)}" for k, b, a in diff.settings
                         if not (k == "edges" and diff.fleet)])]
    return [(title, lines) for title, lines in out if lines]


def terminal(diff: PlanDiff, *, against: str) -> list[str]:
    """The diff for a terminal or CI log; the Terraform summary line last."""
    if diff.empty:
        return [visible(f"compared with {against}"), NO_CHANGES]
    lines = [f"compared with {against}"]
    for title, body in sections(diff):
        lines += ["", f"{title}:"] + [f"  {line}" for line in body]
    return [visible(line) for line in lines + ["", diff.summary()]]


FOLD_LINES = 20  # a section longer than this is folded in <details> in the comment
_ALERT = {"exposure widened": ("WARNING", "Exposure widened"),
          "cost while idle raised": ("WARNING", "Cost while idle raised"),
          "what this does": ("CAUTION", "What this does")}


def comment(diff: PlanDiff, *, stack: str, against: str, doc: Mapping[str, Any] | None = None,
            placeholders: tuple[str, ...] = ()) -> str:
    """The pull-request comment (GitHub markdown): what the plan is for (target, region, fogiac version),
    the summary, the hour and the month with the autostop in force, warnings, then every section, the long
    ones folded. Every value is escaped: none can close a code block or add markdown or HTML."""
    versus = "(new stack)" if diff.against == "nothing" else f"against {md_code(against)}"
    head = f"### fogiac plan: {md_code(stack)} {versus}\n"
    if doc is not None:
        where = [f"target {md_code(str(doc.get('target')))}"]
        if doc.get("resources"):
            where.append(f"region {md_code(str(doc.get('region')))}")
        where.append(f"fogiac {md_code(str(doc.get('fogiac_version')))}")
        head += " · ".join(where) + "\n"
    head += "\n"
    if placeholders:  # what `up` would refuse: said first, whatever else changes
        head += ("> [!WARNING]\n> **Documentation placeholders (`fogiac up` refuses them)**\n"
                 + "".join(f"> - {md_text(line)}\n" for line in placeholders) + "\n")
    if diff.empty:
        return head + f"**{NO_CHANGES}**\n"
    # fogiac's own words and numbers: nothing in them a manifest chose
    parts = [head + f"**{diff.summary()}**  \n{visible(cost_line(diff))}  \n{visible(month_line(diff))}\n"]
    for title, body in sections(diff):
        if title == "cost":
            continue  # already under the summary
        if title in _ALERT:
            kind, label = _ALERT[title]
            parts.append(f"> [!{kind}]\n> **{label}**\n" + "".join(f"> - {md_text(line[2:])}\n" for line in body))
        elif len(body) > FOLD_LINES:
            parts.append(f"<details><summary>{html.escape(visible(title))} ({len(body)} lines)</summary>\n\n"
                         + md_block(body)
                         + "\n</details>\n")
        else:
            parts.append(f"#### {md_text(title)}\n\n" + md_block(body))
    return "\n".join(parts)
