"""What ``up`` pushes to the hosts, fingerprinted for the plan document: each workspace, env script,
requirements file and build context a node names, with the digest of its content, so a change to what
is pushed shows in ``plan``'s diff like any other change (:mod:`fogiac.provision.sync` pushes by the
same hashes: what is ignored here is not pushed there).

Symbolic links are never followed: a link counts as its target text, as it is pushed.
"""

from __future__ import annotations

import fnmatch
import hashlib
import os
from pathlib import Path
from typing import Any

from fogiac.plan.model import Plan

DEFAULT_IGNORE = (".git/", ".hg/", ".svn/", "build/", "devel/", "install/", "log/", "logs/",
                  "__pycache__/", "*.pyc", ".pytest_cache/", ".mypy_cache/", "*.swp", ".DS_Store",
                  ".fogiacignore", ".catkin_tools/", ".venv/")


def ignore_patterns(root: Path, extra: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The defaults, then ``.fogiacignore`` lines (gitignore-like: ``dir/``, globs, ``#`` comments)."""
    patterns = list(DEFAULT_IGNORE) + list(extra)
    ignore_file = root / ".fogiacignore"
    if ignore_file.is_file():
        for line in ignore_file.read_text().splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                patterns.append(line.lstrip("/"))
    return tuple(patterns)


def _ignored(rel: str, is_dir: bool, patterns: tuple[str, ...]) -> bool:
    name = rel.rsplit("/", 1)[-1]
    for pattern in patterns:
        if pattern.endswith("/"):
            if not is_dir:
                continue
            pattern = pattern[:-1]
        target = rel if "/" in pattern else name
        if fnmatch.fnmatchcase(target, pattern):
            return True
    return False


def scan(root: Path, patterns: tuple[str, ...]) -> dict[str, str]:
    """``{relative path: sha256}`` of every file and link under ``root`` not ignored; a link's hash is
    of its target text, and nothing behind a link is read."""
    out: dict[str, str] = {}
    todo = [root]
    while todo:
        folder = todo.pop()
        for entry in sorted(folder.iterdir()):
            rel = entry.relative_to(root).as_posix()
            if entry.is_symlink():
                if not _ignored(rel, False, patterns):
                    out[rel] = hashlib.sha256(b"symlink\0" + os.fsencode(os.readlink(entry))).hexdigest()
            elif entry.is_dir():
                if not _ignored(rel, True, patterns):
                    todo.append(entry)
            elif entry.is_file() and not _ignored(rel, False, patterns):
                out[rel] = hashlib.sha256(entry.read_bytes()).hexdigest()
    return out


def sums_text(hashes: dict[str, str]) -> str:
    return "".join(f"{digest}  {path}\n" for path, digest in sorted(hashes.items()))


def digest_of(hashes: dict[str, str]) -> str:
    return hashlib.sha256(sums_text(hashes).encode()).hexdigest()



def fingerprint(path: str) -> str:
    """The digest of a pushed file or folder's content ("missing" when it is not there now)."""
    where = Path(path)
    try:
        if where.is_dir():
            return digest_of(scan(where, ignore_patterns(where)))
        if where.is_file():
            return hashlib.sha256(where.read_bytes()).hexdigest()
    except OSError as err:
        return f"unreadable ({err.strerror or err})"
    return "missing"


def pushed(plan: Plan) -> list[dict[str, Any]]:
    """Every path a node has pushed to its host, with the digest of its content, in node order."""
    rows: list[dict[str, Any]] = []
    for node in plan.nodes:
        paths: list[tuple[str, str | None]] = []
        if node.launch is not None:
            paths += [("workspace", node.launch.workspace), ("env_script", node.launch.env_script),
                      ("requirements", node.launch.requirements)]
        if node.build is not None:
            paths.append(("build", node.build.context))
        rows += [{"node": node.name, "what": what, "path": path, "sha256": fingerprint(path)}
                 for what, path in paths if path is not None]
    return rows
