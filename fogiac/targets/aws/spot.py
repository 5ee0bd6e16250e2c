"""Spot with fallback: a spot host AWS has no capacity for runs on-demand instead, and says so.

AWS refuses a spot launch with one of a few codes (no capacity in the zone, a maximum price
below the market, the account's spot limit). The engine's error carries the code; ``up`` then
runs the compute stack again with those hosts on-demand and records them in ``outputs.json``, so
later ``up``s keep them on-demand (switching market would replace the instance) until ``down``.
Falling back to another zone instead would move the stack's subnets; fogiac does not.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection

from fogiac.plan.model import Plan
from fogiac.targets.aws.model import vpn_of
from fogiac.targets.aws.placement import cost_lines

ON_DEMAND = "on_demand_fallback"  # in outputs.json: spot hosts that run on-demand
# What AWS answers when a spot launch cannot be had (EC2 API error codes and spot request status codes).
NO_CAPACITY = ("InsufficientInstanceCapacity", "capacity-not-available", "capacity-oversubscribed",
               "SpotMaxPriceTooLow", "price-too-low", "MaxSpotInstanceCountExceeded")


def no_capacity(error: str) -> str:
    """The no-capacity code an engine error names, or ``""``."""
    return next((code for code in NO_CAPACITY if code in error), "")


def on_demand(plan: Plan, hosts: Collection[str]) -> Plan:
    """The plan with ``hosts`` asking for on-demand instead of spot, and priced so."""
    if not any(h.spot and h.name in hosts for h in plan.hosts):
        return plan
    specs = tuple(dataclasses.replace(h, spot=False, spot_usd_per_hour=None) if h.name in hosts else h
                  for h in plan.hosts)
    return dataclasses.replace(plan, hosts=specs, cost=cost_lines(specs, vpn_of(plan), robots=len(plan.edges)))


def fallback_line(plan: Plan, host: str, code: str) -> str:
    spec = next(h for h in plan.hosts if h.name == host)
    return (f"{host}: no spot capacity for {spec.machine} in {plan.zone} ({code}); "
            "running on-demand instead at " + ("an unknown price (the catalogue has none there)"
                                               if spec.usd_per_hour is None else f"${spec.usd_per_hour:.4f}/h"))
