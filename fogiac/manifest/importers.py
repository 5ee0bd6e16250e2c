"""Launch files fogiac imports, one registry: which reader takes a file, by its kind.

::

    fogros    FogROS (ROS 1) roslaunch XML, ``.launch`` / ``.xml``   fogiac.manifest.fogros
    fogros2   FogROS2 Python launch files, ``.py`` (read, never run)  fogiac.manifest.fogros2

Each is an :class:`Importer` published under the ``fogiac.importers`` entry point group (fogiac's own
two below, declared in its ``pyproject.toml``), so another installed package adds a launch format by
declaring one more. Every verb that takes a manifest also takes one of these (:func:`load_any`), and
``fogiac import`` writes the manifest it converts to (:func:`import_file`). An :class:`Importer` is a
description: its reader is imported when first used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from fogiac.errors import ManifestError
from fogiac.manifest.schema import Manifest, load_manifest
from fogiac.registry import Registry


class Converted(NamedTuple):
    """What a reader makes of a launch file: the manifest, its YAML text, and what it inferred."""

    manifest: Manifest
    text: str
    notes: tuple[str, ...]  # one line each, printed by `fogiac import` as "inferred ..."


Convert = Callable[..., Converted]  # (path, *, out=None) -> Converted


@dataclass(frozen=True)
class Importer:
    """What an importer publishes: the kind (its entry point's name), the file names it takes, and its reader."""

    kind: str
    suffixes: tuple[str, ...]
    target: str  # "module:function" of the reader's Convert
    describes: str

    def convert(self, path: Path, *, out: Path | None = None) -> Converted:
        module, attr = self.target.split(":")
        function: Convert = getattr(importlib.import_module(module), attr)
        return function(path, out=out)


FOGROS = Importer("fogros", (".launch", ".xml"), "fogiac.manifest.fogros:import_launch", "FogROS roslaunch XML")
FOGROS2 = Importer("fogros2", (".py",), "fogiac.manifest.fogros2:import_launch", "FogROS2 Python launch file")

IMPORTERS: Registry[Importer] = Registry("fogiac.importers", what="importer",
                                         error=lambda line: ManifestError([line]))


def importers() -> tuple[Importer, ...]:
    """Every installed importer, by kind."""
    return tuple(IMPORTERS.get(kind) for kind in IMPORTERS.names())


def for_path(path: Path) -> Importer | None:
    """The importer for ``path``'s kind, or None for anything else (a fogiac manifest)."""
    return next((i for i in importers() if path.name.endswith(i.suffixes)), None)


def import_file(path: Path, *, out: Path | None = None) -> Converted:
    """Convert and validate a launch file of any known kind; nothing is written here."""
    importer = for_path(path)
    if importer is None:
        kinds = "; ".join(f"{i.describes} ({', '.join(i.suffixes)})" for i in importers())
        raise ManifestError([f"{path}: not a launch file fogiac imports; it reads: {kinds}"])
    return importer.convert(path, out=out)


def load_any(path: str | Path) -> Manifest:
    """A fogiac manifest, or a launch file converted on the fly (``fogiac up robot.launch.py``)."""
    path = Path(path)
    importer = for_path(path)
    return importer.convert(path)[0] if importer else load_manifest(path)
