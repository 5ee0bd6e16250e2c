"""Where fogiac's shipped files live, in a checkout and after ``pip install``.

``stacks``, ``templates`` and ``workloads`` are top-level packages installed beside ``fogiac``,
so one lookup through the import system works in both cases.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path


def package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(f"fogiac is installed without its {name!r} package; reinstall it")
    return Path(next(iter(spec.submodule_search_locations)))


def templates_dir() -> Path:
    return package_dir("templates")


def stacks_dir() -> Path:
    return package_dir("stacks")


def workloads_dir() -> Path:
    return package_dir("workloads")
