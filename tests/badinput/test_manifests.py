"""Hostile manifests: each file in ``manifests/`` is a case a reviewer can add without code.

A case's first line is ``# expect: REGEX``, what the one-line problem must say. Its text is the
manifest, unless a ``# body: EXPR`` line builds it (for inputs too big, too deep or too binary to
check in; EXPR is a Python expression with ``range`` and nothing else). ``fogiac validate`` runs
in a fresh folder under a memory limit and a time limit, and must exit 1 with lines of the form
``fogiac.yaml:LINE: ...`` (or ``fogiac.yaml: ...``), no traceback, nothing created, nothing changed.
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest

CASES = sorted(Path(__file__).with_name("manifests").glob("*.yaml"))
MEMORY_LIMIT = 1 << 30  # address space: fogiac validate needs ~300 MB; an alias bomb needs gigabytes
TIME_LIMIT = 30  # seconds, for a command that takes about one


def _header(text: str, key: str) -> str | None:
    match = re.search(rf"^# {key}: (.*)$", text, re.M)
    return match.group(1) if match else None


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() if p.is_file() else b"" for p in sorted(root.rglob("*"))}


@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_validate_names_the_problem_in_one_line(case: Path, tmp_path: Path) -> None:
    text = case.read_text()
    expect = _header(text, "expect")
    assert expect, f"{case.name}: first line must be '# expect: REGEX'"
    body_expr = _header(text, "body")
    body = eval(body_expr, {"__builtins__": {}, "range": range}) if body_expr else text  # noqa: S307 (our own cases)
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_bytes(body if isinstance(body, bytes) else body.encode())
    before = _files(tmp_path)
    env = dict(os.environ, FOGIAC_STATE_DIR=str(tmp_path / "state"))
    result = subprocess.run([sys.executable, "-m", "fogiac", "validate", "fogiac.yaml"], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=TIME_LIMIT, preexec_fn=_limit_memory)
    output = (result.stdout + result.stderr).strip()
    assert result.returncode == 1, output[-2000:]
    assert "Traceback" not in output and "MemoryError" not in output
    assert not re.search(r" object at 0x[0-9a-f]+", output), output  # never an internal object's repr
    lines = output.splitlines()
    assert lines and all(line.startswith("fogiac.yaml:") for line in lines), output[-2000:]
    assert any(re.search(expect, line) for line in lines), f"no line matches {expect!r}:\n{output[-2000:]}"
    assert _files(tmp_path) == before  # nothing created, nothing changed, no state folder
