"""``fogiac import``: a FogROS or FogROS2 launch file becomes the equivalent fogiac.yaml."""

from __future__ import annotations

from pathlib import Path

import typer

from fogiac.errors import FogiacError
from fogiac.manifest.fogros_yaml import comment
from fogiac.manifest.importers import import_file as convert
from fogiac.state import write_text_atomic


def import_launch(
    launch: Path = typer.Argument(..., help="A FogROS .launch or FogROS2 .py launch file."),
    out: Path = typer.Option(Path("fogiac.yaml"), "--out", "-o", help="Where to write the manifest."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing manifest."),
) -> None:
    """Write the fogiac.yaml equivalent of a FogROS or FogROS2 launch file (other nodes stay on the robot)."""
    if out.exists() and not force:
        raise FogiacError(f"{out} exists; pass --force to overwrite it")
    manifest, text, notes = convert(launch, out=out)
    write_text_atomic(out, text)
    # A file name may hold an escape or a line break too: each line printed is one line, with no escapes.
    shown, launch_shown = comment(str(out)), comment(str(launch))
    typer.echo(f"wrote {shown}: {len(manifest.nodes)} cloud node(s) from {launch_shown}")
    for note in notes:
        typer.echo(f"inferred {comment(note)}")
    typer.echo(f"next: fogiac validate {shown} && fogiac plan {shown}")


def register(app: typer.Typer) -> None:
    app.command("import")(import_launch)
