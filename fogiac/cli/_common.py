"""What every CLI module shares: the common options, the one way to load what the user points
at (a fogiac.yaml or a FogROS launch file), and refusing to ask without a terminal."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from fogiac import deployment, store
from fogiac.errors import FogiacError, ManifestError
from fogiac.manifest.importers import load_any
from fogiac.manifest.schema import Manifest
from fogiac.plan.compile import compile_plan, stack_names
from fogiac.plan.model import Plan

MANIFEST = typer.Argument(Path("fogiac.yaml"), help="The manifest (fogiac.yaml) or a FogROS launch file.",
                          dir_okay=False)
ENV = typer.Option("dev", "--env", help="Environment: one stack per manifest and environment.")
TARGET = typer.Option(None, "--target", help="Where cloud nodes run: aws, hosts or local (default: the manifest's).")
YES = typer.Option(False, "--yes", "-y", help="Do not ask.")
FORCE = typer.Option(False, "--force", help="Take over a stack another manifest file made (same name and env).")


def load(manifest: Path) -> Manifest:
    """The manifest at ``manifest``, or the one a FogROS launch file implies (read, not executed).

    A manifest that is not there is one line that says how to make one.
    """
    if not manifest.exists():
        init = "fogiac init" if manifest == Path("fogiac.yaml") else f"fogiac init {manifest}"
        raise ManifestError([f"{manifest}: no such file; `{init}` writes a starter manifest"])
    loaded = load_any(manifest)
    store.configure(loaded.state.url if loaded.state else None, loaded.state.kms_key if loaded.state else None)
    return loaded


def compile_for(manifest: Path, env: str = "dev", target: str | None = None) -> Plan:
    loaded = load(manifest)
    stack = deployment.stack_for(stack_names(loaded, env), manifest)
    return compile_plan(loaded, target=target, environment=env, stack=stack)


def compile_deployed(manifest: Path, env: str = "dev", target: str | None = None, *, force: bool = False,
                     has_force: bool = False, creating: bool = False) -> Plan:
    """The plan for the target the stack was deployed to (see :mod:`fogiac.deployment`).

    A ``--target`` that disagrees with the deployment, or another manifest file with the same
    stack name, is refused in one line; nothing deployed: ``target`` or the manifest's own.
    """
    loaded = load(manifest)
    stack, chosen = deployment.locate(stack_names(loaded, env), manifest, target, force=force, force_hint=has_force,
                                      creating=creating)
    return compile_plan(loaded, target=chosen, environment=env, stack=stack)


def need_yes(yes: bool, what: str) -> None:
    if not yes and (sys.stdin is None or not sys.stdin.isatty()):
        raise FogiacError(f"refusing to {what} without --yes: there is no terminal to ask on")
