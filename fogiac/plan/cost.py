"""What a plan costs and which machines it uses, as plain rows for tables and JSON.

Pure: prices come from the compiled Plan (the checked-in catalogue), never from an API, so
``fogiac plan`` shows them offline. Totals are on-demand, the most an instance can cost; a spot
instance also carries the catalogue's spot estimate, and the plan its total with spot.
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping
from typing import Any, NamedTuple

from fogiac.manifest.clouds import prices as price_source
from fogiac.plan.model import CostLine, HostSpec, NodeSpec, Plan, Replica

# A month, wherever fogiac prints one: AWS's pricing pages use 730 hours (365 days * 24 / 12).
HOURS_PER_MONTH = 730
MONTH = f"month ({HOURS_PER_MONTH} h)"


def per_month(usd_per_hour: float) -> float:
    return usd_per_hour * HOURS_PER_MONTH


def cost_line(line: CostLine) -> dict[str, Any]:
    return {"item": line.item, "quantity": line.quantity, "usd_per_hour": line.usd_per_hour,
            "total": line.total if line.known else None, "price_unknown": not line.known,
            "spot_usd_per_hour": line.spot_usd_per_hour}


def saving_pct(on_demand: float, spot: float) -> int:
    """How much less the spot price is, in whole percent."""
    return round(100 * (on_demand - spot) / on_demand) if on_demand else 0


def spot_source(target: str | None = None) -> dict[str, str]:
    """Where ``target``'s spot estimates come from (default: the default provider's catalogue)."""
    prices = price_source(target)
    return {"source": prices.spot_source, "as_of": prices.spot_as_of, "method": prices.spot_method}


def cost(plan: Plan) -> dict[str, Any]:
    """``{lines, hourly_usd}``: the target's cost lines (instances, its network's hours); with
    spot hosts also ``spot_hourly_usd`` and where the spot estimate comes from."""
    out: dict[str, Any] = {"lines": [cost_line(line) for line in plan.cost], "hourly_usd": plan.hourly_usd,
                           "unknown": list(plan.unknown_costs)}  # hourly_usd leaves these out: at least that much
    if plan.spot_hourly_usd is not None:
        out["spot_hourly_usd"] = plan.spot_hourly_usd
        out["spot_prices"] = spot_source(plan.target)
    if plan.budget_usd_per_hour is not None:  # absent without one: documents as before
        out["budget_usd_per_hour"] = plan.budget_usd_per_hour
    return out


def budget_words(cost_doc: Mapping[str, Any], *, accept: str) -> str | None:
    """What ``up`` will make of the plan's budget (see :func:`fogiac.plan.guard.over_budget`); None: no budget."""
    budget = cost_doc.get("budget_usd_per_hour")
    if budget is None:
        return None
    total, unknown = cost_doc["hourly_usd"], len(cost_doc.get("unknown") or ())
    head = f"budget: ${budget:.4f}/h (cloud.budget_usd_per_hour)"
    if total > budget:
        return f"{head}: over it; up refuses"
    if unknown:
        return f"{head}: cannot be checked with {unknown} price(s) unknown; up refuses unless {accept}"
    return f"{head}: within it"


def menu_line(row: Mapping[str, Any], *, spot_as_of: str) -> str:
    """A host compile chose by requirement: the choice and the runners-up, at the price that ranked them."""
    def each(option: Mapping[str, Any]) -> str:
        if row["ranked_by"] == "spot" and option.get("spot_usd_per_hour") is not None:
            return f"${option['spot_usd_per_hour']:.4f}/h spot est., ${option['usd_per_hour']:.4f}/h on-demand"
        return f"${option['usd_per_hour']:.4f}/h"

    by = f"spot estimates ({spot_as_of})" if row["ranked_by"] == "spot" else "on-demand prices"
    others = ", ".join(f"{o['machine']} ({each(o)})" for o in row["alternatives"]) or "none"
    return (f"{row['name']}: {row['machine']} ({each(row)}) is the cheapest at {by} with {row['chosen_for']}; "
            f"next: {others}")


def host_row(host: HostSpec) -> dict[str, Any]:
    return {
        "name": host.name,
        "machine": host.machine,
        "chosen_for": host.chosen_for,
        "ranked_by": host.ranked_by,
        "alternatives": [{"machine": o.name, "usd_per_hour": o.usd_per_hour, "spot_usd_per_hour": o.spot_usd_per_hour}
                         for o in host.alternatives],
        "vcpus": host.vcpus,
        "gpus": host.gpus,
        "memory_gib": host.memory_gib,
        "usd_per_hour": host.usd_per_hour,  # None (null): unknown, the catalogue has no price there
        "price_unknown": host.usd_per_hour is None,
        "spot": host.spot,
        "spot_usd_per_hour": host.spot_usd_per_hour,
        "disk_gb": host.disk_gb,
        "image": host.image.description if host.image else None,
        "address": host.address,
        "nodes": list(host.nodes),
    }


def node_row(node: NodeSpec) -> dict[str, Any]:
    if node.build is not None:
        runs = f"build {node.build.context} ({node.build.dockerfile})"
    elif node.image is not None:
        runs = node.image
    elif node.launch is not None:
        runs = f"{node.launch.package}/{node.launch.file}"
    elif node.workload is not None:
        runs = f"workload {node.workload}"
    else:
        runs = shlex.join(node.command)  # in the plan's ROS image
    return {"name": node.name, "host": node.host, "kind": node.kind, "runs": runs, "gpu": node.gpu}


def replica_words(replica: Replica) -> str:
    """``replica 1 of 2`` (and, for a hedged replica, when it is asked)."""
    hedge = f", asked after {replica.hedge_delay_s * 1000:g} ms" if replica.hedge == "delayed" and replica.index else ""
    return f"replica {replica.index + 1} of {replica.count}{hedge}"


def replica_rows(plan: Plan, host: str) -> dict[str, Any]:
    """What a host row says about replicas: nothing for an unreplicated host (its row as before)."""
    route = next((r for r in plan.routes if r.host == host), None)
    spec = plan.host(host)
    out: dict[str, Any] = {"zone": spec.zone} if spec.zone is not None else {}
    if route is not None and route.replica is not None:
        out["replica"] = replica_words(route.replica)
    return out


def replica_hosts(plan: Plan, node: str) -> list[str]:
    """The hosts of ``node``'s replicas in index order; [] when it runs once."""
    found = sorted((r.replica.index, r.host) for r in plan.routes if r.replica is not None and r.replica.group == node)
    return [host for _, host in found]


def hosts(plan: Plan) -> list[dict[str, Any]]:
    return [{**host_row(host), **replica_rows(plan, host.name)} for host in plan.hosts]


def nodes(plan: Plan) -> list[dict[str, Any]]:
    return [{**node_row(node), **({"replica_hosts": reps} if (reps := replica_hosts(plan, node.name)) else {})}
            for node in plan.nodes]


class Rows(NamedTuple):
    """All this module says of one plan, as the plan document shows it: a row per host and per node (in the
    plan's order) and the cost section."""

    hosts: list[dict[str, Any]]
    nodes: list[dict[str, Any]]
    cost: dict[str, Any]


def rows(plan: Plan) -> Rows:
    """The plan's host rows, node rows and cost section, asked of this module in one call."""
    return Rows(hosts=hosts(plan), nodes=nodes(plan), cost=cost(plan))


def rate(usd_per_hour: float | None, digits: int = 4) -> str:
    """A price as a table shows it: ``0.0960``, or ``unknown`` (never ``0.0000``) when there is none."""
    return "unknown" if usd_per_hour is None else f"{usd_per_hour:.{digits}f}"


def unknown_note(unknown: tuple[str, ...] | list[str]) -> str:
    """The line under a total that leaves some lines out: which, and what would fill them."""
    return (f"unknown: {', '.join(unknown)} (the catalogue has no price there; "
            "`fogiac catalog update` fills it where the cloud publishes one)")


def total_words(total: float, unknown: int) -> str:
    """``$0.1920 per hour (about $140.16 per month if left running)``; with unknown prices
    ``at least $0.1920 per hour plus 2 unknown (...)``: a sum that leaves something out says so."""
    month = f"about ${per_month(total):.2f} per {MONTH} if left running"
    if not unknown:
        return f"${total:.4f} per hour ({month})"
    return f"at least ${total:.4f} per hour plus {unknown} unknown (at least {month.removeprefix('about ')})"
