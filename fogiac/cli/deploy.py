"""``fogiac up | down | refresh | status | sweep | doctor``: apply a manifest and undo it.

Thin: each command compiles the manifest, hands the plan's target (:mod:`fogiac.targets`) to
the lifecycle (:mod:`fogiac.lifecycle`), which runs the sequence, and renders with rich. Applying
and deleting ask first unless ``--yes``; with no terminal to ask on they refuse at once.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import typer
from rich.live import Live

from fogiac import deployment, targets
from fogiac.cli._common import ENV, FORCE, MANIFEST, TARGET, YES, compile_deployed, compile_for, need_yes
from fogiac.cli.plan import render
from fogiac.errors import FogiacError, PreflightError
from fogiac.lifecycle import sequence
from fogiac.lifecycle.driver import DownOptions, Feature, Target, UpOptions
from fogiac.lifecycle.events import Progress, Timers
from fogiac.lifecycle.report import render_status
from fogiac.net import middleware
from fogiac.plan import placeholders
from fogiac.plan.cost import total_words
from fogiac.plan.guard import ACCEPT_UNKNOWN, over_budget, up_summary
from fogiac.plan.model import Plan
from fogiac.plan.review import visible, visible_doc
from fogiac.plan.saved import checked_show
from fogiac.provision import secrets
from fogiac.provision.report import report_table
from fogiac.tables import console, table

INTERRUPTED = 130  # 128 + SIGINT, as a shell reports it


def _show(doc: Mapping[str, Any], summary: tuple[str, ...] | None) -> None:
    """The plan before the question: the target's preflight summary, or (no preflight) the plan itself."""
    if summary is None:
        render(doc)
        return
    doc = visible_doc(doc)  # no value reaches the terminal with a control or bidi character in it
    out = console()
    for line in (visible(line) for line in summary):
        out.print(line, markup=False, highlight=False)
    for stack in doc["stacks"]:
        counts = Counter(r["type"].rsplit(":", 1)[-1] for r in doc["resources"] if r["stack"] == stack)
        out.print(f"  {stack}: " + ", ".join(f"{n} {kind}" for kind, n in sorted(counts.items())))
    for line in doc["cost"]["lines"]:
        out.print(f"  {'unknown' if line['total'] is None else '$' + format(line['total'], '.4f') + '/h'}  "
                  f"{line['item']}")
    total = doc["cost"]["hourly_usd"]
    out.print(f"[bold]cost:[/] {total_words(total, len(doc['cost'].get('unknown') or ()))}")
    spot = doc["cost"].get("spot_hourly_usd")
    if spot is not None:
        out.print(f"with spot: about ${spot:.4f} per hour (the catalogue's spot estimate of "
                  f"{doc['cost']['spot_prices']['as_of']}; never more than on-demand)")


@contextmanager
def _one_line_each() -> Iterator[None]:
    """Preflight reports every problem at once: print each as its own ``error:`` line."""
    try:
        yield
    except PreflightError as err:
        for line in str(err).splitlines():
            typer.echo(f"error: {line}", err=True)
        raise typer.Exit(1) from None


class _Progress:
    """A live table of resources being changed, each with its own timer.

    ``up``'s own steps (the robot's master, each host's provisioning steps: ``op`` ``check`` and
    ``provision``) join the table on a terminal; into a pipe or a log, where a live table only appears
    once it is over, each is one line on stderr as it starts and as it ends, so ``up`` is never silent.
    """

    STEPS = ("check", "provision")  # the lifecycle's events, beside a cloud engine's resources

    def __init__(self) -> None:
        self.timers = Timers(clock=time.monotonic)
        self.clock = time.monotonic
        err = console(stderr=True)
        self.lines = not err.is_terminal
        self.live = Live(get_renderable=self._table, console=err, refresh_per_second=2, transient=False)

    def _table(self) -> Any:
        out = table(None, "", "resource", "type", "time")
        out.box = None
        now = self.clock()
        for row in list(self.timers.rows.values())[-25:]:
            mark = "[red]✗[/]" if row.failed else "[green]✓[/]" if row.finished is not None else "…"
            out.add_row(mark, f"{row.op} {row.name}", row.type, f"{row.elapsed(now):5.0f}s")
        return out

    def _line(self, event: Progress) -> None:
        """One step as a line: ``planner: runtime …`` when it starts, ``planner: runtime changed (2.8s)``
        when it ends (the step names and states of the provisioning report ``up`` ends with)."""
        self.timers(event)
        row = self.timers.rows.get(event.key)
        what = f"{visible(event.name)}: {visible(event.type)}"
        if event.phase == "start":
            detail = f" {visible(event.message)}" if event.op == "check" and event.message else ""
            typer.echo(f"{what}{detail} …", err=True)
        elif event.phase in ("done", "failed") and row is not None:
            failed = "interrupted" if event.message == "interrupted" else "failed"
            said = failed if event.phase == "failed" else event.message if event.op == "provision" else "ok"
            typer.echo(f"{what} {visible(said)} ({row.elapsed(self.clock()):.1f}s)", err=True)

    def __call__(self, event: Progress) -> None:
        """The lifecycle's on_event: the display starts with the first event, after any question."""
        if self.lines and event.op in self.STEPS:
            self._line(event)
            return
        if not self.live.is_started:
            self.live.start()
        self.timers(event)

    def __enter__(self) -> _Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live.is_started:
            self.live.stop()


def up(manifest: Path = MANIFEST, yes: bool = YES, env: str = ENV, target: str | None = TARGET,
       plan_file: Path | None = typer.Option(None, "--plan", help="Apply only if this saved plan still holds."),
       ssh_from: str | None = typer.Option(None, "--ssh-from", help="Your CIDR for ssh_from: auto."),
       start_edge_master: bool = typer.Option(False, "--start-edge-master",
                                              help="local/hosts: run the edge's roscore too if none answers (demos)."),
       edge_master: str | None = typer.Option(None, "--edge-master", help="Override edge.ros_master."),
       infra_only: bool = typer.Option(False, "--infra-only", help="Create the machines only; provision nothing."),
       force: bool = typer.Option(False, "--force", help="Take over a stack another manifest file made (same name "
                                  "and env), or deploy documentation placeholders (example images, addresses)."),
       accept_unknown_cost: bool = typer.Option(False, ACCEPT_UNKNOWN, help="Apply under cloud.budget_usd_per_hour "
                                                "even where the catalogue has no price (the rest must still fit).")
       ) -> None:
    """Check, show the plan and its cost, ask, then create the machines and start the nodes."""
    plan = compile_deployed(manifest, env, target, force=force, has_force=True, creating=True)
    if (problem := over_budget(plan, accept_unknown=accept_unknown_cost)) is not None:
        raise FogiacError(f"{manifest}: {problem}")
    if plan.fleet and not middleware.deploys_fleet(plan.middleware):  # it would link every robot to every topic
        raise FogiacError(f"{manifest}: robots: up deploys a fleet over the relay (ROS 1) and Zenoh (ROS 2) only; "
                          f"the {plan.middleware} middleware has no per-robot access yet (docs/guides/fleet.md); "
                          "use edge: for one robot")
    chosen = targets.get(plan.target)
    need_yes(yes, "apply")
    show: Callable[[Mapping[str, Any], tuple[str, ...] | None], None] = _show
    if plan_file is not None:  # exactly what was reviewed, or nothing: checked now, and again under the lock
        show = checked_show(plan_file, plan, manifest=manifest, show=_show)
    found = placeholders.found(plan)
    if found and not force:  # copied from the documentation: nothing of the user's would run, or be reachable
        raise FogiacError("; ".join(found) + "; up refuses documentation placeholders (pass --force to deploy anyway)")
    if not infra_only:
        secrets.check(plan)  # every named secret readable before anything is created
    try:
        with _one_line_each(), _Progress() as progress:
            result = sequence.up(chosen, plan, UpOptions(
                manifest_path=manifest, yes=yes, ssh_from=ssh_from, show=show,
                confirm=lambda q: typer.confirm(q, default=False), announce=lambda line: typer.echo(line, err=True),
                on_event=progress, start_edge_master=start_edge_master, edge_master=edge_master,
                infra_only=infra_only))
    except KeyboardInterrupt:
        _interrupted(manifest, plan, chosen)
    if result.report is not None:
        console().print(report_table(result.report))
    robots = f"robots {', '.join(edge.name for edge in plan.edges)}" if plan.fleet else ""
    for host, connect in sorted(result.relays.items()):
        typer.echo(f"{host}: relay {connect} <-> {robots or f'edge {result.edge_master}'}")
    for made in result.machines:
        typer.echo(f"{made.host}: {made.id} {made.machine} public {made.public} private {made.private}")
    typer.echo(f"applied: {result.applied}")
    typer.echo(up_summary(result.plan or plan))


def _interrupted(manifest: Path, plan: Plan, chosen: Target) -> None:
    """Ctrl-C during up: say what exists now and how to remove it; exit 130."""
    record = deployment.read(plan.stack)
    if record is None or not record.exists:
        typer.echo("interrupted: nothing was created", err=True)
        raise typer.Exit(INTERRUPTED)
    typer.echo(f"interrupted: up of {plan.stack} stopped part-way; this is what it left:", err=True)
    try:
        console(stderr=True).print(*render_status(chosen, sequence.status(chosen, plan)), sep="\n")
    except FogiacError as err:
        typer.echo(f"(cannot list it: {err})", err=True)
    typer.echo(f"`fogiac down {manifest}` removes it; `fogiac up {manifest}` completes it", err=True)
    raise typer.Exit(INTERRUPTED)


def down(manifest: Path = MANIFEST, yes: bool = YES, env: str = ENV, target: str | None = TARGET,
         keep_network: bool = typer.Option(False, "--keep-network", help="Keep the network stack for a fast next up."),
         force: bool = FORCE) -> None:
    """Destroy compute, then network (past errors), then sweep; exit 1 if anything is left."""
    plan = compile_deployed(manifest, env, target, force=force, has_force=True)
    chosen = targets.get(plan.target)
    need_yes(yes, "destroy")
    if not yes and not typer.confirm(f"Destroy everything of stack {plan.stack}?", default=False):
        raise typer.Exit(1)
    with _Progress() as progress:
        result = sequence.down(chosen, plan, DownOptions(keep_network=keep_network, on_event=progress))
    if not result.existed:
        typer.echo(f"{plan.stack}: not deployed; nothing to remove")
        return
    for line in result.engine_errors:
        typer.echo(f"engine: {line}", err=True)
    if result.engine_errors and result.clean:
        typer.echo("the sweep removed what the engine could not; its state may still list it: "
                   "the next up refreshes first", err=True)
    for item in result.not_checked:
        typer.echo(f"not checked: {item}", err=True)
    for item in result.left:
        typer.echo(f"could not delete: {item}", err=True)
    if result.kept:
        typer.echo(result.kept)
    removed = f"removed {len(result.deleted)} ({', '.join(result.deleted)}); " if result.deleted else ""
    typer.echo(f"{plan.stack}: {removed}{'nothing left' if result.clean else f'{len(result.left)} left'}")
    if not result.clean:
        raise typer.Exit(1)


def refresh(manifest: Path = MANIFEST, env: str = ENV, target: str | None = TARGET) -> None:
    """Update fogiac's state from what exists in the cloud."""
    plan = compile_for(manifest, env, target)
    results = targets.get(plan.target).refresh(plan)
    for r in results:
        typer.echo(f"{r.what}: {r.summary}")
    if not all(r.ok for r in results):
        raise typer.Exit(1)


def status(manifest: Path = MANIFEST, env: str = ENV, target: str | None = TARGET,
           as_json: bool = typer.Option(False, "--json", help="Print the status document.")) -> None:
    """The stack's hosts: state, type, addresses, uptime and cost so far."""
    plan = compile_deployed(manifest, env, target)
    chosen = targets.get(plan.target)
    doc = sequence.status(chosen, plan)
    if as_json:
        typer.echo(json.dumps(doc, indent=2, sort_keys=True))
        return
    console().print(*render_status(chosen, doc), sep="\n")  # each line of a target on its own line
    if target is None and not doc.get("deployed", True) and deployment.read(plan.stack) is None:
        # nothing says where the stack went (a first up that stopped before it made anything leaves no record):
        # the manifest's own target was asked, which may not be the one the operator tried
        others = ", ".join(name for name in targets.names() if name != plan.target)
        typer.echo(f"note: nothing is recorded for {plan.stack} on this machine, so this is target {plan.target} "
                   f"(the manifest's cloud.provider); --target asks another ({others})", err=True)


def sweep(manifest: Path = MANIFEST, env: str = ENV, target: str | None = TARGET, yes: bool = YES,
          dry_run: bool = typer.Option(False, "--dry-run", help="Only list what would be deleted.")) -> None:
    """Delete every resource tagged with the stack, even ones outside fogiac's state."""
    plan = compile_deployed(manifest, env, target)  # the record's target; another manifest's stack is refused
    chosen = targets.get(plan.target)
    if not dry_run and Feature.CREATES_MACHINES in chosen.features:
        need_yes(yes, "sweep")
        if not yes and not typer.confirm(f"Delete everything tagged fogiac:stack={plan.stack}?", default=False):
            raise typer.Exit(1)
    result = chosen.sweep(plan, dry_run=dry_run)
    if result.note:
        typer.echo(result.note)
    for item in result.found if dry_run else result.deleted:
        typer.echo(f"{'would delete' if dry_run else 'deleted'}: {item}")
    for item in result.not_checked:
        typer.echo(f"not checked: {item}", err=True)
    for line in result.errors if not dry_run else ():
        typer.echo(f"could not delete: {line}", err=True)
    if not dry_run and result.left:
        raise typer.Exit(1)


def doctor(manifest: Path = MANIFEST, env: str = ENV, target: str | None = TARGET,
           ssh_from: str | None = typer.Option(None, "--ssh-from", help="Your CIDR for ssh_from: auto.")) -> None:
    """Check what the target needs before up (aws: CLI, credentials, policy, zone, quotas; local: ROS 1 and what
    each workload node imports), create nothing, say what would fail."""
    plan = compile_for(manifest, env, target)
    results = targets.get(plan.target).doctor(plan, ssh_from=ssh_from)
    for check in results:
        typer.echo(f"{'ok  ' if check.ok else 'FAIL'} {check.what}: {check.detail}")
    if not all(check.ok for check in results):
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    for command in (up, down, refresh, status, sweep, doctor):
        app.command()(command)
