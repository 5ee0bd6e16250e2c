"""``fogiac graph``: draw the deployment (SVG and PNG)."""

from __future__ import annotations

from pathlib import Path

import typer

from fogiac.cli._common import MANIFEST, TARGET, compile_for
from fogiac.plan.diagram import draw


def graph(
    manifest: Path = MANIFEST,
    out: Path = typer.Option(Path("fogiac-graph"), "--out", "-o", help="Output path without suffix."),
    target: str | None = TARGET,
) -> None:
    """Draw edge and cloud sites, machines, nodes and the topics crossing the relay or VPN."""
    svg, png = draw(compile_for(manifest, target=target), out)
    typer.echo(f"wrote {svg} and {png}")


def register(app: typer.Typer) -> None:
    app.command()(graph)
