"""Make a test-only plug-in an installed distribution: a ``*.dist-info`` with its entry points on
``sys.path``, as ``pip install`` of a package declaring them would leave, then rescan the registry."""

from __future__ import annotations

import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from fogiac import registry


@contextmanager
def installed(where: Path, name: str, entry_points: Mapping[str, Mapping[str, str]]) -> Iterator[None]:
    """``entry_points``: group -> {name: "module:attr"}; uninstalled (off sys.path, rescanned) afterwards."""
    info = where / f"{name}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{key} = {value}\n" for key, value in points.items()) + "\n"
        for group, points in entry_points.items()))
    sys.path.insert(0, str(where))
    registry.rescan()
    try:
        yield
    finally:
        sys.path.remove(str(where))
        registry.rescan()
