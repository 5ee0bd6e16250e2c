"""Reading a manifest or a launch file: the caps come before the read.

A path may name anything: ``/dev/zero`` (never ends), a FIFO (blocks until a writer comes), a
2-million-line file, bytes that are not UTF-8. :func:`read_source` refuses each in one line before
fogiac holds more than the cap in memory; :func:`screen_python` refuses Python nested deeper than
the parser can build without running out of memory or stack (a launch file is read, never run).
"""

from __future__ import annotations

import io
import os
import stat
import tokenize
from pathlib import Path

from fogiac.errors import ManifestError

MAX_BYTES = 1 << 20  # a manifest of 100 nodes is ~20 KB; a large launch file ~50 KB
MAX_LINES = 50_000
MAX_BRACKETS = 64  # brackets open at once in a Python launch file
MAX_STATEMENT_TOKENS = 5_000  # operators, names and brackets in one statement (strings and commas aside)


def read_source(path: Path, *, source: str | None = None, limit: int = MAX_BYTES) -> str:
    """The text of ``path`` if it is a regular file of at most ``limit`` bytes and ``MAX_LINES`` lines of
    UTF-8; else ManifestError in one line. Nothing past the cap is read."""
    where = source or str(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO opens at once instead of waiting for a writer
    except FileNotFoundError:
        raise ManifestError([f"{where}: no such file"]) from None
    except OSError as err:
        raise ManifestError([f"{where}: cannot read: {err.strerror or err}"]) from None
    with os.fdopen(fd, "rb") as fh:
        mode = os.fstat(fh.fileno()).st_mode
        if not stat.S_ISREG(mode):
            kind = ("a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode)
                    else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
            raise ManifestError([f"{where}: is {kind}; give a manifest or launch file"])
        try:
            data = fh.read(limit + 1)
        except OSError as err:
            raise ManifestError([f"{where}: cannot read: {err.strerror or err}"]) from None
    if len(data) > limit:
        raise ManifestError([f"{where}:1: the file is larger than the limit of {limit} bytes"])
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data[:err.start].count(b"\n") + 1
        raise ManifestError([f"{where}:{line}: not UTF-8 text (byte 0x{data[err.start]:02x})"]) from None
    lines = text.count("\n") + 1
    if lines > MAX_LINES:
        raise ManifestError([f"{where}:1: the file has {lines} lines; the limit is {MAX_LINES}"])
    return text


_QUIET = {tokenize.STRING, tokenize.NL, tokenize.COMMENT, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING}


def screen_python(text: str, *, source: str) -> None:
    """Refuse Python that would make ``ast.parse`` (or a walk of its tree) run out of memory or stack:
    brackets open deeper than MAX_BRACKETS, or a statement of more than MAX_STATEMENT_TOKENS tokens (a
    chain of ``-`` or ``not`` or ``.a`` nests one level each). The tokenizer itself keeps no recursion."""
    depth = count = 0
    try:
        for token in tokenize.generate_tokens(io.StringIO(text).readline):
            if token.type == tokenize.NEWLINE:
                count = 0
                continue
            if token.type in _QUIET or token.string == ",":
                continue
            if token.string in "([{" and token.type == tokenize.OP:
                depth += 1
                if depth > MAX_BRACKETS:
                    raise ManifestError([f"{source}:{token.start[0]}: nested deeper than {MAX_BRACKETS} brackets"])
            elif token.string in ")]}" and token.type == tokenize.OP:
                depth -= 1
            count += 1
            if count > MAX_STATEMENT_TOKENS:
                raise ManifestError([f"{source}:{token.start[0]}: a statement longer than {MAX_STATEMENT_TOKENS} "
                                     "tokens; a launch file needs far fewer"])
    except (tokenize.TokenError, SyntaxError) as err:  # the parser says it better; it runs next
        del err
