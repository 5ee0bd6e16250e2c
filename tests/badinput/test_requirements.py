"""A launch package's requirements file naming something other than a released package (issue 35 item 9).

With carried wheels (``FOGIAC_CARRY_WHEELS=1``) pip runs on the operator's machine: a PEP 508 direct
reference (``name @ URL``), a URL or a path is built from source there, running its build code. Each is
refused by ``fogiac validate`` in one line naming the file, the line and the reference, before anything
is planned.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.badinput.test_sources import _one_line, _validate

MANIFEST = ("name: rq\nedge: {ros_master: http://localhost:11311}\nnodes:\n  - name: talker\n    machine: t3.small\n"
            "    launch: {package: p, file: t.launch, workspace: ws, requirements: requirements.txt}\n")
LINES = {
    "direct-reference": "evil @ https://example.invalid/evil-1.0.tar.gz",
    "direct-file": "evil@file:///tmp/evil",
    "vcs-url": "git+https://example.invalid/evil.git",
    "bare-url": "https://example.invalid/evil-1.0.tar.gz",
    "relative-path": "./evil",
    "absolute-path": "/tmp/evil",
    "archive-name": "evil-1.0.tar.gz",
    "wheel-name": "evil-1.0-py3-none-any.whl",
    "direct-with-marker": "evil @ https://example.invalid/e.zip ; python_version >= '3'",
}


@pytest.mark.parametrize("case", LINES, ids=list(LINES))
def test_a_reference_pip_would_build_is_refused(case: str, tmp_path: Path) -> None:
    (tmp_path / "ws" / "src").mkdir(parents=True)
    (tmp_path / "requirements.txt").write_text(f"numpy==1.26.4\n{LINES[case]}\n")
    (tmp_path / "fogiac.yaml").write_text(MANIFEST)
    _one_line(*_validate("fogiac.yaml", tmp_path),
              r"^fogiac.yaml:6: nodes\[0\].launch.requirements: requirements.txt:2: '.*': only released packages "
              r"by name \(and version\) are allowed here; a URL, path or `name @ URL` reference would be built "
              r"from source where pip runs$")
    assert not (tmp_path / "state").exists()
