"""Issue 35 item 11: ``ls`` and ``status`` print what a stack's record holds, and a record is a file anyone
with the state folder can edit: its text reaches the terminal as inert text (an ESC sequence or a
newline shown as ``\\xNN``, rich markup as itself) and a cost that is not an amount (``NaN``, a string,
negative) as "unknown", never ``$nan`` or a traceback."""

from __future__ import annotations

import time
from pathlib import Path

from typer.testing import CliRunner

from fogiac import deployment, targets
from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import plan_document
from fogiac.state import StackState
from fogiac.targets.existing import ExistingMachines
from fogiac.tables import console
from tests.conftest import EXAMPLES

HOSTILE = "\x1b]52;c;cm0gLXJmIH4=\x07\x1b[2J[bold red]owned[/]\nsecond line"


def _hostile_stack(manifest: Path, hourly: object) -> str:
    plan = compile_plan(load_manifest(manifest), environment="dev")
    record = deployment.finish(plan, manifest, plan_digest="x")
    StackState(plan.stack).set(StackState.DEPLOYMENT, {**record.__dict__, "since_epoch": time.time() - 3600,
                                                       "target": HOSTILE, "since": HOSTILE})
    applied = plan_document(plan, targets.get(plan.target).declare(plan), manifest=manifest)
    applied["cost"]["hourly_usd"] = hourly
    StackState(plan.stack).set(StackState.APPLIED, applied)
    return plan.stack


def test_ls_prints_a_hostile_record_as_inert_text(tmp_path: Path, _state_dir: Path) -> None:
    manifest = tmp_path / "minimal.yaml"
    manifest.write_text((EXAMPLES / "minimal.yaml").read_text())
    for hourly, name in ((float("nan"), "minimal"), ("lots", "second"), (-3.0, "third")):
        manifest.write_text((EXAMPLES / "minimal.yaml").read_text().replace("name: minimal", f"name: {name}"))
        _hostile_stack(manifest, hourly)
    result = CliRunner().invoke(app, ["ls"], env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    assert "\x1b" not in result.output and "\x07" not in result.output and "$nan" not in result.output
    assert "owned" in result.output and "[bold red]owned[/]" in result.output  # markup shown, not applied
    rows = [[c.strip() for c in line.split("│")[1:-1]] for line in result.output.splitlines()
            if line.startswith("│") and "stack" not in line]
    assert len(rows) == 3, result.output  # one line per stack: the newline did not start another row
    for cells in rows:
        assert cells[2] == "\\x1b]52;c;cm0gLXJmIH4=\\x07\\x1b[2J[bold red]owned[/]\\x0asecond line", cells
        assert cells[5] == "unknown", cells


def test_status_rows_of_hosts_print_a_hostile_record_as_inert_text() -> None:
    doc = {"stack": "s-dev", "target": "existing", "edge_master": HOSTILE,
           "hosts": [{"host": HOSTILE, "machine": "m", "address": "10.0.0.1\x1b[31m", "uptime_s": 60,
                      "cost_usd": float("nan"), "autostop": None,
                      "nodes": [{"node": "n\x1b[1A", "running": True, "restarts": "\x1b[2K9"}]}]}
    screen = console()
    with screen.capture() as captured:
        screen.print(*ExistingMachines().render_status(doc), sep="\n")
    out = captured.get()
    assert "\x1b" not in out and "$nan" not in out, out
    assert "\\x1b[2K9" in out and "10.0.0.1\\x1b[31m" in out and "unknown" in out
