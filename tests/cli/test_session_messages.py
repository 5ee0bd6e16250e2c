"""Issue 17's defects that need no deployment, as the user's session: validate in one round,
one month everywhere, import keeps the GPU, and the small things people notice."""

from __future__ import annotations

import re
from pathlib import Path

from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.plan.compile import compile_plan
from fogiac.manifest.schema import load_manifest

from tests.conftest import EXAMPLES
from tests.test_fogros_import import make_workspace


def run(*args: str) -> tuple[int, list[str]]:
    result = CliRunner().invoke(app, [*args], env={"COLUMNS": "200"})
    return result.exit_code, [line.rstrip() for line in result.output.splitlines()]


def test_5_validate_reports_field_errors_and_cross_field_rules_in_one_run(tmp_path: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text("""\
name: demo
network:
  mode: vpn
  vpc_cidr: 10.10.0.0/16
  client_cidr: 10.10.4.0/22
  ssh_fromm: auto
nodes:
  - name: planner
    machine: c5.4xlrge
    workload: motion_planning
  - name: grasp
    machine: g4dn.xlarge
  - name: planner
    machine: c5.xlarge
    workload: motion_planning
""")
    code, out = run("validate", str(manifest))
    m = str(manifest)
    assert code == 1
    assert out == [
        f"{m}:5: network.client_cidr: 10.10.4.0/22 overlaps vpc_cidr 10.10.0.0/16",
        f"{m}:6: network.ssh_fromm: unknown key; did you mean 'ssh_from'?",
        f"{m}:9: nodes[0].machine: 'c5.4xlrge' is not a known instance type; did you mean 'c5.4xlarge'?",
        f"{m}:11: nodes[1]: needs exactly one of image, build, launch, workload or command (got none)",
        f"{m}:13: nodes[2].name: duplicate node name 'planner'",
    ]


def test_5_a_rule_that_needs_a_broken_field_is_skipped_and_says_so(tmp_path: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text("name: demo\nnetwork:\n  vpc_cidr: 10.10.0.1/16\n  client_cidr: 10.10.0.0/22\n"
                        "nodes:\n  - name: a\n    machine: c5.xlarge\n    workload: motion_planning\n"
                        "    topics:\n      in: /foo\n")
    code, out = run("validate", str(manifest))
    m = str(manifest)
    assert (code, out) == (1, [
        f"{m}:2: network: checks across fields skipped: they need network.vpc_cidr, which has a problem",
        # 10: what is wrong in the author's terms, not pydantic's
        f"{m}:3: network.vpc_cidr: '10.10.0.1/16' has host bits set; did you mean 10.10.0.0/16?",
        f"{m}:10: nodes[0].topics.in: '/foo': should be a list; write [/foo]",
    ])


def test_6_plan_cost_and_up_use_one_month() -> None:
    manifest = EXAMPLES / "motion-planning.yaml"
    hourly = compile_plan(load_manifest(manifest)).hourly_usd
    monthly = f"{hourly * 730:.2f}"
    code, plan = run("plan", str(manifest))
    assert code == 0
    assert f"cost: ${hourly:.4f} per hour (about ${monthly} per month (730 h) if left running)" in plan
    assert plan[-1] == "Plan: 31 to add, 0 to change, 0 to destroy."  # Terraform's summary comes last
    code, cost = run("cost", str(manifest))
    assert code == 0
    assert any("$/month (730 h)" in line for line in cost), cost
    (total,) = [line for line in cost if "total" in line]
    assert total.split("│")[-2].strip() == monthly


def test_8_import_infers_the_gpu_from_the_machine_type_and_says_what_next(tmp_path: Path) -> None:
    robot = make_workspace(tmp_path)
    out_file = tmp_path / "fogiac.yaml"
    code, out = run("import", str(robot), "--out", str(out_file))
    assert code == 0, out
    assert out == [
        f"wrote {out_file}: 2 cloud node(s) from {robot}",
        "inferred dexnet: gpu: true, because g4dn.xlarge has 1 GPU(s) (T4)",
        f"next: fogiac validate {out_file} && fogiac plan {out_file}",
    ]
    nodes = {n.name: n for n in load_manifest(out_file).nodes}
    assert nodes["dexnet"].gpu is True and nodes["cloud-planner"].gpu is False
    code, plan = run("plan", str(out_file))
    assert any(re.search(r"│ dexnet +│ .* │ yes +│$", line) for line in plan), plan  # the GPU column


def test_10_version_short_help_and_no_type_tags_on_flags() -> None:
    code, out = run("--version")
    assert (code, out) == (0, ["fogiac 0.1.0"])
    code, out = run("-h")
    assert code == 0 and any("Usage:" in line for line in out)
    for verb in ("up", "down", "plan", "status", "validate", "logs", "import"):
        code, out = run(verb, "-h")
        assert code == 0, (verb, out)
        assert not any("<bool>" in line for line in out), (verb, out)
        assert any(re.search(r"--help +-h +Show this message", line) for line in out), (verb, out)
