"""``fogiac ls`` (also ``fogiac stacks``): every stack deployed from this machine, read from the local state.

Offline and fast: it reads each stack's deployment record and applied plan from the state folder
(:mod:`fogiac.state`) and asks no cloud. The cost so far is the applied plan's hourly cost times the
hours since the first ``up``: an upper bound (hosts that autostop stopped bill less); ``fogiac status``
asks the cloud for the real figure.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import typer

from fogiac import deployment
from fogiac.errors import FogiacError
from fogiac.lifecycle.robots import robot_count
from fogiac.manifest.importers import load_any
from fogiac.plan.compile import compile_plan
from fogiac.plan.guard import duration
from fogiac.state import StackState, stack_names, state_root
from fogiac.tables import console, printable, table, usd

STATES = {deployment.COMPLETE: "up", deployment.PARTIAL: "partial", deployment.REMOVED: "removed"}


def _environment(record: deployment.Deployment, applied: dict[str, Any] | None, name: str | None) -> str | None:
    if applied and isinstance(applied.get("environment"), str):
        return str(applied["environment"])
    if name and record.stack.startswith(f"{name}-"):
        return record.stack[len(name) + 1:]
    return None


def _autostop_and_env(record: deployment.Deployment, applied: dict[str, Any] | None) -> tuple[str, str]:
    """What autostop does for the stack, and its ``--env``, from the manifest that made it (read, compiled offline)."""
    try:
        loaded = load_any(Path(record.manifest))
    except FogiacError:
        env = _environment(record, applied, None)
        return "unknown (manifest gone)", env or "?"
    env = _environment(record, applied, loaded.name) or "?"
    try:
        plan = compile_plan(loaded, target=record.target, environment=env)
    except FogiacError:
        return "unknown (manifest changed)", env
    if plan.autostop is None:
        return "off", env
    return f"{plan.autostop.action} after {duration(plan.autostop.idle_s)} idle", env


def _so_far(applied: dict[str, Any] | None, hours: float) -> str:
    """The cost so far from the applied plan's hourly cost; a record's value that is not an amount (NaN,
    a string, negative) is "unknown", never printed raw or trusted in arithmetic."""
    cost = applied.get("cost") if applied else None
    if not isinstance(cost, dict) or "hourly_usd" not in cost:
        return "—"
    hourly = cost["hourly_usd"]
    rate, total = usd(hourly, digits=4), usd(hourly * hours) if usd(hourly) else None
    unknown = cost.get("unknown")
    if isinstance(unknown, list) and unknown:  # some price is unknown: no bound can be given, only what is known
        return f"unknown ({rate}/h plus {len(unknown)} unknown)" if rate else "unknown"
    return f"at most {total} ({rate}/h)" if rate and total else "unknown"


def rows(*, everything: bool = False, now: float | None = None) -> list[dict[str, str]]:
    """One row per stack with a deployment record (``everything``: also those ``down`` removed)."""
    now = time.time() if now is None else now
    out = []
    for stack in stack_names():
        try:
            record = deployment.read(stack)
        except FogiacError:
            continue  # not a stack fogiac wrote
        if record is None or (not record.exists and not everything):
            continue
        applied = StackState(stack).get(StackState.APPLIED)
        applied = applied if isinstance(applied, dict) else None
        autostop, env = _autostop_and_env(record, applied)
        so_far = "—" if not record.exists else _so_far(applied, max(0.0, now - record.since_epoch) / 3600)
        out.append({"stack": stack, "env": env, "target": record.target,
                    "state": STATES.get(record.state, record.state), "since": record.since,
                    "cost so far": so_far, "autostop": autostop, "manifest": record.manifest,
                    "robots": str(robot_count(stack) or "-")})  # a fleet's robots the record links
    return out


def register(app: typer.Typer) -> None:
    def ls(everything: bool = typer.Option(False, "--all", help="Also stacks that `down` removed."),
           manifests: bool = typer.Option(False, "--manifests", help="Show the manifest file that made each.")) -> None:
        """Every stack deployed from this machine: target, state, robots (a fleet), cost so far, autostop (offline)."""
        found = rows(everything=everything)
        if not found:
            typer.echo("no stacks deployed from this machine (state in "
                       f"{state_root()}); `fogiac up` deploys one")
            return
        fleets = ["robots"] if any(row["robots"] != "-" for row in found) else []  # else the table as before
        columns = ["stack", "env", "target", "state", *fleets, "since", "cost so far", "autostop"] + (
            ["manifest"] if manifests else [])
        out = table(None, *columns)
        for row in found:
            out.add_row(*(printable(row[c]) for c in columns))  # a record's text never drives the terminal
        screen = console()
        screen.print(out)
        screen.print("cost so far: the applied plan's hourly cost since the first up, an upper bound; "
                     "`fogiac status MANIFEST` asks the cloud", markup=False, style="dim")

    app.command("ls")(ls)
    app.command("stacks", help="Same as `fogiac ls`.")(ls)
