"""``fogiac plan HEAD --against BASE``: table-driven over pairs of manifests, through the real CLI.

Each pair is two versions of one manifest as a pull request would change it; the assertions are
the lines a reviewer reads, the summary line and the exit code of ``--detailed-exitcode``.
"""

from __future__ import annotations

import json
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import __version__
from fogiac.cli import app

runner = CliRunner()
DATA = Path(__file__).parent / "data"

BASE = """\
name: review
cloud: {provider: aws, region: us-west-2}
network:
  mode: vpn
  vpc_cidr: 10.10.0.0/16
  ssh_from: [100.64.113.7/32]
nodes:
  - name: planner
    machine: c5.large
    workload: motion_planning
    topics: {in: [/req], out: [/path]}
"""
GRASP = """\
  - name: grasp
    machine: g4dn.xlarge
    workload: grasp_planning
    gpu: true
"""

FLOWS = BASE.replace("  ssh_from: [100.64.113.7/32]\n", "  ssh_from: [100.64.113.7/32]\n  flow_logs: true\n")
WIDER_EGRESS = BASE.replace("  ssh_from: [100.64.113.7/32]\n", "  ssh_from: [100.64.113.7/32]\n  egress_tcp: [80, 443, 8883]\n")

SPOT_PLANNER = BASE.replace("    workload: motion_planning\n", "    workload: motion_planning\n    spot: true\n")


@dataclass(frozen=True)
class Pair:
    name: str
    base: str
    head: str
    code: int
    summary: str
    lines: tuple[str, ...]  # each must be a line of the output (stripped)
    absent: tuple[str, ...] = ()


PAIRS = (
    Pair("instance type change is an in-place update", BASE, BASE.replace("c5.large", "c5.xlarge"), 2,
         "Plan: 0 to add, 1 to change, 0 to destroy.",
         ("~ aws:ec2/instance:Instance review-dev-host-planner", "instanceType: c5.large -> c5.xlarge",
          "hourly cost: $0.2350 -> $0.3200 (+$0.0850)", "machine: c5.large -> c5.xlarge"),
         ("exposure widened:",)),
    Pair("node added", BASE, BASE + GRASP, 2, "Plan: 1 to add, 0 to change, 0 to destroy.",
         ("+ aws:ec2/instance:Instance review-dev-host-grasp", "+ grasp (g4dn.xlarge, $0.5260/h)",
          "+ grasp on grasp (workload: workload grasp_planning)")),
    Pair("node removed", BASE + GRASP, BASE, 2, "Plan: 0 to add, 0 to change, 1 to destroy.",
         ("- aws:ec2/instance:Instance review-dev-host-grasp", "- grasp (g4dn.xlarge, $0.5260/h)")),
    Pair("topic added cloud -> edge is flagged", BASE, BASE.replace("out: [/path]", "out: [/path, /cmd_vel]"), 2,
         "Plan: 0 to add, 0 to change, 0 to destroy.",
         ("! actuation topic added cloud -> robot: /cmd_vel (host planner): what the cloud side publishes there "
          "moves the robot", "+ /cmd_vel (cloud -> robot, host planner)")),
    Pair("an ordinary topic added cloud -> edge is flagged below", BASE,
         BASE.replace("out: [/path]", "out: [/path, /map]"), 2, "Plan: 0 to add, 0 to change, 0 to destroy.",
         ("! topic added cloud -> edge: /map (from host planner to the robot)",
          "+ /map (cloud -> robot, host planner)"), ("actuation",)),
    Pair("ssh_from widened is flagged", BASE, BASE.replace("100.64.113.7/32", "100.64.113.0/24"), 2,
         "Plan: 1 to add, 0 to change, 1 to destroy.",
         ("! CIDR widened: hosts tcp 22 from 100.64.113.7/32 to 100.64.113.0/24 (SSH from the operator)",
          "+ hosts ingress tcp 22 100.64.113.0/24 (SSH from the operator)",
          "- hosts ingress tcp 22 100.64.113.7/32 (SSH from the operator)",
          "+ aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule review-dev-hosts-in-tcp-22-100.64.113.0-24")),
    Pair("VPC CIDR change replaces the network and everything in it", BASE,
         BASE.replace("10.10.0.0/16", "10.20.0.0/16"), 2, "Plan: 25 to add, 2 to change, 25 to destroy.",
         ("-/+ aws:ec2/vpc:Vpc review-dev-vpc", "cidrBlock: 10.10.0.0/16 -> 10.20.0.0/16  # forces replacement",
          "-/+ aws:ec2/subnet:Subnet review-dev-subnet-hosts",
          "vpcId: <review-dev-vpc.id> -> (known after apply)  # forces replacement",
          "-/+ aws:ec2/instance:Instance review-dev-host-planner",
          "subnetId: <review-dev-subnet-hosts.id> -> (known after apply)  # forces replacement",
          "~ aws:ec2/internetGateway:InternetGateway review-dev-igw")),
    Pair("spot turned on is priced at the spot estimate, on-demand beside", BASE, SPOT_PLANNER, 2,
         "Plan: 1 to add, 0 to change, 1 to destroy.",
         ("hourly cost: $0.2350 -> $0.1789 (-$0.0561), spot hosts at the catalogue's spot estimate of 2025-06-28; "
          "at on-demand prices $0.2350 -> $0.2350", "spot: false -> true",
          "instanceMarketOptions.marketType: null -> spot  # forces replacement")),
    Pair("spot node added", BASE, BASE + GRASP + "    spot: true\n", 2, "Plan: 1 to add, 0 to change, 0 to destroy.",
         ("hourly cost: $0.2350 -> $0.4244 (+$0.1894), spot hosts at the catalogue's spot estimate of 2025-06-28; "
          "at on-demand prices $0.2350 -> $0.7610",
          "+ grasp (g4dn.xlarge, spot, about $0.1894/h est., $0.5260/h on-demand)")),
    Pair("egress widened is flagged", BASE, WIDER_EGRESS, 2, "Plan: 1 to add, 0 to change, 0 to destroy.",
         ("! egress added to the internet: hosts tcp 8883 to 0.0.0.0/0 "
          "(TCP 8883 to the internet (updates, images and packages))",
          "+ hosts egress tcp 8883 0.0.0.0/0 (TCP 8883 to the internet (updates, images and packages))",
          "+ aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule review-dev-hosts-out-tcp-8883-0.0.0.0-0")),
    Pair("flow logs turned off removes their log group, role and flow log", FLOWS, BASE, 2,
         "Plan: 0 to add, 0 to change, 4 to destroy.",
         ("- aws:ec2/flowLog:FlowLog review-dev-flow-log", "- aws:cloudwatch/logGroup:LogGroup review-dev-flow-logs",
          "- aws:iam/role:Role review-dev-flow-logs-role", "- aws:iam/rolePolicy:RolePolicy review-dev-flow-logs-policy")),
    Pair("no change", BASE, BASE, 0, "", ("No changes. Your infrastructure matches the configuration.",),
         ("Plan:",)),
)


@pytest.mark.parametrize("pair", PAIRS, ids=[p.name for p in PAIRS])
def test_pair(pair: Pair, tmp_path: Path) -> None:
    (tmp_path / "base.yaml").write_text(pair.base)
    (tmp_path / "head.yaml").write_text(pair.head)
    result = runner.invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml"),
                                 "--detailed-exitcode"])
    assert result.exit_code == pair.code, result.output
    lines = [line.strip() for line in result.output.splitlines()]
    if pair.summary:
        assert lines[-1] == pair.summary
    for line in pair.lines:
        assert line in lines, f"{line!r} not in output:\n{result.output}"
    for text in pair.absent:
        assert text not in result.output


def test_json_v2_carries_action_before_and_after(tmp_path: Path) -> None:
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "head.yaml").write_text(BASE.replace("c5.large", "c5.xlarge"))
    result = runner.invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml"),
                                 "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    assert doc["format_version"] == 2
    (instance,) = [r for r in doc["resources"] if r["action"] != "no-op"]
    assert instance["action"] == "update" and instance["replace_because"] == []
    assert instance["before"]["instanceType"] == "c5.large" and instance["after"]["instanceType"] == "c5.xlarge"
    assert set(instance["before"]) == {"instanceType", "userData"}  # the cloud-init names the machine
    changes = doc["changes"]
    assert changes["summary"] == "Plan: 0 to add, 1 to change, 0 to destroy." and changes["against"] == "manifest"
    assert (changes["add"], changes["change"], changes["destroy"]) == (0, 1, 0)
    assert changes["cost"] == {"hourly_usd_before": 0.235, "hourly_usd_after": 0.32}  # no spot: on-demand only
    assert all("[secret]" == r["inputs"]["privateKey"] for r in doc["resources"] if "privateKey" in r["inputs"])


def _repo(tmp_path: Path, base: str, head: str) -> Path:
    repo = tmp_path / "repo"
    repo.mkdir()
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@example.com", "-c", "commit.gpgsign=false"]
    subprocess.run(["git", "init", "-q", "-b", "main", str(repo)], check=True)
    (repo / "fogiac.yaml").write_text(base)
    subprocess.run([*git, "-C", str(repo), "add", "fogiac.yaml"], check=True)
    subprocess.run([*git, "-C", str(repo), "commit", "-q", "-m", "base"], check=True)
    (repo / "fogiac.yaml").write_text(head)
    return repo


def test_against_a_git_revision_renders_the_pull_request_comment(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The CI example's comment for the ssh_from pair, checked in as tests/cli/data/comment-ssh-widened.md."""
    repo = _repo(tmp_path, BASE, BASE.replace("100.64.113.7/32", "100.64.113.0/24").replace("c5.large", "c5.xlarge"))
    monkeypatch.chdir(repo)
    result = runner.invoke(app, ["plan", "fogiac.yaml", "--against", "git:main:fogiac.yaml", "--markdown",
                                 "--detailed-exitcode"])
    assert result.exit_code == 2, result.output
    assert result.output == (DATA / "comment-ssh-widened.md").read_text().replace("{fogiac_version}", __version__)
    same = runner.invoke(app, ["plan", "fogiac.yaml", "--against", "git:HEAD:fogiac.yaml", "--detailed-exitcode"])
    assert same.exit_code == 2  # the working tree differs from the commit


@pytest.mark.parametrize(("against", "error"), [
    ("git:nosuchref:fogiac.yaml", "git:nosuchref:fogiac.yaml: fatal: invalid object name 'nosuchref'."),
    ("git:main:missing.yaml", "git:main:missing.yaml: fatal: path 'missing.yaml' does not exist in 'main'"),
    ("git:main", "git:main: expected git:REF:PATH, e.g. git:origin/main:fogiac.yaml"),
    ("nowhere.yaml", "nowhere.yaml: no such file (--against takes a path or git:REF:PATH)"),
])
def test_bad_base_is_one_line(against: str, error: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(_repo(tmp_path, BASE, BASE))
    result = runner.invoke(app, ["plan", "fogiac.yaml", "--against", against])
    assert result.exit_code == 1
    assert result.output.strip() == error


def test_markdown_comment_prices_spot_at_the_estimate(tmp_path: Path) -> None:
    """The pull-request comment's cost line and host rows for a spot host: the estimate, dated, and on-demand."""
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "head.yaml").write_text(SPOT_PLANNER + GRASP + "    spot: true\n")
    head, base = str(tmp_path / "head.yaml"), str(tmp_path / "base.yaml")
    result = runner.invoke(app, ["plan", head, "--against", base, "--markdown"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[4] == ("hourly cost: $0.2350 -> $0.3683 (+$0.1333), spot hosts at the catalogue's spot estimate of "
                        "2025-06-28; at on-demand prices $0.2350 -> $0.7610  ")
    assert lines[5] == ("monthly cost if left running (730 h): $171.55 -> $268.86 (+$97.31), at on-demand prices "
                        "$171.55 -> $555.53; autostop stops the hosts after 30 idle minutes")
    assert "+ grasp (g4dn.xlarge, spot, about $0.1894/h est., $0.5260/h on-demand)" in lines
    cost = json.loads(runner.invoke(app, ["plan", head, "--against", base, "--json"]).output)["changes"]["cost"]
    assert cost == {"hourly_usd_before": 0.235, "hourly_usd_after": 0.761, "spot_hourly_usd_before": None,
                    "spot_hourly_usd_after": 0.3683, "spot_as_of": "2025-06-28"}
    same = runner.invoke(app, ["plan", head, "--against", head, "--detailed-exitcode"])
    assert same.exit_code == 0, same.output  # equal spot totals: nothing to report


def test_markdown_comment_shows_wider_egress_and_flow_logs_turned_off(tmp_path: Path) -> None:
    """The pull-request comment warns about egress opened to the internet and lists the flow-log resources going."""
    (tmp_path / "base.yaml").write_text(FLOWS)
    (tmp_path / "head.yaml").write_text(WIDER_EGRESS)
    result = runner.invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml"),
                                 "--markdown"])
    assert result.exit_code == 0, result.output
    assert ("> - egress added to the internet: hosts tcp 8883 to 0.0.0.0/0 "
            "(TCP 8883 to the internet (updates, images and packages))") in result.output.splitlines()
    assert "**Plan: 1 to add, 0 to change, 4 to destroy.**  " in result.output.splitlines()
    assert "- aws:ec2/flowLog:FlowLog review-dev-flow-log" in result.output.splitlines()


LOCAL = "name: sandboxed\ncloud: {provider: local}\nnodes:\n  - {name: planner, machine: c5.4xlarge, command: [planner]}\n"
LOCAL_PAIRS = {  # issue 35 item 19: a target without resources counts its hosts
    "machine changed": (LOCAL.replace("c5.4xlarge", "c5.9xlarge"), "Plan: 0 to add, 1 to change, 0 to destroy.",
                        (0, 1, 0)),
    "host added": (LOCAL + "  - {name: grasp, machine: t3.small, command: [grasp]}\n",
                   "Plan: 1 to add, 0 to change, 0 to destroy.", (1, 0, 0)),
    "topic added": (LOCAL.replace("command: [planner]", "command: [planner], topics: {in: [/goal]}"),
                    "Plan: 0 to add, 0 to change, 0 to destroy.", (0, 0, 0)),  # the same host: nothing to count
}


@pytest.mark.parametrize("case", LOCAL_PAIRS, ids=list(LOCAL_PAIRS))
def test_a_local_plan_counts_its_changed_hosts(case: str, tmp_path: Path) -> None:
    head, summary, counts = LOCAL_PAIRS[case]
    (tmp_path / "base.yaml").write_text(LOCAL)
    (tmp_path / "head.yaml").write_text(head)
    argv = ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml")]
    result = runner.invoke(app, [*argv, "--detailed-exitcode"])
    assert result.exit_code == 2, result.output
    assert result.output.splitlines()[-1] == summary
    changes = json.loads(runner.invoke(app, [*argv, "--json"]).output)["changes"]
    assert (changes["summary"], changes["add"], changes["change"], changes["destroy"]) == (summary, *counts)
