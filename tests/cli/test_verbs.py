"""The CLI's verb map matches what each module registers, and a verb loads only its own module."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import typer

import fogiac.cli
from fogiac.cli import COMMANDS, verbs_of
from tests.conftest import EXAMPLES, REPO


def test_every_registered_verb_is_in_the_map_and_nothing_else() -> None:
    modules = [m.name for m in pkgutil.iter_modules(fogiac.cli.__path__) if not m.name.startswith("_")]
    declared = {verb: COMMANDS.value(verb) for verb in COMMANDS.names()}
    elsewhere = {module for module in declared.values() if not module.startswith("fogiac.cli.")}  # a target's verbs
    registered = {verb: module for module in [*(f"fogiac.cli.{m}" for m in modules), *sorted(elsewhere)]
                  for verb in verbs_of(module)}
    assert registered == declared


def test_validate_for_local_loads_neither_the_relay_nor_aws_nor_a_cloud_sdk() -> None:
    """The manifest names EC2 machine types, which the aws ``cloud:`` variant checks (its catalogue,
    read from its folder); nothing of the aws target's lifecycle, engine or SDKs loads."""
    code = ("import sys; from fogiac.cli import app; sys.argv = ['fogiac', 'validate', sys.argv[1], '--target', 'local']\n"
            "try:\n    app()\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in ('fogiac.net.relay.cloud', 'fogiac.targets.aws.vpn', 'fogiac.targets.aws.target',"
            " 'fogiac.targets.aws.engine', 'fogiac.targets.aws.api', 'boto3', 'pulumi') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code, str(EXAMPLES / "motion-planning.yaml")], cwd=REPO,
                         capture_output=True, text=True, check=True)
    assert out.stdout.splitlines()[-1] == "[]", out.stdout + out.stderr


def test_an_unknown_verb_is_clicks_one_line_usage_error() -> None:
    from typer.testing import CliRunner

    result = CliRunner().invoke(fogiac.cli.app, ["deploy"])
    assert result.exit_code == 2
    assert "No such command 'deploy'" in result.output
    assert isinstance(fogiac.cli.app, typer.Typer)
