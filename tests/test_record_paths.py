"""One file name per record (issue 32): only :mod:`fogiac.state` and :mod:`fogiac.store` build a path inside
a stack's folder.

Checked over the source with ``ast`` (nothing is imported), in every module of ``fogiac/``, ``stacks/``,
``workloads/`` and ``benchmarks/``. A path inside a stack's folder is built by ``/`` on the folder, so
these are what the check refuses outside the two modules:

- ``/`` whose left side is a stack's folder as code reaches it: ``<anything>.folder``, ``<anything>.ensure()``,
  ``stack_dir(...)``, or a variable named ``state_dir`` (what provisioning is handed);
- ``/`` whose right side is the name of a file the state keeps (``known_hosts``, ``lock.json`` ...);
- any other mention of a record file's name, as a string (``"stack.json"``, ``"provision.json"`` ...),
  since a name written twice is a path built twice; docstrings may name them;
- ``stack_dir`` used at all (the state hands out typed paths instead).

A target's own files are named by the target and placed by :meth:`StackState.target_file`.
"""

from __future__ import annotations

import ast
from pathlib import Path

from fogiac.state import LEGACY_FILES, StackState

REPO = Path(__file__).resolve().parents[1]
OWNERS = {REPO / "fogiac" / "state.py", REPO / "fogiac" / "store.py"}
RECORD_NAMES = {StackState.RECORD, StackState.LOCK, StackState.REFRESHED, StackState.KNOWN_HOSTS,
                *LEGACY_FILES.values()}
FOLDER_CALLS = {"stack_dir", "ensure"}


def _sources() -> list[Path]:
    return sorted(p for top in ("fogiac", "stacks", "workloads", "benchmarks") for p in (REPO / top).rglob("*.py")
                  if p not in OWNERS)


def _docstrings(tree: ast.AST) -> set[int]:
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def _is_folder(node: ast.expr) -> bool:
    if isinstance(node, ast.Attribute):
        return node.attr == "folder"
    if isinstance(node, ast.Name):
        return node.id == "state_dir"
    if isinstance(node, ast.Call):
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
        return name in FOLDER_CALLS
    if isinstance(node, ast.IfExp):
        return _is_folder(node.body) or _is_folder(node.orelse)
    return False


def offenders(path: Path, *, root: Path = REPO) -> list[str]:
    tree = ast.parse(path.read_text())
    docs = _docstrings(tree)
    where = path.relative_to(root)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            right = node.right
            if _is_folder(node.left) or (isinstance(right, ast.Constant) and right.value in RECORD_NAMES):
                out.append(f"{where}:{node.lineno}: {ast.unparse(node)}")
        elif isinstance(node, ast.Constant) and node.value in RECORD_NAMES and id(node) not in docs:
            out.append(f"{where}:{node.lineno}: {node.value!r}")
        elif isinstance(node, ast.Name) and node.id == "stack_dir":
            out.append(f"{where}:{node.lineno}: stack_dir")
        elif isinstance(node, ast.alias) and node.name == "stack_dir":
            out.append(f"{where}:{node.lineno}: import stack_dir")
    return out


def test_only_the_state_builds_a_path_inside_a_stack_folder() -> None:
    found = [line for path in _sources() for line in offenders(path)]
    assert found == []


def test_the_check_sees_each_way_of_building_one(tmp_path: Path) -> None:
    """The check is not vacuous: each way the issue found a path built outside the state is caught."""
    sample = tmp_path / "sample.py"
    sample.write_text(
        '"""A module that may name record.json in its docstring."""\n'
        "from fogiac.state import StackState, stack_dir\n"
        "a = StackState('s').folder / 'outputs.json'\n"
        "b = stack_dir('s') / 'certs'\n"
        "c = state_dir / KNOWN\n"
        "d = base / 'known_hosts'\n"
        "RECORD = 'provision.json'\n"
        "e = (s.ensure() if create else s.folder) / 'pulumi'\n")
    lines = [line.split(": ", 1)[1] for line in offenders(sample, root=tmp_path)]
    assert sorted(lines) == sorted([
        "import stack_dir", "stack_dir", "StackState('s').folder / 'outputs.json'", "stack_dir('s') / 'certs'",
        "state_dir / KNOWN", "base / 'known_hosts'", "'known_hosts'", "'provision.json'",
        "(s.ensure() if create else s.folder) / 'pulumi'"])
