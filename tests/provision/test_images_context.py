"""A workload image's build context holds what its recipe copies and nothing more, and the host's pip settings reach a
build as a config file (real files, no engine).

The image's tag is a digest of its context: a context holding all of fogiac made the grasp planner's and
SLAM's images (which take two of its files) rebuild on every change anywhere in fogiac."""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision import images
from tests.conftest import EXAMPLES


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


@pytest.mark.parametrize(("example", "whole"), [("grasp-planning.yaml", False), ("slam.yaml", False),
                                                 ("motion-planning.yaml", True)])
def test_a_workload_context_holds_the_parts_of_fogiac_its_recipe_copies(tmp_path: Path, example: str,
                                                                        whole: bool) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / example))
    (node,) = [n for n in plan.nodes if n.kind == "workload"]
    recipe = images.workload_context(node, flavour="debian", into=tmp_path / "ctx")
    files = _files(recipe.context)
    fogiac = {f for f in files if f.startswith("fogiac/")}
    if whole:
        assert {"fogiac/__init__.py", "fogiac/errors.py", "fogiac/procs.py", "fogiac/cli/__init__.py"} <= fogiac
    else:
        assert fogiac == {"fogiac/__init__.py", "fogiac/errors.py"}, fogiac
    assert "Dockerfile" in files and f"workloads/{node.workload}/__init__.py" in files
    assert not any("__pycache__" in f or "/tests/" in f for f in files)


def test_copy_lines_name_the_parts_taken() -> None:
    assert images.fogiac_copied("FROM x\nCOPY fogiac/__init__.py fogiac/errors.py fogiac/\nCOPY a b\n") == [
        "__init__.py", "errors.py"]
    assert images.fogiac_copied("FROM x\nCOPY fogiac/ fogiac/\n") == [""]
    assert images.fogiac_copied("FROM x\nCOPY workloads/ workloads/\n") == []


def test_the_hosts_pip_settings_become_a_pip_config_file_and_nothing_else() -> None:
    conf = images.pip_config({"PIP_INDEX_URL": "https://u:t@mirror.lab/simple", "PIP_NO_INDEX": "1",
                              "PIP_TRUSTED_HOST": "a.lab b.lab", "PIP_EXTRA_INDEX_URL": "x\n[global]\nproxy = evil",
                              "HOME": "/root"})
    assert conf == "[global]\nindex-url = https://u:t@mirror.lab/simple\nno-index = 1\ntrusted-host = a.lab b.lab\n"
