"""Stack names never collide (issue 26 item 11), and stacks named the old way keep their names.

``name: robot-prod`` with ``--env dev`` and ``name: robot`` with ``--env prod-dev`` were both
``robot-prod-dev``: one stack folder, one tag, one sweep. An environment with a '-' is now joined
with ``--``, which neither a name nor an environment may hold.
"""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from fogiac import deployment
from fogiac.cli import app

runner = CliRunner()
MANIFEST = "name: {name}\ncloud: {{provider: local}}\nnodes:\n  - {{name: a, machine: t3.small, command: [sleep, '1']}}\n"


def _stack(path: Path, env: str) -> tuple[int, str]:
    result = runner.invoke(app, ["plan", str(path), "--json", "--env", env])
    return result.exit_code, json.loads(result.output)["stack"] if result.exit_code == 0 else result.output


def _manifest(tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(MANIFEST.format(name=name))
    return path


def test_names_and_environments_with_dashes_do_not_collide(tmp_path: Path, _state_dir: Path) -> None:
    one = _stack(_manifest(tmp_path, "robot-prod"), "dev")
    other = _stack(_manifest(tmp_path, "robot"), "prod-dev")
    assert one == (0, "robot-prod-dev") and other == (0, "robot--prod-dev")  # 'dev' keeps the name it had


def test_an_environment_with_a_double_dash_is_refused(tmp_path: Path, _state_dir: Path) -> None:
    code, out = _stack(_manifest(tmp_path, "robot"), "prod--dev")
    assert code == 1 and out.strip() == ("error: --env 'prod--dev' holds '--', which fogiac keeps for joining the "
                                         "name and the environment")


def test_a_stack_deployed_under_the_old_name_keeps_it(tmp_path: Path, _state_dir: Path) -> None:
    path = _manifest(tmp_path, "robot")
    folder = _state_dir / "robot-prod-dev"  # what an older fogiac made of robot + prod-dev
    folder.mkdir()
    (folder / "stack.json").write_text(json.dumps({
        "stack": "robot-prod-dev", "target": "local", "manifest": deployment.manifest_id(path), "state": "complete",
        "since": "2026-01-01T00:00:00Z", "since_epoch": 1.0, "plan_digest": ""}))
    assert _stack(path, "prod-dev") == (0, "robot-prod-dev")
    result = runner.invoke(app, ["plan", str(path), "--env", "prod-dev", "--detailed-exitcode"])
    assert result.exit_code == 2 and "robot-prod-dev" in result.output  # compared with the old stack
    # another manifest of that old name is not taken for it: it gets the new, distinct name
    (tmp_path / "elsewhere").mkdir()
    assert _stack(_manifest(tmp_path / "elsewhere", "robot"), "prod-dev") == (0, "robot--prod-dev")
