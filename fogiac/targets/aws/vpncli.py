"""``fogiac vpn up|down|status``: run the edge's OpenVPN on the stack's Client VPN profile.

Thin: picks the profile (``--profile PATH``, else the one in the state folder of the
manifest's stack for ``--env``), calls :mod:`.vpn`, prints one line. Everything is idempotent
and exits 0 when there is nothing to do; errors (not root, no openvpn, tunnel failed) exit 1
with one line. The aws target contributes these commands (plug-in group ``fogiac.commands``);
the CLI imports no target.
"""

from __future__ import annotations

from pathlib import Path

import typer

from fogiac.cli._common import ENV, load
from fogiac.plan.compile import stack_name
from fogiac.targets.aws.vpn import TunnelStatus, default_profile_path, tunnel_down, tunnel_status, tunnel_up

_MANIFEST = typer.Argument(Path("fogiac.yaml"), help="The manifest (or launch file) whose stack's profile to use.")
_PROFILE = typer.Option(None, "--profile", help="Use this client.ovpn instead.", dir_okay=False)
_ROBOT = typer.Option(None, "--robot", help="A fleet's robot: the profile on its own certificate.")


def _profile(manifest: Path, profile: Path | None, env: str, robot: str | None = None) -> Path:
    if profile is not None:
        return profile.expanduser().resolve()

    return default_profile_path(stack_name(load(manifest), env), create=False, robot=robot)


def _describe(status: object) -> str:

    assert isinstance(status, TunnelStatus)
    if not status.running:
        return "stopped"
    where = f" on {status.device}" if status.device else ""
    addr = f" {status.address}" if status.address else ""
    return f"running (pid {status.pid}){where}{addr}"


def register(app: typer.Typer) -> None:
    """Add ``fogiac vpn`` to the CLI (the ``fogiac.commands`` entry point ``vpn`` names this module)."""
    app.add_typer(commands(), name="vpn")


def commands() -> typer.Typer:
    """``fogiac vpn``'s sub-commands."""
    vpn = typer.Typer(help="Run the edge's Client VPN connection (OpenVPN, needs root).",
                      no_args_is_help=True)

    @vpn.command("up")
    def up(manifest: Path = _MANIFEST, profile: Path | None = _PROFILE, env: str = ENV, robot: str | None = _ROBOT,
           timeout: float = typer.Option(30.0, help="Seconds to wait for the tunnel.")) -> None:
        """Start OpenVPN and wait until the tunnel is up."""
        outcome = tunnel_up(profile=_profile(manifest, profile, env, robot), timeout=timeout)
        prefix = "VPN up" if outcome.changed else "VPN already up"
        typer.echo(f"{prefix}: {_describe(outcome.status)}")

    @vpn.command("down")
    def down(manifest: Path = _MANIFEST, profile: Path | None = _PROFILE, env: str = ENV,
             robot: str | None = _ROBOT) -> None:
        """Stop OpenVPN and wait for it to exit."""
        outcome = tunnel_down(profile=_profile(manifest, profile, env, robot))
        typer.echo("VPN down" if outcome.changed else "VPN not running")

    @vpn.command("status")
    def status(manifest: Path = _MANIFEST, profile: Path | None = _PROFILE, env: str = ENV,
               robot: str | None = _ROBOT) -> None:
        """Say whether OpenVPN runs, on which tun device, with which address."""
        typer.echo(f"VPN {_describe(tunnel_status(profile=_profile(manifest, profile, env, robot)))}")

    return vpn
