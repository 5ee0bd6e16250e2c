"""Another version of a manifest, for ``fogiac plan --against``: a file, or ``git:REF:PATH``.

``git:REF:PATH`` is read with ``git show REF:PATH`` in the repository around the current folder
(PATH from the repository's top, as git names it), so the pull request's base branch needs no
checkout and no network: the CI example fetches it once. Relative paths inside that manifest
(launch workspaces, SSH keys) are taken from PATH's folder in the working tree.
"""

from __future__ import annotations

import hashlib
import subprocess
from dataclasses import dataclass
from pathlib import Path

from fogiac.errors import ManifestError
from fogiac.manifest.importers import load_any
from fogiac.manifest.schema import Manifest, parse_manifest

GIT_PREFIX = "git:"


@dataclass(frozen=True)
class Revision:
    manifest: Manifest
    label: str  # what the user passed, for messages and the JSON document
    sha256: str  # of the manifest's bytes


def _git(args: list[str], *, cwd: Path, what: str) -> bytes:
    try:
        done = subprocess.run(["git", *args], cwd=cwd, capture_output=True, check=False)
    except FileNotFoundError:
        raise ManifestError([f"{what}: git is not installed"]) from None
    if done.returncode != 0:
        reason = done.stderr.decode(errors="replace").strip().splitlines()
        raise ManifestError([f"{what}: {reason[-1] if reason else 'git failed'}"])
    return done.stdout


def load_revision(spec: str, *, cwd: Path | None = None) -> Revision:
    """The manifest ``spec`` names; ManifestError (one line) when it cannot be read or is invalid."""
    cwd = cwd or Path.cwd()
    if not spec.startswith(GIT_PREFIX):
        path = Path(spec)
        if not path.is_file():
            raise ManifestError([f"{spec}: no such file (--against takes a path or git:REF:PATH)"])
        return Revision(load_any(path), spec, hashlib.sha256(path.read_bytes()).hexdigest())
    ref, sep, name = spec[len(GIT_PREFIX):].partition(":")
    if not sep or not ref or not name:
        raise ManifestError([f"{spec}: expected git:REF:PATH, e.g. git:origin/main:fogiac.yaml"])
    top = Path(_git(["rev-parse", "--show-toplevel"], cwd=cwd, what=spec).decode().strip())
    data = _git(["show", f"{ref}:{name}"], cwd=top, what=spec)
    try:
        text = data.decode()
    except UnicodeDecodeError:
        raise ManifestError([f"{spec}: not UTF-8 text"]) from None
    manifest = parse_manifest(text, source=spec, base=(top / name).parent)
    return Revision(manifest, spec, hashlib.sha256(data).hexdigest())
