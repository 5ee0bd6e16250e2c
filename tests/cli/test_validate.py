"""`fogiac validate` and `fogiac schema` through the real CLI app."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from fogiac.cli import app

from ..conftest import EXAMPLES

runner = CliRunner()


def test_validate_a_good_manifest() -> None:
    result = runner.invoke(app, ["validate", str(EXAMPLES / "motion-planning.yaml")])
    assert result.exit_code == 0, result.output
    assert "valid (1 node, 1 host, target aws)" in result.output


def test_validate_reports_each_problem_on_one_line_exit_1(tmp_path: Path) -> None:
    bad = tmp_path / "fogiac.yaml"
    bad.write_text("name: x\nnodes:\n  - name: a\n    machine: g4dn.xlrge\n    image: i\n  - name: a\n    machine: t3.micro\n")
    result = runner.invoke(app, ["validate", str(bad)])
    assert result.exit_code == 1
    assert result.output.splitlines() == [
        f"{bad}:4: nodes[0].machine: 'g4dn.xlrge' is not a known instance type; did you mean 'g4dn.xlarge'?",
        f"{bad}:6: nodes[1]: needs exactly one of image, build, launch, workload or command (got none)",
        f"{bad}:6: nodes[1].name: duplicate node name 'a'",  # a rule across nodes, in the same run
    ]
    assert "Traceback" not in result.output


def test_validate_for_a_target_that_cannot_compile() -> None:
    result = runner.invoke(app, ["validate", str(EXAMPLES / "minimal.yaml"), "--target", "hosts"])
    assert result.exit_code == 1
    assert result.output.strip() == "error: cloud.hosts: the hosts target needs at least one machine"


def test_schema_is_json() -> None:
    result = runner.invoke(app, ["schema"])
    assert result.exit_code == 0
    assert json.loads(result.output)["title"] == "fogiac manifest"


def test_validate_imports_neither_pulumi_nor_boto3() -> None:
    code = (
        "import sys; from fogiac.cli import main; sys.argv=['fogiac','validate',%r]\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "bad=[m for m in sys.modules if m.split('.')[0] in ('pulumi','pulumi_aws','boto3','botocore','torch','fabric')]\n"
        "print(bad)"
    ) % str(EXAMPLES / "minimal.yaml")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_init_writes_a_valid_starter_and_never_overwrites(tmp_path: Path) -> None:
    path = tmp_path / "fogiac.yaml"
    result = runner.invoke(app, ["init", str(path), "--name", "rover"])
    assert result.exit_code == 0, result.output
    check = runner.invoke(app, ["validate", str(path)])
    assert check.exit_code == 0 and "valid (1 node" in check.output
    again = runner.invoke(app, ["init", str(path)])
    assert again.exit_code == 1 and again.output.strip() == f"error: {path} exists; edit it, or pick another path"
    bad = runner.invoke(app, ["init", str(tmp_path / "other.yaml"), "--name", "Bad Name"])
    assert bad.exit_code == 1 and not (tmp_path / "other.yaml").exists()


def test_cost_lists_instances_and_client_vpn_per_hour_day_month() -> None:
    result = runner.invoke(app, ["cost", str(EXAMPLES / "motion-planning.yaml")])
    assert result.exit_code == 0, result.output
    assert "instance planner (c5.24xlarge)" in result.output
    assert "Client VPN subnet association" in result.output
    assert "4.2300" in result.output and "101.52" in result.output and "3087.90" in result.output  # 730 h


def test_a_requirements_file_with_a_pip_option_is_refused_by_validate(tmp_path: Path) -> None:
    """The same one line `up` would give on the host, before anything is planned or created."""
    (tmp_path / "ws" / "src").mkdir(parents=True)
    (tmp_path / "requirements.txt").write_text("shellingham==1.5.4\n--index-url http://elsewhere/simple\n")
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text("name: rq\nedge: {ros_master: http://localhost:11311}\nnodes:\n  - name: talker\n"
                        "    machine: t3.small\n    launch: {package: p, file: t.launch, workspace: ws, "
                        "requirements: requirements.txt}\n")
    result = runner.invoke(app, ["validate", str(manifest)])
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == [
        f"{manifest}:6: nodes[0].launch.requirements: requirements.txt:2: --index-url: only package specifiers "
        "are allowed here; the host's pip settings choose the index"]
