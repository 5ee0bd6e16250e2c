"""The operator's cost guard: what a stack still has, what it costs per hour and so far, and a
warning when it has had no edge for longer than its autostop time yet still runs or costs.

Pure: a target gathers the facts (its instances and their state, the network stack's age, when
an edge was last seen) and this module does the sums and the wording, the same for every
target. Prices are the catalogue's: on-demand, except that an instance running as spot (what the
target got, after any fallback) is priced at the catalogue's spot estimate and labelled so, with
the estimate's date; a stopped instance's disk is not in the catalogue and is not counted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from fogiac.manifest.clouds import prices as price_source
from fogiac.plan.model import Plan


@dataclass(frozen=True)
class Billed:
    """One thing the stack still has."""

    item: str
    usd_per_hour: float | None  # what it costs now (0 while stopped); None: unknown (the catalogue has no price)
    since: float | None  # epoch seconds this rate has applied since; None: unknown, nothing counted so far
    running: bool = True  # a stopped host is kept (its disk) but does not run
    spot_estimate: bool = False  # the rate is the catalogue's spot estimate (a spot instance), not a list price


def duration(seconds: float) -> str:
    """``2h 05m``, ``12m 30s``: short enough for a status line."""
    s = max(0, int(seconds))
    if s >= 3600:
        return f"{s // 3600}h {s % 3600 // 60:02d}m"
    return f"{s // 60}m {s % 60:02d}s"


def guard(billed: Sequence[Billed], *, now: float, autostop_s: float | None,
          edge_idle_since: float | None) -> dict[str, Any]:
    """``{lines, usd_per_hour, cost_usd, no_edge_s, warning, spot_estimate_as_of}`` for ``fogiac status``
    (JSON-ready); ``spot_estimate_as_of`` is the spot estimates' date, None when no line is one.

    ``edge_idle_since``: since when no edge has been connected, as far as the target can tell
    (None: one is connected now, or nobody knows). The warning fires when that is longer than
    the autostop time and something still runs or costs: the watchdog did not stop it, or what
    it cannot stop (the Client VPN association) is still billed.
    """
    lines: list[dict[str, Any]] = [{"item": b.item, "usd_per_hour": b.usd_per_hour, "running": b.running,
              "spot_estimate": b.spot_estimate, "since": b.since, "price_unknown": b.usd_per_hour is None,
              "cost_usd": (round(max(0.0, now - b.since) / 3600 * b.usd_per_hour, 4)
                           if b.since is not None and b.usd_per_hour is not None else None)}
             for b in billed]
    unknown = [b.item for b in billed if b.usd_per_hour is None]
    hourly = round(sum(b.usd_per_hour or 0.0 for b in billed), 4)
    no_edge = now - edge_idle_since if edge_idle_since is not None else None
    warning = ""
    if autostop_s is not None and no_edge is not None and no_edge > autostop_s:
        costly = [b.item for b in billed if b.usd_per_hour is None or b.usd_per_hour > 0]
        running = [b.item for b in billed if b.running]
        head = f"no edge for {duration(no_edge)}, longer than autostop's {duration(autostop_s)}"
        if costly:
            about = "about " if any(b.spot_estimate and (b.usd_per_hour or 0) > 0 for b in billed) else ""
            warning = (f"{head}, and this stack still costs {about}{at_least(hourly, len(unknown))} "
                       f"({', '.join(costly)}): `fogiac down` removes it")
        elif running:
            warning = (f"{head}, yet {', '.join(running)} still run: the autostop watchdog did not stop them "
                       "(see its log on the host)")
    # Totals are sums of the known prices; ``unknown`` names what they leave out (null, never 0, in JSON).
    return {"lines": lines, "usd_per_hour": hourly, "unknown": unknown,
            "cost_usd": round(sum(line["cost_usd"] or 0.0 for line in lines), 4),
            "no_edge_s": round(no_edge) if no_edge is not None else None, "warning": warning,
            "spot_estimate_as_of": price_source().spot_as_of if any(b.spot_estimate for b in billed) else None}


def at_least(usd_per_hour: float, unknown: int, *, digits: int = 2) -> str:
    """``$0.19/h``, or ``at least $0.19/h plus 2 unknown`` when some prices are unknown: a sum that leaves
    out what the catalogue cannot price must never read as the whole cost."""
    amount = f"${usd_per_hour:.{digits}f}/h"
    return amount if not unknown else f"at least {amount} plus {unknown} unknown"


ACCEPT_UNKNOWN = "--accept-unknown-cost"  # up's flag that lets an unknown price pass the budget


def over_budget(plan: Plan, *, accept_unknown: bool) -> str | None:
    """Why ``up`` must not apply ``plan`` against its ``cloud.budget_usd_per_hour``, in one line; None: it may.

    The plan is held to the budget at on-demand prices (the most it can cost). A price the catalogue does
    not know cannot be held to anything: it is not 0, so such a plan is refused by name until the price is
    known or the operator says to take it (:data:`ACCEPT_UNKNOWN`); what is known must still fit.
    """
    budget = plan.budget_usd_per_hour
    if budget is None:
        return None
    unknown = plan.unknown_costs
    where = f"cloud.budget_usd_per_hour (${budget:.4f}/h)"
    if plan.hourly_usd > budget:
        return (f"{where}: this plan costs {at_least(plan.hourly_usd, len(unknown), digits=4)} at on-demand "
                "prices, over the budget; raise the budget or ask for smaller machines")
    if unknown and not accept_unknown:
        return (f"{where} cannot be checked: the price of {', '.join(unknown)} in {plan.region} is unknown (the "
                f"catalogue has none there; the rest costs ${plan.hourly_usd:.4f}/h); `fogiac catalog update` fills "
                f"it where the cloud publishes one, or `fogiac up {ACCEPT_UNKNOWN}` applies it anyway")
    return None


def _prices(spot_as_of: str | None) -> str:
    if spot_as_of is None:
        return "on-demand catalogue prices"
    return f"on-demand catalogue prices, spot instances at the catalogue's spot estimate of {spot_as_of}"


def render(doc: dict[str, Any]) -> list[str]:
    """The guard's lines under a status table: the totals, then the warning if any."""
    unknown = len(doc.get("unknown") or ())
    so_far_total = f"${doc['cost_usd']:.2f}" if not unknown else f"at least ${doc['cost_usd']:.2f}"
    out = [f"cost: {at_least(doc['usd_per_hour'], unknown, digits=4)} now, {so_far_total} so far "
           f"({_prices(doc.get('spot_estimate_as_of'))}; stopped hosts' disks not counted)"]
    for line in doc["lines"]:
        so_far = "-" if line["cost_usd"] is None else f"${line['cost_usd']:.2f}"
        estimate = " (spot estimate)" if line.get("spot_estimate") else ""
        rate = "unknown  " if line["usd_per_hour"] is None else f"${line['usd_per_hour']:.4f}/h"
        out.append(f"  {rate}  {so_far:>8} so far  {line['item']}{estimate}")
    if doc["warning"]:
        out.append(f"warning: {doc['warning']}")
    return out


def up_summary(plan: Plan) -> str:
    """``up``'s last word on money: what the stack costs while up and what autostop does about it.

    ``plan`` is the plan as applied: a spot host that fell back to on-demand is on-demand there.
    Spot hosts count at the catalogue's spot estimate, labelled, with on-demand as the ceiling.
    """
    spot = plan.spot_hourly_usd
    prices = price_source(plan.target)
    unknown = len(plan.unknown_costs)
    head = f"cost: {at_least(plan.hourly_usd, unknown, digits=4)} while up"
    if spot is not None:
        head = (f"cost: about ${spot:.4f}/h while up (spot hosts at the catalogue's spot estimate of "
                f"{prices.spot_as_of}; {at_least(plan.hourly_usd, unknown, digits=4)} at on-demand prices, "
                f"the most spot costs)")
    if plan.autostop is None:
        return f"{head}; autostop is off: it costs this until `fogiac down`"
    stop = plan.autostop
    what = "stops the hosts" if stop.action == "stop" else "terminates the hosts"
    tail = ""
    if plan.vpn is not None:
        tail = f"; {prices.network_item} is billed until `fogiac down`"
    return f"{head}; autostop {what} after {duration(stop.idle_s)} without an edge{tail}"
