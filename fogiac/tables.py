"""Tables and consoles that survive a pipe: a value is never cut, whatever the width.

On a terminal rich fits tables to its width and folds long cells; into a pipe or a file
(CI logs, ``fogiac status | grep``) there is no width to fit, so lines are as long as the
values they hold: an instance id or an address prints whole.
"""

from __future__ import annotations

import sys
from typing import TextIO

from rich.console import Console
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
