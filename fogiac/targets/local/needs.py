"""What a ``local`` sandbox's nodes need from this machine's Python, checked before they are started.

Why: a sandbox runs its nodes with fogiac's own interpreter (no per-host virtual environment, as a
cloud host gets), so a workload node whose requirements are not installed here died only after
``up`` had started everything, with the node's ``ModuleNotFoundError`` in its log, while ``doctor``
had said ``ok``. ``doctor --target local`` and ``up --target local`` ask the same question here: each
workload node's requirements (its recipe's list, what a cloud host's environment is built from)
installed for this interpreter, and its node module importable (rospy and the message packages), and
when not, the exact command that installs what is missing.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path

from fogiac.plan.model import Plan
from fogiac.provision import workload
from fogiac.targets.base import Check

_NAME = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)")
SYSTEM_PACKAGES = Path("/usr/lib/python3/dist-packages")  # Debian's: ros-core's rospy lives here


def unmet(requirement: str) -> bool:
    """Whether ``requirement`` (a PEP 508 line of a recipe) is not installed for this interpreter, or
    installed at a version it excludes (when ``packaging`` is here to read the specifier)."""
    match = _NAME.match(requirement)
    if match is None:
        return True
    try:
        version = importlib.metadata.version(match.group(1))
    except importlib.metadata.PackageNotFoundError:
        return True
    try:
        from packaging.requirements import Requirement  # noqa: PLC0415 - optional: names alone without it
    except ImportError:
        return False
    return not Requirement(requirement).specifier.contains(version, prereleases=True)


def install_line(requirements: list[str]) -> str:
    """The command that installs ``requirements`` into the interpreter the sandboxes run."""
    return shlex.join([sys.executable, "-m", "pip", "install", *requirements])


def _imports(module: str) -> str | None:
    """The last line of what importing ``module`` said in a fresh interpreter (None: it imported)."""
    try:
        done = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True,
                              timeout=120, stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        return f"importing {module} took over 120 s"
    if done.returncode == 0:
        return None
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return lines[-1].strip() if lines else f"exit {done.returncode}"


def workload_problems(plan: Plan, *, import_nodes: bool) -> list[Check]:
    """One check per workload the plan's nodes run: its requirements installed here (and, with
    ``import_nodes``, its node module imported in a fresh interpreter, which is what the sandbox runs)."""
    checks: list[Check] = []
    names = sorted({n.workload for n in plan.nodes if n.kind == "workload" and n.workload})
    for name in names:
        nodes = ", ".join(n.name for n in plan.nodes if n.workload == name)
        what = f"workload {name} (node {nodes})"
        needs = list(workload.recipe(name).requirements())
        missing = [r for r in needs if unmet(r)]
        if missing:
            checks.append(Check(what, False, f"not installed for {sys.executable}, which runs local sandboxes' nodes: "
                                             f"{', '.join(missing)}; install: {install_line(missing)}"))
            continue
        module = f"{workload.package(name)}.node"
        failed = _imports(module) if import_nodes else None
        if failed is not None:
            checks.append(Check(what, False, f"{module} does not import with {sys.executable}: {failed}"))
            continue
        checks.append(Check(what, True, f"{', '.join(needs)} installed" + (f"; {module} imports" if import_nodes
                                                                              else "")))
    return checks


def rospy_check() -> Check:
    """rospy for the sandboxes' nodes and relay; when a virtual environment hides Debian's, say that."""
    found = importlib.util.find_spec("rospy")
    if found is not None:
        return Check("rospy", True, found.origin or "found")
    in_venv = sys.prefix != sys.base_prefix
    if in_venv and (SYSTEM_PACKAGES / "rospy").is_dir():
        return Check("rospy", False, f"installed in {SYSTEM_PACKAGES}, which this virtual environment ({sys.prefix}) "
                                     "does not see: it was made without --system-site-packages (recreate it with "
                                     f"`python3 -m venv --system-site-packages`, or set include-system-site-packages "
                                     f"= true in {Path(sys.prefix) / 'pyvenv.cfg'})")
    hint = "install python3-rospy" + (" and make the virtual environment with --system-site-packages" if in_venv
                                      else "")
    return Check("rospy", False, f"not importable ({hint})")
