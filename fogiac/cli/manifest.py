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


def register(app: typer.Typer) -> None:
    app.command()(validate)
    app.command()(schema)
