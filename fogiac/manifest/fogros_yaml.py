"""What of a launch file may reach the manifest ``fogiac import`` writes, and how: nothing but quoted
YAML scalars and comments that cannot end their line.

A launch file is someone else's text. A node's package holding a newline (a Python string, or ``&#10;``
in XML) once went raw into the header's ``#   - ...`` lines, so the line broke and the rest became new
top-level keys (``network: {ssh_from: ...}`` validated and opened SSH to it), for ``plan``/``up`` run on
the launch file too; an escape character made the text invalid YAML, reported against a file never
written. So both importers write through here:

- every string taken from the launch file (or the files it names) is a :class:`FromLaunch`, which the
  dumper always writes double-quoted, escapes and all, whatever the string holds;
- every header line goes through :func:`comment`, which writes each character that is not printable
  (a line break of any kind YAML or Python knows: ``\\n``, ``\\r``, ``\\x85``, ``\\u2028``, ``\\u2029``,
  ``\\v``, ``\\f``; escapes; controls) as its Python escape, so a comment stays one line;
- :func:`validate` names the launch file and the line of the node a problem comes from, never the
  YAML's own lines (a file that may never be written).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from fogiac.errors import ManifestError
from fogiac.manifest.schema import Manifest, parse_manifest


class FromLaunch(str):
    """A string read from a launch file: written as a double-quoted scalar, never a plain one."""

    __slots__ = ()


class _Dumper(yaml.SafeDumper):
    """safe_dump's dumper, writing :class:`FromLaunch` strings (values and keys) double-quoted."""


_Dumper.add_representer(FromLaunch, lambda dumper, value: dumper.represent_scalar(
    "tag:yaml.org,2002:str", str(value), style='"'))


def comment(text: str) -> str:
    """``text`` with every character that is not printable written as its escape: one line, whatever it held."""
    return "".join(ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii") for ch in text)


def dump(header: Sequence[str], data: dict[str, Any]) -> str:
    """The manifest's text: the header as comment lines, then the data (launch-file strings quoted)."""
    lines = [comment(line if line.startswith("#") else f"# {line}") for line in header]
    body = yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=False, width=4096)
    return "".join(f"{line}\n" for line in lines) + body


_PROBLEM = re.compile(r"^\x00:\d+: ", re.S)  # parse_manifest's "SOURCE:LINE: " under the source below
_NODE = re.compile(r"^nodes\[(\d+)\]")


def validate(text: str, *, launch: Path, base: Path, node_lines: Sequence[int]) -> Manifest:
    """Parse the converted text; a problem names the launch file at the line of the node it is about
    (``robot.launch:9: imported as nodes[1].machine: ...``), or line 1 for the manifest as a whole."""
    try:
        return parse_manifest(text, source="\x00", base=base)
    except ManifestError as err:
        raise ManifestError([_relocate(problem, launch, node_lines) for problem in err.problems]) from None


def _relocate(problem: str, launch: Path, node_lines: Sequence[int]) -> str:
    head = _PROBLEM.match(problem)
    if head is None:
        return problem
    rest = problem[head.end():]
    node = _NODE.match(rest)
    index = int(node.group(1)) if node else -1
    line = node_lines[index] if 0 <= index < len(node_lines) else 1
    return f"{launch}:{line}: imported as {rest}"
