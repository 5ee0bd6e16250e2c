"""``fogiac graph``: draw the deployment (SVG and PNG)."""

from __future__ import annotations

from pathlib import Path

import typer


def graph(
    manifest: Path = typer.Argument(Path("fogiac.yaml"), help="The manifest or a FogROS launch file."),
    out: Path = typer.Option(Path("fogiac-graph"), "--out", "-o", help="Output path without suffix."),
    target: str = typer.Option(None, "--target", help="aws, hosts or local (default: the manifest's)."),
) -> None:
    """Draw edge and cloud sites, machines, nodes and the topics crossing the relay or VPN."""
    from fogiac.compile import compile_plan
    from fogiac.fogros import load_any
    from fogiac.graph import draw

    svg, png = draw(compile_plan(load_any(manifest), target=target), out)
    typer.echo(f"wrote {svg} and {png}")


def register(app: typer.Typer) -> None:
    app.command()(graph)
