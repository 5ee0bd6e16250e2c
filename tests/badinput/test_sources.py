"""What a manifest or launch file path may name (issue 26 item 21): caps before reading.

``fogiac validate PATH`` runs in a fresh folder under the same memory and time limits as the
manifest cases: ``/dev/zero`` was read whole before the 1 MiB cap, a FIFO hung, bytes that are not
UTF-8 and deeply nested Python in a launch file gave tracebacks, a 2-million-line launch file took
all the time there was. Each is one line naming the file, and exit 1.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.badinput.test_manifests import TIME_LIMIT, _limit_memory

HEAD = "def generate_launch_description():\n    x = "
FILES: dict[str, tuple[str, bytes, str]] = {  # name: (file, bytes, what the line says)
    "xml-not-utf8": ("robot.launch", b"<launch>\n<node pkg='fogros' \xff/>\n</launch>\n", r"robot.launch:2: not UTF-8"),
    "py-not-utf8": ("robot.launch.py", b"# \xfe\xff\n", r"robot.launch.py:1: not UTF-8"),
    "yaml-not-utf8": ("fogiac.yaml", b"name: x\nnodes: []\n# \xff\n", r"fogiac.yaml:3: not UTF-8"),
    "py-minus-chain": ("robot.launch.py", (HEAD + "-" * 200_000 + "1\n").encode(), r"robot.launch.py:2: a statement"),
    "py-not-chain": ("robot.launch.py", (HEAD + "not " * 4_990 + "1\n").encode(), r"robot.launch.py:1: nested too"),
    "py-sum-chain": ("robot.launch.py", (HEAD + "+".join(["1"] * 2_490) + "\n").encode(), r"nested too deeply"),
    "py-attribute-chain": ("robot.launch.py", (HEAD + "a" + ".a" * 2_490 + "\n").encode(), r"nested too deeply"),
    "py-brackets": ("robot.launch.py", (HEAD + "[" * 190 + "]" * 190 + "\n").encode(), r":2: nested deeper than"),
    "py-2M-lines": ("robot.launch.py", b"\n" * 2_000_000 + HEAD.encode() + b"1\n", r"larger than the limit"),
    "xml-2M-lines": ("robot.launch", b"<launch>" + b"\n" * 2_000_000 + b"</launch>\n", r"larger than the limit"),
    "yaml-60k-lines": ("fogiac.yaml", b"name: x\n" + b"#\n" * 60_000, r"60002 lines; the limit is 50000"),
}


def _validate(path: str, cwd: Path) -> tuple[int, str]:
    env = dict(os.environ, FOGIAC_STATE_DIR=str(cwd / "state"))
    result = subprocess.run([sys.executable, "-m", "fogiac", "validate", path], cwd=cwd, env=env,
                            capture_output=True, text=True, timeout=TIME_LIMIT, preexec_fn=_limit_memory)
    return result.returncode, (result.stdout + result.stderr).strip()


def _one_line(code: int, output: str, expect: str) -> None:
    import re

    assert code == 1, output[-2000:]
    assert "Traceback" not in output and len(output.splitlines()) == 1, output[-2000:]
    assert re.search(expect, output), output


@pytest.mark.parametrize("case", FILES, ids=list(FILES))
def test_a_hostile_file_is_one_line(case: str, tmp_path: Path) -> None:
    name, body, expect = FILES[case]
    (tmp_path / name).write_bytes(body)
    _one_line(*_validate(name, tmp_path), expect)
    assert not (tmp_path / "state").exists()


def test_dev_zero_is_refused_before_a_byte_is_read(tmp_path: Path) -> None:
    _one_line(*_validate("/dev/zero", tmp_path), r"^/dev/zero: is a device")


def test_a_fifo_is_refused_not_waited_on(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fogiac.yaml")
    _one_line(*_validate("fogiac.yaml", tmp_path), r"^fogiac.yaml: is a FIFO")
    os.mkfifo(tmp_path / "robot.launch.py")
    _one_line(*_validate("robot.launch.py", tmp_path), r"^robot.launch.py: is a FIFO")
