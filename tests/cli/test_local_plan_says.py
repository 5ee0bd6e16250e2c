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


def test_the_local_hosts_table_rents_no_machine(_state_dir: Path) -> None:
    """Item 21: the hosts table listed c5.4xlarge and 16 vCPUs as if a machine were rented on local."""
    result = CliRunner().invoke(app, ["plan", str(EXAMPLES / "motion-planning.yaml"), "--target", "local"],
                                env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    row = next(line for line in result.output.splitlines() if line.startswith("│ planner "))
    cells = [cell.strip() for cell in row.split("│")[1:-1]]
    assert cells[1].startswith("this machine (aws: c5.") and cells[3:7] == ["shared"] * 4, cells


def test_status_with_nothing_recorded_says_which_target_it_asked(tmp_path: Path, _state_dir: Path) -> None:
    """Item 21: after a first `up --target local` that stopped before making anything, `status` (no --target)
    answered for the manifest's cloud target without saying so; `--target local` says nothing of a cloud."""
    manifest = tmp_path / "fogiac.yaml"
    hosts = "provider: hosts\n  hosts:\n    - {name: box, address: 10.0.0.42, user: ubuntu, key: lab_ed25519}"
    manifest.write_text((EXAMPLES / "minimal.yaml").read_text().replace("provider: aws", hosts))
    (tmp_path / "lab_ed25519").write_text("not a key: status reads no machine\n")
    (tmp_path / "lab_ed25519").chmod(0o600)
    result = CliRunner().invoke(app, ["status", str(manifest)], env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    assert result.stderr.strip().startswith("note: nothing is recorded for minimal-dev on this machine, so this is "
                                            "target hosts (the manifest's cloud.provider); --target asks another (")
    assert "local" in result.stderr.splitlines()[-1]
    local = CliRunner().invoke(app, ["status", str(manifest), "--target", "local"], env={"COLUMNS": "400"})
    assert local.exit_code == 0 and local.output.strip() == "minimal-dev: not deployed", local.output
    assert "AWS" not in local.output and "cloud was not checked" not in local.output
