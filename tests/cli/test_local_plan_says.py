"""Issue 35, item 21: the local plan says what local does. It listed the relay's cloud end on port 11411
while each sandbox's relay listens on a port chosen at ``up``, and a c5.4xlarge of 16 vCPUs with no word
that a sandbox shares this machine."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.targets.local.manifest import Sandboxes
from tests.conftest import EXAMPLES


def test_the_local_plan_says_what_a_sandbox_is(_state_dir: Path) -> None:
    result = CliRunner().invoke(app, ["plan", str(EXAMPLES / "motion-planning.yaml"), "--target", "local"],
                                env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    assert "each host: fogiac relay, cloud end, a free port per sandbox, chosen at the first up" in result.output
    assert "port 11411" not in result.output
    assert Sandboxes.plan_note in result.output.replace("\n", " ")


def test_the_aws_plan_keeps_its_port(_state_dir: Path) -> None:
    result = CliRunner().invoke(app, ["plan", str(EXAMPLES / "motion-planning.yaml")], env={"COLUMNS": "400"})
    assert "each host: fogiac relay, cloud end, port 11411" in result.output, result.output
    assert Sandboxes.plan_note.split(";")[0] not in result.output
