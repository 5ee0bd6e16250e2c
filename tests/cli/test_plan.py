"""``fogiac plan`` through the real CLI: tables, the JSON document, --out, --detailed-exitcode."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import deployment
from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import APPLIED_FILE
from fogiac.state import stack_dir, write_json_atomic

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
runner = CliRunner()

PROXY = """\
name: proxied
cloud:
  provider: aws
  region: us-east-1
network:
  mode: proxy
  ssh_from: [100.64.113.7/32]
nodes:
  - name: planner
    machine: c5.4xlarge
    workload: motion_planning
    spot: true
"""


@pytest.fixture
def minimal(tmp_path: Path) -> Path:
    path = tmp_path / "fogiac.yaml"
    shutil.copy(EXAMPLES / "minimal.yaml", path)
    return path


def plan(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, ["plan", *args])
    return result.exit_code, result.output


def test_plan_reads_like_terraform_in_a_ci_log(minimal: Path) -> None:
    code, out = plan(str(minimal))
    assert code == 0, out
    lines = out.splitlines()
    assert "network stack: 29 to create" in lines and "compute stack: 2 to create" in lines
    # one line per resource, its full type token and name, key inputs indented below it
    endpoint = lines.index("  + aws:ec2clientvpn/endpoint:Endpoint minimal-dev-endpoint")
    assert lines[endpoint + 1] == "      clientCidrBlock: 10.200.0.0/22"
    assert "  + aws:ec2/vpc:Vpc minimal-dev-vpc" in lines and "      cidrBlock: 10.10.0.0/16" in lines
    assert "Client VPN subnet association" in out and "Client VPN connection (the edge)" in out
    assert "cost: $0.1708 per hour" in out
    assert "      privateKey: [secret]" in lines


def test_into_a_pipe_no_value_is_cut(minimal: Path) -> None:
    """CliRunner's stdout is no terminal: nothing is fitted to 80 columns, nothing ends in an ellipsis."""
    code, out = plan(str(minimal))
    assert code == 0, out
    assert "…" not in out
    ingress = [line for line in out.splitlines() if line.startswith("  + aws:vpc/securityGroupIngressRule")]
    assert ingress and all(len(line) > 80 for line in ingress)


def test_json_document(minimal: Path) -> None:
    code, out = plan(str(minimal), "--json")
    assert code == 0, out
    doc = json.loads(out)
    assert doc["format_version"] == 2
    assert doc["stack"] == "minimal-dev" and doc["target"] == "aws"
    assert doc["manifest"] == {"path": str(minimal), "sha256": hashlib.sha256(minimal.read_bytes()).hexdigest()}
    assert doc["stacks"] == ["network", "compute"]
    assert all(set(r) == {"stack", "type", "name", "action", "inputs"} for r in doc["resources"])
    assert {r["stack"] for r in doc["resources"]} == {"network", "compute"}
    assert [h["name"] for h in doc["hosts"]] == ["talker"]
    assert doc["hosts"][0]["vcpus"] == 2 and doc["hosts"][0]["usd_per_hour"] == 0.0208
    assert doc["cost"]["hourly_usd"] == 0.1708
    assert len(doc["plan_digest"]) == 64


@pytest.mark.parametrize("extra", [[], ["--json"]])
def test_no_private_key_text_in_any_output(minimal: Path, extra: list[str]) -> None:
    code, out = plan(str(minimal), *extra)
    assert code == 0, out
    assert "PRIVATE KEY" not in out
    assert "[secret]" in out


def test_out_saves_the_document(minimal: Path, tmp_path: Path) -> None:
    saved = tmp_path / "plans" / "plan.json"
    code, out = plan(str(minimal), "--json", "--out", str(saved))
    assert code == 0, out
    assert json.loads(saved.read_text()) == json.loads(out)
    assert not [p for p in saved.parent.iterdir() if p.name.startswith(".")]


def test_detailed_exitcode_against_the_applied_plan(minimal: Path, _state_dir: Path, tmp_path: Path) -> None:
    assert plan(str(minimal), "--detailed-exitcode")[0] == 2  # never applied
    code, out = plan(str(minimal), "--json", "--detailed-exitcode")
    assert code == 2
    # what every target's up records when it completes: the plan document and the deployment record
    write_json_atomic(stack_dir("minimal-dev") / APPLIED_FILE, json.loads(out))
    deployment.finish(compile_plan(load_manifest(minimal)), minimal, plan_digest=json.loads(out)["plan_digest"])
    assert plan(str(minimal), "--detailed-exitcode")[0] == 0
    assert plan(str(minimal), "--detailed-exitcode", "--env", "prod")[0] == 2
    minimal.write_text(minimal.read_text().replace("t3.small", "t3.medium"))
    assert plan(str(minimal), "--detailed-exitcode")[0] == 2


def test_corrupt_deployment_record_is_an_error(minimal: Path, _state_dir: Path) -> None:
    (_state_dir / "minimal-dev").mkdir()
    (_state_dir / "minimal-dev" / deployment.RECORD_FILE).write_text("{not json")
    code, out = plan(str(minimal), "--detailed-exitcode")
    assert code == 1
    assert "unreadable state file" in out


def test_proxy_mode_plan(tmp_path: Path) -> None:
    manifest = tmp_path / "proxy.yaml"
    manifest.write_text(PROXY)
    code, out = plan(str(manifest), "--json")
    assert code == 0, out
    doc = json.loads(out)
    assert not [r for r in doc["resources"] if r["type"].startswith("aws:ec2clientvpn")]
    relay = [r["inputs"]["cidrIpv4"] for r in doc["resources"] if r["inputs"].get("fromPort") == 11411]
    assert sorted(relay) == ["10.10.0.0/16", "100.64.113.7/32"]
    assert [line["item"] for line in doc["cost"]["lines"]] == [
        "instance planner (c5.4xlarge, spot)"]


def test_local_target_has_no_cloud_resources(minimal: Path) -> None:
    code, out = plan(str(minimal), "--target", "local")
    assert code == 0, out
    assert "no cloud resources (target local)" in out
    assert "talker" in out
    code, out = plan(str(minimal), "--target", "local", "--json")
    assert json.loads(out)["resources"] == [] and json.loads(out)["stacks"] == []


def test_errors_are_one_line_exit_1(minimal: Path, tmp_path: Path) -> None:
    code, out = plan(str(minimal), "--target", "moon")
    assert code == 1
    assert out.strip() == "error: unknown target 'moon'; valid: aws, hosts, local"
    bad = tmp_path / "bad.yaml"
    bad.write_text(minimal.read_text().replace("t3.small", "t3.smal"))
    code, out = plan(str(bad))
    assert code == 1
    assert "nodes[0].machine: 't3.smal' is not a known instance type" in out
    assert "Traceback" not in out


def test_the_cli_loads_no_cloud_sdk_until_plan_runs() -> None:
    code = "import sys, fogiac.cli; print(sorted({m.split('.')[0] for m in sys.modules} & {'pulumi', 'boto3'}))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert done.stdout.strip() == "[]"
