"""``fogiac robot revoke | restore NAME``: cut one robot of a fleet off at once, and let it back, with no
manifest edit and no process restarted.

The record keeps the robot revoked (``StackState.REVOKED``) until ``restore`` or until the manifest drops it;
every host's access file (the relay's ``fleet.json``, Zenoh's ``zenoh-fleet.json``) is rewritten at once, and
each cloud end re-reads it within a second, closing the robot's link and refusing its redials (the relay) or
reloading its rules without it (a Zenoh router), well within 10 s. A refused relay edge end
waits longer between dials (up to 30 s); ``restore`` wakes the robot's edge ends that run on this machine, so
they link within a second or two, and one elsewhere links at its next dial.

``revoke`` leaves the robot's edge processes running: the cut is the cloud ends' refusal, which holds whoever
runs the edge (a robot that runs its own cannot be stopped from here), and the edge backs off on its own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import typer

from fogiac import targets
from fogiac.cli._common import ENV, MANIFEST, TARGET, compile_deployed
from fogiac.errors import FogiacError, ProvisionError
from fogiac.lifecycle.driver import Feature, RobotRefuser
from fogiac.lifecycle.edge import wake_robot
from fogiac.net import middleware
from fogiac.provision.runner import recorded_access, rewrite_fleet_access
from fogiac.state import StackState, stack_lock

robot_app = typer.Typer(help="A fleet's robots: revoke one at once, or restore it.", no_args_is_help=True)


def _change(name: str, manifest: Path, env: str, target: str | None, *, revoke: bool) -> None:
    plan = compile_deployed(manifest, env, target)
    robots = [edge.name for edge in plan.edges]
    if not plan.fleet:
        raise ProvisionError(f"{manifest}: no robots: list; a one-robot stack (edge:) has no robot to "
                             f"{'revoke' if revoke else 'restore'}")
    if name not in robots:
        raise ProvisionError(f"{manifest}: no robot {name!r} in robots: ({', '.join(robots)})")
    if not middleware.deploys_fleet(plan.middleware):
        raise ProvisionError(f"the {plan.middleware} middleware keeps no per-robot access to revoke")
    chosen = targets.get(plan.target)
    if Feature.PROVISIONS not in chosen.features:
        raise ProvisionError(f"target {plan.target} runs its nodes itself: fogiac reaches none of its hosts to "
                             "rewrite their access")
    stack = StackState(plan.stack)

    def change(document: dict[str, Any]) -> None:
        before = document.get(StackState.REVOKED)
        names = {str(n) for n in before} if isinstance(before, list) else set()
        names = names | {name} if revoke else names - {name}
        if names:
            document[StackState.REVOKED] = sorted(names)
        else:
            document.pop(StackState.REVOKED, None)

    with stack_lock(plan.stack, operation="revoke" if revoke else "restore"):
        hosts = {host: access for host, (access, _, _) in recorded_access(stack.folder, chosen.access_from).items()}
        if not hosts or any(spec.name not in hosts for spec in plan.hosts):
            raise ProvisionError(f"stack {plan.stack} is not up; run `fogiac up {manifest}` first")
        stack.update(change)
        report = rewrite_fleet_access(plan, hosts=hosts, state_dir=stack.folder)
        refused, refusal = None, None
        if Feature.REFUSES_ROBOTS in chosen.features:  # its network holds the robot's credential too (aws VPN)
            try:
                refused = cast(RobotRefuser, chosen).refuse_revoked(plan)
            except FogiacError as err:
                refusal = err
    # Its edge ends on this machine waited longer after each refusal (up to 30 s): they dial now. One elsewhere
    # links at its next dial.
    woken = wake_robot(plan, name) if not revoke else []
    for failed in report.failed:
        typer.echo(f"error: {failed.error}", err=True)
    if refusal is not None:
        typer.echo(f"error: {refusal}", err=True)
    elif refused:
        typer.echo(refused)
    done = "revoked: every cloud end refuses its certificate" if revoke else (
        "restored: its edge end links again" + (" now" if woken else " at its next dial (within 30 s)"))
    typer.echo(f"robot {name} {done} ({len(report.hosts) - len(report.failed)} of {len(report.hosts)} hosts)")
    if not report.ok or refusal is not None:
        raise typer.Exit(1)


@robot_app.command("revoke")
def revoke(name: str, manifest: Path = MANIFEST, env: str = ENV, target: str | None = TARGET) -> None:
    """Cut robot NAME off now: every cloud end refuses its certificate until `fogiac robot restore NAME`."""
    _change(name, manifest, env, target, revoke=True)


@robot_app.command("restore")
def restore(name: str, manifest: Path = MANIFEST, env: str = ENV, target: str | None = TARGET) -> None:
    """Let a revoked robot NAME link again."""
    _change(name, manifest, env, target, revoke=False)


def register(app: typer.Typer) -> None:
    app.add_typer(robot_app, name="robot")
