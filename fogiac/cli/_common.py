"""What every CLI module shares: the common options, the one way to load what the user points
at (a fogiac.yaml or a FogROS launch file), and refusing to ask without a terminal."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from fogiac.errors import FogiacError
from fogiac.manifest.fogros import load_any
from fogiac.manifest.schema import Manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan

MANIFEST = typer.Argument(Path("fogiac.yaml"), help="The manifest (fogiac.yaml) or a FogROS launch file.",
                          dir_okay=False)
ENV = typer.Option("dev", "--env", help="Environment: one stack per manifest and environment.")
TARGET = typer.Option(None, "--target", help="Where cloud nodes run: aws, hosts or local (default: the manifest's).")
YES = typer.Option(False, "--yes", "-y", help="Do not ask.")


def load(manifest: Path) -> Manifest:
    """The manifest at ``manifest``, or the one a FogROS launch file implies (read, not executed)."""
    return load_any(manifest)


def compile_for(manifest: Path, env: str = "dev", target: str | None = None) -> Plan:
    return compile_plan(load(manifest), target=target, environment=env)


def need_yes(yes: bool, what: str) -> None:
    if not yes and (sys.stdin is None or not sys.stdin.isatty()):
        raise FogiacError(f"refusing to {what} without --yes: there is no terminal to ask on")
