"""How ``fogiac status`` reads in a terminal: the lifecycle's part (not deployed, the edge's processes,
the relayed topics) around the target's own rows, and the autostop line every target shows."""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

from fogiac.lifecycle.driver import Target
from fogiac.lifecycle.robots import robots_table
from fogiac.provision import idle
from fogiac.tables import table


def render_status(target: Target, doc: Mapping[str, Any]) -> list[Any]:
    """Rich renderables (or plain strings), one per line or table."""
    if not doc.get("deployed", True):
        if doc.get("unchecked"):  # no record here, and the cloud could not be asked
            return [f"{doc['stack']}: not deployed from this machine (no record); the cloud was not checked for "
                    f"what another machine may have left: {doc['unchecked']}"]
        if doc.get("checked"):
            return [f"{doc['stack']}: not deployed ({doc['checked']}; `fogiac sweep --dry-run` lists anything "
                    "else tagged with the stack)"]
        return [f"{doc['stack']}: not deployed"]
    out = list(target.render_status(doc))
    running = [e for e in doc.get("edge", []) if e["running"]]
    if running:
        out.append("edge processes: " + ", ".join(f"{e['name']} (pid {e['pid']})" for e in running))
    if doc.get("robots"):  # a fleet: one row per robot before its links' topics
        out.append(robots_table(doc["robots"]))
    if doc.get("relays"):
        out.append(relays_table(doc["relays"]))
        out += replicas_lines(doc["relays"])
    return out


def relays_table(links: list[Mapping[str, Any]]) -> Any:
    relays = table("relayed topics (direction as in the manifest: in = robot to node)", "host", "link", "topic",
                   "dir", "msgs", "msgs/s", "KiB/s", "latency ms", "drops")
    for relay in links:
        rtt = f" {relay['rtt_ms']:.2f} ms" if relay.get("rtt_ms") else ""
        link = ("up" if relay.get("connected") else "down") + rtt
        for t in relay.get("topics", []) or [{}]:
            latency = "-" if t.get("latency_ms") is None else f"{t['latency_ms']:.2f}"
            rate = t.get("bytes_per_s")
            host = relay["host"] + (f" ({relay['edge']})" if relay.get("edge") else "")  # a fleet robot's link
            relays.add_row(host, link, t.get("topic", "-"), t.get("direction", "-"),
                           str(t.get("msgs", "-")), str(t.get("msgs_per_s", "-")),
                           "-" if rate is None else f"{rate / 1024:.1f}", latency, str(t.get("drops", "-")))
    return relays


def replicas_lines(links: list[Mapping[str, Any]]) -> list[Any]:
    """The replicated nodes' copies (a link's ``replica``): answers won, latency, health; then one line
    naming each replica that stopped answering or lost its link."""
    rows = [(link["host"], link["replica"]) for link in links if link.get("replica")]
    if not rows:
        return []
    shown = table("replicas (first reply wins)", "node", "replica", "host", "health", "won", "answers",
                  "latency ms (median / p95)", "last answer")

    def ms(value: Any) -> str:
        return "-" if value is None else f"{value:.1f}"

    for host, r in sorted(rows, key=lambda row: (row[1].get("group", ""), row[1].get("index", 0))):
        age = r.get("last_answer_s")
        shown.add_row(r.get("group", "-"), f"{_number(r)}/{r.get('count', '-')}", host,
                      r.get("health", "unknown"), str(r.get("won", 0)), str(r.get("answers", 0)),
                      f"{ms(r.get('latency_ms'))} / {ms(r.get('latency_p95_ms'))}",
                      "-" if age is None else f"{age:g} s ago")
    out: list[Any] = [shown]
    for host, r in rows:
        if r.get("health") == "silent":
            age = r.get("last_answer_s")
            out.append(f"replica {_number(r)} of {r.get('group')} on {host} stopped answering "
                       f"(last answer {'never' if age is None else f'{age:g} s ago'})")
        elif r.get("health") == "down":
            out.append(f"replica {_number(r)} of {r.get('group')} on {host} is not linked (host or its relay down)")
    return out


def _number(r: Mapping[str, Any]) -> str:
    """A replica as people count it: 1 of 2 on ``<node>-r1`` (``index`` counts from 0, as the plan does)."""
    number, index = r.get("number"), r.get("index")
    if isinstance(number, int):
        return str(number)
    return str(index + 1) if isinstance(index, int) and not isinstance(index, bool) else "-"


def duration(seconds: float) -> str:
    minutes = int(seconds // 60)
    return f"{minutes // 60}h{minutes % 60:02d}m" if minutes >= 60 else f"{minutes}m{int(seconds % 60):02d}s"


def autostop_line(state: Mapping[str, Any], now: float | None = None) -> str:
    """``stopped by autostop at 12:03:10 UTC`` or ``idle 4m 10s, stops at ...`` or ``in use``."""
    now = time.time() if now is None else now

    def clock(t: float) -> str:
        return time.strftime("%H:%M:%S UTC", time.gmtime(t))

    if state.get(idle.UNREACHABLE):
        return f"idle time unknown ({idle.UNREACHABLE}: {state[idle.UNREACHABLE]})"
    if state.get("stopped_at"):
        verb = "terminated" if state.get("action") == "terminate" else "stopped"
        return f"{verb} by autostop at {clock(state['stopped_at'])} (idle since {clock(state['idle_since'])})"
    if state.get("idle_since") is None:
        return f"in use (autostop {state.get('action', 'stop')} after idle)"
    idle_s = int(now - state["idle_since"])
    return f"idle {idle_s // 60}m {idle_s % 60}s, autostop at {clock(state['stops_at'])}"
