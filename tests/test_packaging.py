"""`pip install .` ships stacks, templates and workloads: fogiac works from another directory."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import EXAMPLES, REPO


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    wheels = tmp_path_factory.mktemp("wheels")
    target = tmp_path_factory.mktemp("site")
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(pip + ["wheel", "--no-deps", "--no-build-isolation", "-w", str(wheels), str(REPO)],
                   check=True, capture_output=True)
    (wheel,) = wheels.glob("fogiac-*.whl")
    subprocess.run(pip + ["install", "--no-deps", "--target", str(target), str(wheel)], check=True, capture_output=True)
    return target


def run(installed: Path, cwd: Path, code: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(installed)}
    result = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_installed_package_finds_its_files_outside_the_checkout(installed: Path, tmp_path: Path) -> None:
    out = run(installed, tmp_path, (
        "import json, fogiac, stacks, workloads\n"
        "from fogiac.resources import templates_dir, stacks_dir, workloads_dir\n"
        "print(json.dumps([fogiac.__file__, str(templates_dir()), str(stacks_dir()), str(workloads_dir())]))"
    ))
    paths = json.loads(out)
    for path in paths:
        assert path.startswith(str(installed)), path
    assert (installed / "stacks" / "aws" / "Pulumi.yaml").is_file()
    assert (installed / "templates" / "vpn" / "client.ovpn.j2").is_file()
    assert any((installed / "workloads").rglob("*.cfg")), "motion-planning problems are not shipped"


def test_installed_cli_validates_a_copied_manifest(installed: Path, tmp_path: Path) -> None:
    shutil.copy(EXAMPLES / "motion-planning.yaml", tmp_path / "fogiac.yaml")
    out = run(installed, tmp_path, (
        "import sys; from fogiac.cli import main; sys.argv = ['fogiac', 'validate']\n"
        "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
    ))
    assert out.strip() == "fogiac.yaml: valid (1 node, 1 host, target aws)"


def test_ssh_libraries_include_the_terrapin_fix() -> None:
    """fabric alone accepts Debian's paramiko 2.12 (no strict key exchange, CVE-2023-48795)."""
    import inspect
    import tomllib

    import cryptography
    import paramiko

    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())["project"]
    assert any(r.startswith("paramiko>=3.4.0") for r in project["optional-dependencies"]["ssh"])
    assert "cryptography>=42.0.4" in project["dependencies"]
    assert tuple(map(int, paramiko.__version__.split(".")[:2])) >= (3, 4)
    assert tuple(map(int, cryptography.__version__.split(".")[:3])) >= (42, 0, 4)
    strict = inspect.signature(paramiko.Transport.__init__).parameters.get("strict_kex")
    assert strict is not None and strict.default is True
