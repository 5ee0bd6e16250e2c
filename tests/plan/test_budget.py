"""Issue 35, "costs that are unknown say so": the cost guard holds a plan to ``cloud.budget_usd_per_hour``
and refuses to pass a price the catalogue does not know (unknown is not $0) unless ``up --accept-unknown-cost``
says so, in one line naming what is unknown."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.guard import over_budget

ROOT = Path(__file__).resolve().parents[2]
MINIMAL = (ROOT / "examples" / "minimal.yaml").read_text()


def budgeted(region: str, budget: str) -> str:
    text = MINIMAL.replace("us-west-2", region)
    return text.replace("cloud:\n", f"cloud:\n  budget_usd_per_hour: {budget}\n", 1)


def test_an_unknown_price_is_refused_against_a_budget_naming_it() -> None:
    plan = compile_plan(parse_manifest(budgeted("sa-east-1", "5")))
    said = over_budget(plan, accept_unknown=False)
    assert said is not None and "\n" not in said
    assert said.startswith("cloud.budget_usd_per_hour ($5.0000/h) cannot be checked: the price of "
                           "instance talker (t3.small) in sa-east-1 is unknown")
    assert "--accept-unknown-cost" in said and "fogiac catalog update" in said
    assert over_budget(plan, accept_unknown=True) is None  # told: what is known fits


def test_what_is_known_must_still_fit() -> None:
    plan = compile_plan(parse_manifest(budgeted("sa-east-1", "0.01")))  # the VPN association alone is $0.15/h
    said = over_budget(plan, accept_unknown=True)
    assert said is not None and "at least $0.1500/h plus 1 unknown at on-demand prices, over the budget" in said


def test_a_priced_plan_is_held_to_its_budget() -> None:
    assert over_budget(compile_plan(parse_manifest(budgeted("us-west-2", "5"))), accept_unknown=False) is None
    said = over_budget(compile_plan(parse_manifest(budgeted("us-west-2", "0.1"))), accept_unknown=False)
    assert said is not None and "over the budget" in said and "at least" not in said
    assert over_budget(compile_plan(parse_manifest(MINIMAL.replace("us-west-2", "sa-east-1"))),
                       accept_unknown=False) is None  # no budget, nothing to hold it to


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "fogiac.yaml").write_text(budgeted("sa-east-1", "5"))
    return tmp_path


def fogiac(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {"PYTHONPATH": str(ROOT), "PATH": os.environ["PATH"], "COLUMNS": "200", "HOME": str(folder),
           "FOGIAC_STATE_DIR": str(folder / "state")}
    return subprocess.run([sys.executable, "-m", "fogiac", *args], cwd=folder, capture_output=True, text=True,
                          timeout=300, env=env)


def test_up_refuses_in_one_line_before_anything(folder: Path) -> None:
    done = fogiac(folder, "up", "--yes")
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert [line for line in done.stderr.splitlines() if not line.startswith("warning:")] == [
        "error: fogiac.yaml: cloud.budget_usd_per_hour ($5.0000/h) cannot be checked: the price of instance talker "
        "(t3.small) in sa-east-1 is unknown (the catalogue has none there; the rest costs $0.1500/h); "
        "`fogiac catalog update` fills it where the cloud publishes one, or `fogiac up --accept-unknown-cost` "
        "applies it anyway"]
    assert not (folder / "state").exists()  # nothing created


def test_plan_says_within_or_over(tmp_path: Path) -> None:
    from fogiac.plan.cost import budget_words, cost
    within = cost(compile_plan(parse_manifest(budgeted("us-west-2", "5"))))
    assert budget_words(within, accept="x") == "budget: $5.0000/h (cloud.budget_usd_per_hour): within it"
    over = cost(compile_plan(parse_manifest(budgeted("us-west-2", "0.1"))))
    assert budget_words(over, accept="x") == "budget: $0.1000/h (cloud.budget_usd_per_hour): over it; up refuses"


def test_plan_says_what_up_will_make_of_the_budget(folder: Path) -> None:
    done = fogiac(folder, "plan")
    assert done.returncode == 0, done.stderr
    assert ("budget: $5.0000/h (cloud.budget_usd_per_hour): cannot be checked with 1 price(s) unknown; up refuses "
            "unless `fogiac up --accept-unknown-cost`") in done.stdout
