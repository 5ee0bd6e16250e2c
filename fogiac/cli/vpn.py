"""``fogiac vpn up|down|status``: run the edge's OpenVPN on the stack's Client VPN profile.

Thin: picks the profile (``--profile PATH``, else the stack's state folder), calls
:mod:`fogiac.net.vpn`, prints one line. Everything is idempotent and exits 0 when there is
nothing to do; errors (not root, no openvpn, tunnel failed) exit 1 with one line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

_PROFILE = typer.Option(None, "--profile", help="The client.ovpn to use.", dir_okay=False)
_STACK = typer.Option(None, "--stack", help="Use the profile in this stack's state folder.")


def _profile(profile: Optional[Path], stack: Optional[str]) -> Path:
    from fogiac.errors import VpnError
    from fogiac.net.vpn import default_profile_path

    if profile is not None:
        return profile.expanduser().resolve()
    if stack:
        return default_profile_path(stack)
    raise VpnError("say which VPN profile to use: --profile PATH or --stack NAME")


def _describe(status: object) -> str:
    from fogiac.net.vpn import TunnelStatus

    assert isinstance(status, TunnelStatus)
    if not status.running:
        return "stopped"
    where = f" on {status.device}" if status.device else ""
    addr = f" {status.address}" if status.address else ""
    return f"running (pid {status.pid}){where}{addr}"


def register(app: typer.Typer) -> None:
    vpn = typer.Typer(help="Run the edge's Client VPN connection (OpenVPN, needs root).",
                      no_args_is_help=True)

    @vpn.command("up")
    def up(profile: Optional[Path] = _PROFILE, stack: Optional[str] = _STACK,
           timeout: float = typer.Option(30.0, help="Seconds to wait for the tunnel.")) -> None:
        """Start OpenVPN and wait until the tunnel is up."""
        from fogiac.net.vpn import tunnel_up

        outcome = tunnel_up(profile=_profile(profile, stack), timeout=timeout)
        prefix = "VPN up" if outcome.changed else "VPN already up"
        typer.echo(f"{prefix}: {_describe(outcome.status)}")

    @vpn.command("down")
    def down(profile: Optional[Path] = _PROFILE, stack: Optional[str] = _STACK) -> None:
        """Stop OpenVPN and wait for it to exit."""
        from fogiac.net.vpn import tunnel_down

        outcome = tunnel_down(profile=_profile(profile, stack))
        typer.echo("VPN down" if outcome.changed else "VPN not running")

    @vpn.command("status")
    def status(profile: Optional[Path] = _PROFILE, stack: Optional[str] = _STACK) -> None:
        """Say whether OpenVPN runs, on which tun device, with which address."""
        from fogiac.net.vpn import tunnel_status

        typer.echo(f"VPN {_describe(tunnel_status(profile=_profile(profile, stack)))}")

    app.add_typer(vpn, name="vpn")
