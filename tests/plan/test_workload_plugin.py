"""A workload another distribution declares (``tests/plugins/tally/``, under ``fogiac.workloads``) passes
``validate`` and compiles like fogiac's own; uninstalled, the same manifest fails in one line. Nothing in
fogiac/ names it."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ManifestError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision import venv, workload
from tests.plugins.install import installed
from tests.plugins.tally import ENTRY_POINTS, MANIFEST

runner = CliRunner()


@pytest.fixture
def manifest(tmp_path: Path) -> Path:
    path = tmp_path / "counting.yaml"
    path.write_text(MANIFEST)
    return path


def test_an_installed_workload_passes_validate_and_compiles(manifest: Path, tmp_path: Path) -> None:
    with installed(tmp_path / "site", "fogiac_tally", ENTRY_POINTS):
        result = runner.invoke(app, ["validate", str(manifest)])
        assert result.exit_code == 0, result.output
        plan = compile_plan(load_manifest(manifest))
        node = plan.node("counter")
        assert (node.kind, node.workload) == ("workload", "tally")
        assert workload.package("tally") == "tests.plugins.tally"  # what `python -m PACKAGE node` runs
        assert venv.requirements(["tally"]) == ("tally-counter==0.1",)


def test_without_it_the_same_manifest_fails_in_one_line(manifest: Path) -> None:
    with pytest.raises(ManifestError) as caught:
        load_manifest(manifest)
    assert len(caught.value.problems) == 1
    assert "nodes[0].workload" in caught.value.problems[0] and "'tally'" in caught.value.problems[0]
    result = runner.invoke(app, ["validate", str(manifest)])
    assert result.exit_code == 1 and "Traceback" not in result.output
