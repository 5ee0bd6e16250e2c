"""Tables and consoles that survive a pipe: a value is never cut, whatever the width.

On a terminal rich fits tables to its width and folds long cells; into a pipe or a file
(CI logs, ``fogiac status | grep``) there is no width to fit, so lines are as long as the
values they hold: an instance id or an address prints whole.
"""

from __future__ import annotations

import math
import re
import sys
from typing import Any, TextIO

from rich.console import Console
from rich.markup import escape
from rich.table import Table

PIPE_WIDTH = 10_000  # wide enough that no table of fogiac's is ever fitted into it


def console(*, stderr: bool = False) -> Console:
    stream: TextIO = sys.stderr if stderr else sys.stdout
    if stream.isatty():
        return Console(stderr=stderr)
    return Console(stderr=stderr, width=PIPE_WIDTH, soft_wrap=True)


def table(title: str | None, *columns: str) -> Table:
    """A table whose cells fold on a terminal (never an ellipsis) and print whole into a pipe."""
    out = Table(title=title)
    for column in columns:
        out.add_column(column, overflow="fold")
    return out


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def printable(value: Any) -> str:
    """A value read from a file (a stack record, a host's answer) as one inert line for a table cell:
    control characters (ESC starting a terminal sequence, newlines) shown as ``\\xNN``, rich markup
    shown as text. A record is not trusted to be what fogiac wrote."""
    text = _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", str(value))
    return escape(text)


def usd(value: Any, *, digits: int = 2) -> str | None:
    """``$1.23`` for a finite amount at least 0; None for anything else (NaN, infinite, negative, not a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
        return None
    return f"${value:.{digits}f}"
