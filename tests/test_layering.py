"""The layering issue 10 asks for, checked over the source with ``ast`` (no import is executed).

- Only ``fogiac/targets/aws/`` (and the Pulumi programs in ``stacks/``) touch boto3, botocore,
  pulumi, pulumi_aws or ``stacks``, whether by ``import`` or through ``fogiac.extras.need``.
- No import cycles between fogiac's modules (module-level imports; TYPE_CHECKING blocks and the
  imports inside functions are not executed at import time, so they cannot form a cycle there).
- No branch on a target's name outside that target's own module or folder.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CLOUD = ("boto3", "botocore", "pulumi", "pulumi_aws", "stacks")
TARGET_NAMES = ("aws", "hosts", "local")


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted((REPO / "fogiac").rglob("*.py")):
        parts = path.relative_to(REPO).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


def _top_level_imports(tree: ast.Module, module: str, is_package: bool) -> list[str]:
    """Modules imported when ``module`` is imported (skipping ``if TYPE_CHECKING:`` blocks)."""
    found: list[str] = []
    base = module.split(".") if is_package else module.split(".")[:-1]

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, ast.Import):
                found.extend(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                prefix = base[: len(base) - node.level + 1] if node.level else []
                target = ".".join(prefix + ([node.module] if node.module else []))
                # ``from pkg import sub`` imports the module pkg.sub; ``from mod import name`` imports mod
                found.extend(f"{target}.{alias.name}" if f"{target}.{alias.name}" in MODULES else target
                             for alias in node.names)
            elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                continue
            elif isinstance(node, (ast.If, ast.Try)):
                visit(node.body + node.orelse + [s for h in getattr(node, "handlers", []) for s in h.body])
    visit(tree.body)
    return found


def _all_imports(tree: ast.Module) -> list[str]:
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.append(node.module)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "need"
              and node.args and isinstance(node.args[0], ast.Constant)):
            names.append(str(node.args[0].value))
    return names


def test_only_the_aws_target_touches_cloud_sdks_and_stacks() -> None:
    offenders = []
    for name, path in _modules().items():
        if name.startswith("fogiac.targets.aws"):
            continue
        for imported in _all_imports(ast.parse(path.read_text())):
            if imported.split(".")[0] in CLOUD:
                offenders.append(f"{path.relative_to(REPO)} imports {imported}")
    assert offenders == []


def test_no_import_cycles() -> None:
    modules = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        imported = _top_level_imports(ast.parse(path.read_text()), name, path.name == "__init__.py")
        graph[name] = {m for m in imported if m in modules and m != name}
    # Tarjan's strongly connected components: any component of more than one module is a cycle.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                connect(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            connect(node)
    assert cycles == []


def test_no_branch_on_a_target_name_outside_its_own_module() -> None:
    offenders = []
    for name, path in _modules().items():
        if name.startswith("fogiac.targets."):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Compare):
                continue
            text = ast.unparse(node)
            consts = [c.value for c in ast.walk(node) if isinstance(c, ast.Constant)]
            if "target" in text and any(c in TARGET_NAMES for c in consts):
                offenders.append(f"{path.relative_to(REPO)}:{node.lineno}: {text}")
    assert offenders == []
