"""``fogiac vpn up|down|status``: run the edge's OpenVPN on the stack's Client VPN profile.

Thin: picks the profile (``--profile PATH``, else the one in the state folder of the
manifest's stack for ``--env``), calls
:mod:`fogiac.net.vpn`, prints one line. Everything is idempotent and exits 0 when there is
nothing to do; errors (not root, no openvpn, tunnel failed) exit 1 with one line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

_MANIFEST = typer.Argument(Path("fogiac.yaml"), help="The manifest whose stack's profile to use.")
_PROFILE = typer.Option(None, "--profile", help="Use this client.ovpn instead.", dir_okay=False)
_ENV = typer.Option("dev", "--env", help="The manifest's environment (stack name-ENV).")


def _profile(manifest: Path, profile: Optional[Path], env: str) -> Path:
    if profile is not None:
        return profile.expanduser().resolve()
    from fogiac.compile import stack_name
    from fogiac.manifest import load_manifest
    from fogiac.net.vpn import default_profile_path

    return default_profile_path(stack_name(load_manifest(manifest), env), create=False)


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
    def up(manifest: Path = _MANIFEST, profile: Optional[Path] = _PROFILE, env: str = _ENV,
           timeout: float = typer.Option(30.0, help="Seconds to wait for the tunnel.")) -> None:
        """Start OpenVPN and wait until the tunnel is up."""
        from fogiac.net.vpn import tunnel_up

        outcome = tunnel_up(profile=_profile(manifest, profile, env), timeout=timeout)
        prefix = "VPN up" if outcome.changed else "VPN already up"
        typer.echo(f"{prefix}: {_describe(outcome.status)}")

    @vpn.command("down")
    def down(manifest: Path = _MANIFEST, profile: Optional[Path] = _PROFILE, env: str = _ENV) -> None:
        """Stop OpenVPN and wait for it to exit."""
        from fogiac.net.vpn import tunnel_down

        outcome = tunnel_down(profile=_profile(manifest, profile, env))
        typer.echo("VPN down" if outcome.changed else "VPN not running")

    @vpn.command("status")
    def status(manifest: Path = _MANIFEST, profile: Optional[Path] = _PROFILE, env: str = _ENV) -> None:
        """Say whether OpenVPN runs, on which tun device, with which address."""
        from fogiac.net.vpn import tunnel_status

        typer.echo(f"VPN {_describe(tunnel_status(profile=_profile(manifest, profile, env)))}")

    app.add_typer(vpn, name="vpn")
