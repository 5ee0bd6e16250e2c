"""Verbs about the manifest itself: ``validate`` and ``schema``. No cloud SDK is imported."""

from __future__ import annotations

import json
from pathlib import Path

import typer

ManifestArg = typer.Argument(Path("fogiac.yaml"), help="The manifest (fogiac.yaml).")


def validate(
    manifest: Path = ManifestArg,
    target: str = typer.Option(None, "--target", help="Check it compiles for this target too."),
) -> None:
    """Check a manifest; print every problem as FILE:LINE: field: what is wrong."""
    from fogiac.compile import compile_plan
    from fogiac.manifest import load_manifest

    loaded = load_manifest(manifest)
    plan = compile_plan(loaded, target=target)
    typer.echo(
        f"{manifest}: valid ({len(loaded.nodes)} node{'s' if len(loaded.nodes) != 1 else ''}, "
        f"{len(plan.hosts)} host{'s' if len(plan.hosts) != 1 else ''}, target {plan.target})"
    )


def schema() -> None:
    """Print the manifest's JSON Schema, for editors to complete and check fogiac.yaml."""
    from fogiac.manifest import json_schema

    typer.echo(json.dumps(json_schema(), indent=2, sort_keys=True))


STARTER = """\
# fogiac.yaml: which ROS nodes run off the robot, where, and over which network.
# Reference: fogiac schema, or the README's manifest reference.
name: {name}
cloud:
  provider: aws        # aws | hosts | local
  region: us-west-2
network:
  mode: vpn            # vpn (AWS Client VPN) | proxy (relay over TLS)
  ssh_from: auto       # your address at `up` time
edge:
  ros_master: http://localhost:11311
nodes:
  - name: planner
    machine: c5.4xlarge
    workload: motion_planning
"""


def init(
    path: Path = typer.Argument(Path("fogiac.yaml"), help="Where to write the starter manifest."),
    name: str = typer.Option("my-robot", "--name", help="Deployment name (DNS-safe)."),
) -> None:
    """Write a starter manifest (never over an existing one)."""
    from fogiac.errors import FogiacError
    from fogiac.manifest import parse_manifest
    from fogiac.state import write_text_atomic

    if path.exists():
        raise FogiacError(f"{path} exists; edit it, or pick another path")
    text = STARTER.format(name=name)
    parse_manifest(text, source=str(path))
    write_text_atomic(path, text)
    typer.echo(f"wrote {path}; next: fogiac validate {path} && fogiac plan {path}")


def cost(
    manifest: Path = ManifestArg,
    target: str = typer.Option(None, "--target", help="aws, hosts or local (default: the manifest's)."),
) -> None:
    """What the deployment costs per hour, day and 30-day month, line by line (on-demand prices)."""
    from rich.console import Console
    from rich.table import Table

    from fogiac.catalog import catalog
    from fogiac.compile import compile_plan
    from fogiac.manifest import load_manifest

    plan = compile_plan(load_manifest(manifest), target=target)
    table = Table(title=f"{plan.stack} ({plan.target}, {plan.region})")
    for column in ("item", "$/hour", "$/day", "$/30 days"):
        table.add_column(column, justify="left" if column == "item" else "right")
    for line in plan.cost:
        table.add_row(line.item, f"{line.total:.4f}", f"{line.total * 24:.2f}", f"{line.total * 720:.2f}")
    total = plan.hourly_usd
    table.add_row("total", f"{total:.4f}", f"{total * 24:.2f}", f"{total * 720:.2f}", style="bold")
    console = Console()
    console.print(table)
    console.print(f"prices: {catalog().source} ({catalog().as_of})", markup=False, style="dim")


def register(app: typer.Typer) -> None:
    app.command()(init)
    app.command()(validate)
    app.command()(schema)
    app.command()(cost)
