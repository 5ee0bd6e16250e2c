"""Issue 35, "costs that are unknown say so": a region the catalogue cannot price (sa-east-1) shows
"unknown", totals say "at least ... plus N unknown", JSON carries null and names what is unknown."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fogiac.plan import guard

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    here = tmp_path_factory.mktemp("unpriced")
    text = (ROOT / "examples" / "minimal.yaml").read_text().replace("us-west-2", "sa-east-1")
    (here / "fogiac.yaml").write_text(text)
    return here


def fogiac(folder: Path, *args: str, verb: str = "plan") -> str:
    done = subprocess.run([sys.executable, "-m", "fogiac", verb, *args], cwd=folder, capture_output=True,
                          text=True, timeout=300, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin",
                                                       "COLUMNS": "200", "HOME": str(folder)})
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_plan_table_says_unknown_and_at_least(folder: Path) -> None:
    out = fogiac(folder)
    assert "0.0000" not in out
    assert "unknown" in out
    assert "cost: at least $0.1500 per hour plus 1 unknown" in out


def test_plan_json_carries_null_and_names_the_unknown(folder: Path) -> None:
    doc = json.loads(fogiac(folder, "--json"))
    assert doc["cost"]["unknown"] == ["instance talker (t3.small)"]
    line = doc["cost"]["lines"][0]
    assert line["usd_per_hour"] is None and line["total"] is None and line["price_unknown"] is True
    assert doc["hosts"][0]["usd_per_hour"] is None and doc["hosts"][0]["price_unknown"] is True


def test_pr_comment_says_cost_unknown(folder: Path) -> None:
    out = fogiac(folder, "--markdown")
    assert "+ talker (t3.small, cost unknown)" in out
    assert "$0.1500 plus 1 unknown" in out and "$0.0000/h" not in out


def test_status_guard_says_unknown_not_zero() -> None:
    doc = guard.guard([guard.Billed("instance a (t3.small, running)", None, 0.0),
                       guard.Billed("Client VPN subnet association", 0.1, 0.0)],
                      now=3600.0, autostop_s=None, edge_idle_since=None)
    assert doc["unknown"] == ["instance a (t3.small, running)"]
    assert doc["lines"][0]["usd_per_hour"] is None and doc["lines"][0]["cost_usd"] is None
    text = "\n".join(guard.render(doc))
    assert "at least $0.1000/h plus 1 unknown now" in text
    assert "unknown" in text.splitlines()[1] and "$0.0000" not in text


def test_a_free_machine_still_costs_zero_not_unknown() -> None:
    doc = guard.guard([guard.Billed("host sandbox", 0.0, 0.0)], now=3600.0, autostop_s=None, edge_idle_since=None)
    assert doc["unknown"] == [] and "$0.0000/h now" in guard.render(doc)[0]


def test_ls_gives_no_bound_when_a_price_is_unknown() -> None:
    from fogiac.cli.stacks import _so_far
    assert _so_far({"cost": {"hourly_usd": 0.15, "unknown": ["instance talker (t3.small)"]}}, 2.0) == \
        "unknown ($0.1500/h plus 1 unknown)"
    assert _so_far({"cost": {"hourly_usd": 0.15, "unknown": []}}, 2.0).startswith("at most $0.30")


def test_cost_table_says_unknown_and_at_least(folder: Path) -> None:
    out = fogiac(folder, verb="cost")
    assert "0.0000" not in out and "0.00 " not in out
    row = next(line for line in out.splitlines() if "instance talker (t3.small)" in line)
    assert row.count("unknown") == 3  # the hour, the day and the month
    assert "0.1500 + 1 unknown" in out  # the total leaves it out, and says so
    assert "cost: at least $0.1500 per hour plus 1 unknown" in out
    assert "unknown: instance talker (t3.small)" in out


def test_diagram_and_state_ls_say_at_least(folder: Path, tmp_path: Path) -> None:
    from fogiac.cli.state import rows
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan
    from fogiac.plan.diagram import layout
    from fogiac.state import FORMAT_VERSION
    from fogiac.store import FolderStore

    plan = compile_plan(load_manifest(folder / "fogiac.yaml"))
    drawing = layout(plan)
    assert drawing.caption.endswith("at least $0.15/h plus 1 unknown")
    assert any("t3.small: 2 vCPU, cost unknown" in box.lines for box in drawing.boxes)
    store = FolderStore(tmp_path)
    store.put("talker-dev", {"format_version": FORMAT_VERSION,
                             "deployment": {"target": "aws", "state": "complete", "since_epoch": 0.0},
                             "applied": {"cost": {"hourly_usd": 0.15, "unknown": ["instance talker (t3.small)"]}}},
              expected=None)
    assert rows(store, now=7200.0)[0]["cost so far"] == "unknown ($0.1500/h plus 1 unknown)"  # never "at most"


def test_spot_fallback_line_says_unknown(folder: Path) -> None:
    import dataclasses

    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan
    from fogiac.targets.aws.spot import fallback_line

    plan = compile_plan(load_manifest(folder / "fogiac.yaml"))
    plan = dataclasses.replace(plan, hosts=tuple(dataclasses.replace(h, spot=True) for h in plan.hosts))
    line = fallback_line(plan, plan.hosts[0].name, "InsufficientInstanceCapacity")
    assert line.endswith("running on-demand instead at an unknown price (the catalogue has none there)")
