"""Where each block of command output in the docs comes from (issue 35, item 25: every command output the
docs show is produced by a test), shared by ``test_docs_outputs.py`` and ``regenerate.py``.

A page says where a block comes from in an HTML comment on the line just before its fence:

- ``<!-- output (CASE): COMMAND -->``: copy ``tests/docs/cases/CASE/`` into an empty folder, run its
  ``setup.sh`` there if it has one, then run COMMAND there; the block is what COMMAND printed (stdout and
  stderr in the order a terminal shows them), with the folder shown as ``DISPLAY_DIR``. Offline commands
  only (validate, plan, import, an ``up`` refused before it starts): the docs test runs each.
- ``<!-- output checked by TEST: COMMAND -->``: COMMAND needs what a slower test brings up (a deployed
  stack, LocalStack); TEST (``tests/...py``, optionally ``::name``) reads this page and compares the
  block with what the command printed there.
- ``<!-- output measured: COMMAND -->``: a measurement, kept as printed on the machine and day the page
  names; its shape is checked against the code that prints it today (numbers are the run's).
- ``<!-- not output: WHY -->``: a block that looks like output and is not (a drawing, a folder listing).

A block that looks like output (``looks_like_output``) and carries none of these fails the docs test, so
output pasted into a page later cannot drift unnoticed.
"""

from __future__ import annotations

import getpass
import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CASES = Path(__file__).resolve().parent / "cases"
PAGES = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]

# What a case's run prints that is this machine's, shown as a reader's: the case's folder and who ran it.
DISPLAY_DIR = "/home/alice/lab"
DISPLAY_WHO = "alice@lab-3"
# What differs from run to run, masked on both sides before comparing (and nothing else).
MASKS = [
    (re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(?:\.\d+)?(?:Z|[+-]\d\d:\d\d)"), "<time>"),  # a moment
    (re.compile(r"\bpid \d+"), "pid <pid>"),  # a process
]
# The terminal width the commands see: a table's width, and so the page's, does not follow the test's.
COLUMNS = "100"

# Blocks a generator writes and another test keeps in sync with the code: the CLI reference's usage lines.
GENERATED = [("<!-- cli-reference:begin", "<!-- cli-reference:end -->")]

_FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.M | re.S)
_MARKER = re.compile(
    r"<!-- (?:output \((?P<case>[\w-]+)\): (?P<command>.+?)"
    r"|output checked by (?P<test>tests/\S+?\.py(?:::\w+)?): (?P<checked>.+?)"
    r"|output measured: (?P<measured>.+?)"
    r"|not output: (?P<why>.+?)) -->$")
_OUTPUT_LANGS = {"", "text", "txt", "console", "output", "plain", "shell-session"}
_SHELL_LANGS = {"sh", "bash", "shell", "zsh"}


@dataclass(frozen=True)
class Block:
    """One fenced block of a page, with the marker line before it (if any)."""

    page: Path
    line: int  # of the opening fence, 1-based
    lang: str
    body: str  # the text between the fences, ending with a newline (or empty)
    marker: str  # the line just before the fence
    start: int  # offsets of the body in the page's text
    end: int

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"

    @property
    def kind(self) -> str | None:
        """``case``, ``checked``, ``measured``, ``not-output``, or None (no marker)."""
        found = _MARKER.fullmatch(self.marker.strip())
        if not found:
            return None
        return ("case" if found["case"] else "checked" if found["test"] else "measured" if found["measured"]
                else "not-output")

    def field(self, name: str) -> str:
        found = _MARKER.fullmatch(self.marker.strip())
        assert found and found[name] is not None, (self.where, name)
        return str(found[name])


def blocks(page: Path) -> list[Block]:
    text = page.read_text()
    found = []
    for fence in _FENCE.finditer(text):
        before = text[:fence.start()].rstrip("\n").rsplit("\n", 1)[-1]
        found.append(Block(page, text.count("\n", 0, fence.start()) + 1, fence[1].strip(), fence[2], before,
                           fence.start(2), fence.end(2)))
    return found


def generated(block: Block) -> bool:
    """The block lies in a region a generator writes (and another test checks)."""
    text = block.page.read_text()
    for begin, end in GENERATED:
        for region in re.finditer(re.escape(begin) + r".*?" + re.escape(end), text, re.S):
            if region.start() <= block.start < region.end():
                return True
    return False


def looks_like_output(block: Block) -> bool:
    """What a reader takes for something a command printed: a plain-text block (``text``, ``console``, no
    language), a shell block holding a ``$ `` prompt line, or a shell block with a whole line of comment (the
    place output gets pasted under the command; a command's note goes at the end of its own line)."""
    if block.lang in _OUTPUT_LANGS:
        return True
    lines = block.body.splitlines()
    if block.lang in _SHELL_LANGS:
        return any(line.startswith("$ ") for line in lines) or any(
            line.lstrip().startswith("#") and not line.startswith("#!") for line in lines)
    return False


def normalise(text: str) -> str:
    for pattern, mask in MASKS:
        text = pattern.sub(mask, text)
    return text


def _who() -> str:
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = str(os.getuid())
    return f"{user}@{socket.gethostname()}"


def displayed(text: str, folder: Path) -> str:
    """What a run printed, as the page shows it: the case's folder and the user@host are the reader's."""
    for path in sorted({str(folder), str(folder.resolve())}, key=len, reverse=True):
        text = text.replace(path, DISPLAY_DIR)
    return text.replace(_who(), DISPLAY_WHO)


def _environment(work: Path) -> dict[str, str]:
    """This checkout's ``fogiac`` and ``python`` first on PATH, a state folder of the run's own, no shared
    store, unbuffered output (so stdout and stderr interleave as on a terminal), a fixed width."""
    bin_dir = work / "bin"
    bin_dir.mkdir()
    for name, argv in (("fogiac", f'{shlex.quote(sys.executable)} -m fogiac "$@"'),
                       ("python", f'{shlex.quote(sys.executable)} "$@"')):
        shim = bin_dir / name
        shim.write_text(f"#!/bin/sh\nexec {argv}\n")
        shim.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if not k.startswith("FOGIAC_")}
    env.update(PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '/usr/bin:/bin')}", REPO=str(REPO),
               PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
               FOGIAC_STATE_DIR=str(work / "state"), PYTHONUNBUFFERED="1", COLUMNS=COLUMNS, NO_COLOR="1",
               TERM="dumb")
    return env


def run_case(case: str, command: str, *, timeout: float = 240) -> str:
    """COMMAND's output in a fresh copy of the case's folder (after its ``setup.sh``), as the page shows it."""
    source = CASES / case
    if not source.is_dir():
        raise FileNotFoundError(f"no case folder {source.relative_to(REPO)}")
    with tempfile.TemporaryDirectory(prefix="docs-case-") as tmp:
        work = Path(tmp)
        env = _environment(work)
        folder = work / "lab"
        shutil.copytree(source, folder, ignore=lambda where, names: ["setup.sh"] if Path(where) == source else [])
        if (source / "setup.sh").exists():
            done = subprocess.run(["bash", "-eu", str(source / "setup.sh")], cwd=folder, env=env,
                                  capture_output=True, text=True, timeout=timeout, check=False)
            if done.returncode != 0:
                raise RuntimeError(f"{source.relative_to(REPO)}/setup.sh failed:\n{done.stdout}{done.stderr}")
        done = subprocess.run(shlex.split(command), cwd=folder, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=timeout, check=False)
        said = displayed(done.stdout, folder)
        return said if said.endswith("\n") or not said else said + "\n"  # a block's last line ends its fence's
