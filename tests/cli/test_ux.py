"""Issue 27: the command line as Terraform's users expect it. Help grouped with the everyday workflow
first, other tools' verbs answered with fogiac's, a missing manifest pointing at `fogiac init`,
`--env`'s suffix shown where the stack's name is, and `fogiac ls` over real state folders."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import deployment, targets
from fogiac.cli import COMMANDS, MAIN_COMMANDS, app
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import plan_document
from fogiac.state import StackState
from tests.conftest import EXAMPLES

needs_ls = pytest.mark.skipif("ls" not in COMMANDS.names(),
                              reason="fogiac's installed entry points predate `ls`: rerun .ci/setup")


def run(*args: str, cwd: Path | None = None, monkeypatch: pytest.MonkeyPatch | None = None) -> tuple[int, str]:
    if cwd is not None and monkeypatch is not None:
        monkeypatch.chdir(cwd)
    result = CliRunner().invoke(app, list(args), env={"COLUMNS": "200"})
    return result.exit_code, result.output


def test_help_lists_the_main_workflow_first_in_its_own_panel() -> None:
    code, out = run("--help")
    assert code == 0, out
    lines = out.splitlines()
    main = next(i for i, line in enumerate(lines) if "Main commands" in line)
    other = next(i for i, line in enumerate(lines) if "Other commands" in line)
    assert main < other
    first_words = [line.strip("│ ").split(" ")[0] for line in lines[main + 1:other - 1]]
    assert [w for w in first_words if w] == list(MAIN_COMMANDS)
    below = {line.strip("│ ").split(" ")[0] for line in lines[other + 1:]}
    assert {"logs", "ssh", "doctor", "sweep", "cost"} <= below
    assert not set(MAIN_COMMANDS) & below


@pytest.mark.parametrize(("verb", "ours"), [("apply", "up"), ("destroy", "down"), ("preview", "plan")])
def test_other_tools_verbs_are_answered_with_fogiacs(verb: str, ours: str) -> None:
    code, out = run(verb, "fogiac.yaml", "--yes")
    assert (code, out) == (2, f"error: fogiac has no `{verb}`; did you mean `fogiac {ours}`?\n")


@pytest.mark.parametrize("verb", [["validate"], ["plan"], ["up", "--yes"], ["status"], ["down", "--yes"], ["cost"]])
def test_a_missing_manifest_suggests_init(verb: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          _state_dir: Path) -> None:
    code, out = run(*verb, cwd=tmp_path, monkeypatch=monkeypatch)
    assert (code, out) == (1, "fogiac.yaml: no such file; `fogiac init` writes a starter manifest\n")
    code, out = run("validate", "robot/fogiac.yaml")
    assert (code, out) == (1, "robot/fogiac.yaml: no such file; `fogiac init robot/fogiac.yaml` writes a "
                              "starter manifest\n")
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_plan_and_cost_say_where_the_stack_names_suffix_comes_from(_state_dir: Path) -> None:
    manifest = str(EXAMPLES / "minimal.yaml")
    code, out = run("plan", manifest, "--env", "prod")
    assert code == 0, out
    assert out.splitlines()[0].startswith("fogiac plan minimal-prod (--env prod): target aws")
    code, out = run("cost", manifest)
    assert code == 0 and "minimal-dev (--env dev; aws, us-west-2)" in out, out


def _deployed(manifest: Path, env: str, *, state: str, hours_ago: float, applied: bool = True) -> str:
    """A stack's state folder as `up` leaves it: the deployment record and (when up finished) the applied plan."""
    plan = compile_plan(load_manifest(manifest), environment=env)
    record = deployment.finish(plan, manifest, plan_digest="x") if state == deployment.COMPLETE else \
        deployment.begin(plan, manifest)
    back = {**record.__dict__, "since_epoch": time.time() - hours_ago * 3600}
    StackState(plan.stack).set(StackState.DEPLOYMENT, back)
    if applied:
        StackState(plan.stack).set(StackState.APPLIED, plan_document(plan, targets.get(plan.target).declare(plan),
                                                                     manifest=manifest))
    return plan.stack


@needs_ls
def test_ls_lists_each_deployed_stack_with_target_state_cost_and_autostop(tmp_path: Path, _state_dir: Path) -> None:
    code, out = run("ls")
    assert (code, out) == (0, f"no stacks deployed from this machine (state in {_state_dir}); "
                              "`fogiac up` deploys one\n")
    motion = tmp_path / "motion.yaml"
    motion.write_text((EXAMPLES / "motion-planning.yaml").read_text())
    minimal = tmp_path / "minimal.yaml"
    minimal.write_text((EXAMPLES / "minimal.yaml").read_text().replace("name: minimal", "name: tiny"))
    _deployed(motion, "prod", state=deployment.COMPLETE, hours_ago=2)
    _deployed(minimal, "dev", state=deployment.PARTIAL, hours_ago=1, applied=False)
    (_state_dir / "not-a-stack").mkdir()  # a folder without a record is not listed
    gone = _deployed(minimal, "old", state=deployment.COMPLETE, hours_ago=1)
    deployment.removed(gone)
    code, out = run("ls")
    assert code == 0, out
    rows = [line for line in out.splitlines() if "│" in line and "stack" not in line]
    assert len(rows) == 2, out
    motion_row = next(r for r in rows if "motion-planning-prod" in r)
    cells = [c.strip() for c in motion_row.split("│")[1:-1]]
    assert cells[:4] == ["motion-planning-prod", "prod", "aws", "up"]
    hourly = StackState("motion-planning-prod").get(StackState.APPLIED)["cost"]["hourly_usd"]
    so_far = re.fullmatch(r"at most \$([\d.]+) \(\$([\d.]+)/h\)", cells[5])
    assert so_far and float(so_far[2]) == pytest.approx(hourly, abs=1e-4), cells
    assert float(so_far[1]) == pytest.approx(2 * hourly, abs=0.02)  # two hours at that rate
    assert "stop after 30m 00s idle" in motion_row
    tiny_row = next(r for r in rows if "tiny-dev" in r)
    assert [c.strip() for c in tiny_row.split("│")[1:5]] == ["tiny-dev", "dev", "aws", "partial"]
    assert "—" in tiny_row  # no applied plan: no cost figure
    code, out = run("stacks", "--all")
    assert code == 0 and "tiny-old" in out and "removed" in out, out
    motion.unlink()
    code, out = run("ls")
    assert code == 0 and "unknown (manifest gone)" in out, out
