"""``fogiac up | down | refresh | status | sweep | doctor``: apply a manifest and undo it.

Thin: each command compiles the manifest, calls :mod:`fogiac.deploy` (or :mod:`fogiac.aws`)
and renders with rich. Applying and deleting ask first unless ``--yes``; with no terminal to
ask on they refuse at once. Heavy imports stay inside the commands.
"""

from __future__ import annotations

import sys
from collections import Counter
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Optional

import typer

_MANIFEST = typer.Argument(Path("fogiac.yaml"), help="The manifest (fogiac.yaml).", dir_okay=False)
_ENV = typer.Option("dev", "--env", help="Environment: one stack per manifest and environment.")
_TARGET = typer.Option(None, "--target", help="aws, hosts or local (default: the manifest's).")
_YES = typer.Option(False, "--yes", "-y", help="Do not ask.")


def _compile(manifest: Path, env: str, target: Optional[str]) -> Any:
    from fogiac.compile import compile_plan
    from fogiac.fogros import load_any

    return compile_plan(load_any(manifest), target=target, environment=env)


def _need_yes(yes: bool, what: str) -> None:
    from fogiac.errors import FogiacError

    if not yes and (sys.stdin is None or not sys.stdin.isatty()):
        raise FogiacError(f"refusing to {what} without --yes: there is no terminal to ask on")


def _show(doc: Mapping[str, Any], report: Any) -> None:
    from rich.console import Console

    console = Console()
    console.print(f"[bold]{doc['stack']}[/]: {report.region} zone {report.zone}, account {report.account}, "
                  f"SSH from {', '.join(report.operator_cidrs)}")
    for stack in doc["stacks"]:
        counts = Counter(r["type"].rsplit(":", 1)[-1] for r in doc["resources"] if r["stack"] == stack)
        console.print(f"  {stack}: " + ", ".join(f"{n} {kind}" for kind, n in sorted(counts.items())))
    for line in doc["cost"]["lines"]:
        console.print(f"  ${line['total']:.4f}/h  {line['item']}")
    total = doc["cost"]["hourly_usd"]
    console.print(f"[bold]cost: ${total:.4f} per hour[/] (about ${total * 730:.2f} per month if left running)")


@contextmanager
def _one_line_each() -> Iterator[None]:
    """Preflight reports every problem at once: print each as its own ``error:`` line."""
    from fogiac.errors import PreflightError

    try:
        yield
    except PreflightError as err:
        for line in str(err).splitlines():
            typer.echo(f"error: {line}", err=True)
        raise typer.Exit(1) from None


class _Progress:
    """A live table of resources being changed, each with its own timer."""

    def __init__(self) -> None:
        import time

        from rich.console import Console
        from rich.live import Live

        from fogiac.engine import Timers

        self.timers = Timers(clock=time.monotonic)
        self.clock = time.monotonic
        self.live = Live(get_renderable=self._table, console=Console(stderr=True), refresh_per_second=2,
                         transient=False)

    def _table(self) -> Any:
        from rich.table import Table

        table = Table(show_header=True, box=None)
        for column in ("", "resource", "type", "time"):
            table.add_column(column)
        now = self.clock()
        for row in list(self.timers.rows.values())[-25:]:
            mark = "[red]✗[/]" if row.failed else "[green]✓[/]" if row.finished is not None else "…"
            table.add_row(mark, f"{row.op} {row.name}", row.type, f"{row.elapsed(now):5.0f}s")
        return table

    def __call__(self, event: Any) -> None:
        """The engine's on_event: the display starts with the first event, after any question."""
        if not self.live.is_started:
            self.live.start()
        self.timers(event)

    def __enter__(self) -> _Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live.is_started:
            self.live.stop()


def up(manifest: Path = _MANIFEST, yes: bool = _YES, env: str = _ENV, target: Optional[str] = _TARGET,
       plan_file: Optional[Path] = typer.Option(None, "--plan", help="Apply only if this saved plan still holds."),
       ssh_from: Optional[str] = typer.Option(None, "--ssh-from", help="Your CIDR for ssh_from: auto."),
       start_edge_master: bool = typer.Option(False, "--start-edge-master",
                                              help="local/hosts: run the edge's roscore too if none answers (demos)."),
       edge_master: Optional[str] = typer.Option(None, "--edge-master", help="Override edge.ros_master."),
       infra_only: bool = typer.Option(False, "--infra-only", help="aws: create the stacks only; provision nothing.")) -> None:
    """Check, show the plan and its cost, ask, then create the machines and start the nodes."""
    from fogiac.deploy import UpOptions, target as target_of
    from fogiac.savedplan import check_saved_plan

    plan = _compile(manifest, env, target)
    chosen = target_of(plan.target)
    _need_yes(yes, "apply")
    if plan_file is not None:
        check_saved_plan(plan_file, manifest=manifest, stack=plan.stack, target=plan.target)
    with _one_line_each(), _Progress() as progress:
        result = chosen.up(plan, UpOptions(
            manifest_path=manifest, yes=yes, ssh_from=ssh_from, show=_show,
            confirm=lambda q: typer.confirm(q, default=False), announce=lambda line: typer.echo(line, err=True),
            on_event=progress, extras={"start_edge_master": start_edge_master, "edge_master": edge_master,
                                         "infra_only": infra_only}))
    if result.report is not None:
        from rich.console import Console

        from fogiac.provision.report import report_table

        Console().print(report_table(result.report))
        for host, connect in sorted(result.outputs.get("relays", {}).items()):
            typer.echo(f"{host}: relay {connect} <-> edge {plan.edge_master if edge_master is None else edge_master}")
    hosts = result.outputs.get("compute", {}).get("hosts", {})
    for name, host in sorted(hosts.items()):
        typer.echo(f"{name}: {host.get('instance_id')} {host.get('machine')} public {host.get('public_ip')} "
                   f"private {host.get('private_ip')}")
    typer.echo(f"applied: {result.applied}")


def down(manifest: Path = _MANIFEST, yes: bool = _YES, env: str = _ENV, target: Optional[str] = _TARGET,
         keep_network: bool = typer.Option(False, "--keep-network", help="Keep the network stack for a fast next up.")) -> None:
    """Destroy compute, then network (past errors), then sweep; exit 1 if anything is left."""
    from fogiac.deploy import DownOptions, target as target_of

    plan = _compile(manifest, env, target)
    chosen = target_of(plan.target)
    _need_yes(yes, "destroy")
    if not yes and not typer.confirm(f"Destroy everything of stack {plan.stack}?", default=False):
        raise typer.Exit(1)
    with _Progress() as progress:
        result = chosen.down(plan, DownOptions(keep_network=keep_network, on_event=progress))
    for line in result.engine_errors:
        typer.echo(f"engine: {line}", err=True)
    if result.engine_errors and result.clean:
        typer.echo("the sweep removed what the engine could not; its state may still list it: "
                   "the next up refreshes first", err=True)
    for item in result.not_checked:
        typer.echo(f"not checked: {item}", err=True)
    for item in result.left:
        typer.echo(f"could not delete: {item}", err=True)
    if result.kept_usd_per_hour is not None:
        typer.echo(f"kept the network stack: ${result.kept_usd_per_hour:.2f}/h while kept "
                   f"(Client VPN association; VPC, subnets and gateway are free)")
    typer.echo(f"{plan.stack}: {'nothing left' if result.clean else f'{len(result.left)} resource(s) left'}")
    if not result.clean:
        raise typer.Exit(1)


def refresh(manifest: Path = _MANIFEST, env: str = _ENV) -> None:
    """Update fogiac's state from what exists in the cloud."""
    from fogiac.engine import Engine
    from fogiac.state import stack_lock

    plan = _compile(manifest, env, None)
    with stack_lock(plan.stack, operation="refresh"):
        results = Engine(plan).refresh()
    for r in results:
        typer.echo(f"{r.layer}: {r.summary}")
    if not all(r.ok for r in results):
        raise typer.Exit(1)


def status(manifest: Path = _MANIFEST, env: str = _ENV, target: Optional[str] = _TARGET,
           as_json: bool = typer.Option(False, "--json", help="Print the status document.")) -> None:
    """The stack's hosts: state, type, addresses, uptime and cost so far."""
    import json

    from rich.console import Console
    from rich.table import Table

    from fogiac.deploy import target as target_of

    plan = _compile(manifest, env, target)
    doc = target_of(plan.target).status(plan)
    if as_json:
        typer.echo(json.dumps(doc, indent=2, sort_keys=True))
        return
    if plan.target != "aws":
        Console().print(*_fleet_tables(doc))
        return
    table = Table(title=f"{plan.stack} ({plan.region})")
    for column in ("host", "instance", "state", "type", "public", "private", "uptime", "cost so far"):
        table.add_column(column)
    for h in doc["hosts"]:
        table.add_row(h["host"], h["instance_id"], h["state"], h["machine"], h["public_ip"] or "-",
                      h["private_ip"] or "-", f"{h['uptime_s'] / 3600:.1f} h", f"${h['cost_usd']:.2f}")
    Console().print(table if doc["hosts"] else f"{plan.stack}: no instances")


def _fleet_tables(doc: Mapping[str, Any]) -> list[Any]:
    """Nodes with their supervision state, then relayed topics with live figures."""
    from rich.table import Table

    if not doc.get("deployed"):
        return [f"{doc['stack']}: not deployed"]
    nodes = Table(title=f"{doc['stack']} ({doc['target']}), edge {doc.get('edge_master')}")
    for column in ("host", "machine", "node", "state", "restarts"):
        nodes.add_column(column)
    for host in doc["hosts"]:
        for node in host["nodes"]:
            state = "-" if "running" not in node else "running" if node["running"] else "failed"
            nodes.add_row(host["host"], host["machine"], node["node"], state, str(node.get("restarts", "-")))
    relays = Table(title="relayed topics")
    for column in ("host", "link", "topic", "dir", "msgs", "msgs/s", "KiB/s", "latency ms", "drops"):
        relays.add_column(column, overflow="fold")
    for relay in doc["relays"]:
        link = ("up" if relay.get("connected") else "down") + (f" {relay['rtt_ms']:.2f} ms" if relay.get("rtt_ms") else "")
        for t in relay.get("topics", []) or [{}]:
            latency = "-" if t.get("latency_ms") is None else f"{t['latency_ms']:.2f}"
            rate = t.get("bytes_per_s")
            relays.add_row(relay["host"], link, t.get("topic", "-"), t.get("direction", "-"), str(t.get("msgs", "-")),
                           str(t.get("msgs_per_s", "-")), "-" if rate is None else f"{rate / 1024:.1f}", latency,
                           str(t.get("drops", "-")))
    return [nodes, relays]


def sweep(manifest: Path = _MANIFEST, env: str = _ENV, yes: bool = _YES,
          dry_run: bool = typer.Option(False, "--dry-run", help="Only list what would be deleted.")) -> None:
    """Delete every resource tagged with the stack, even ones outside fogiac's state."""
    from fogiac.aws import sweep as run_sweep

    plan = _compile(manifest, env, None)
    if not dry_run:
        _need_yes(yes, "sweep")
        if not yes and not typer.confirm(f"Delete everything tagged fogiac:stack={plan.stack}?", default=False):
            raise typer.Exit(1)
    result = run_sweep(plan.stack, region=plan.region, dry_run=dry_run)
    for item in result.found if dry_run else result.deleted:
        typer.echo(f"{'would delete' if dry_run else 'deleted'}: {item}")
    for item in result.not_checked:
        typer.echo(f"not checked: {item}", err=True)
    for line in result.errors if not dry_run else ():
        typer.echo(f"could not delete: {line}", err=True)
    if not dry_run and result.left:
        raise typer.Exit(1)


def doctor(manifest: Path = _MANIFEST, env: str = _ENV, target: Optional[str] = _TARGET,
           ssh_from: Optional[str] = typer.Option(None, "--ssh-from", help="Your CIDR for ssh_from: auto.")) -> None:
    """Run every check `up` makes, create nothing, say what would fail."""
    from fogiac.deploy import doctor as checks, target as target_of

    plan = _compile(manifest, env, target)
    target_of(plan.target)
    results = checks(plan, ssh_from=ssh_from)
    for what, ok, detail in results:
        typer.echo(f"{'ok  ' if ok else 'FAIL'} {what}: {detail}")
    if not all(ok for _, ok, _ in results):
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    for command in (up, down, refresh, status, sweep, doctor):
        app.command()(command)
