"""A static walk of one value through fogiac's code: how many places a reader visits to follow it.

Start at a function and one of its parameters (``fogiac/cli/deploy.py:up manifest``); the walk
tracks that name and every name assigned from an expression that mentions a tracked one, and
enters every function a tracked value is passed to (resolved through the module's imports: a
function of the module, ``from x import f``, ``module.f``, ``self.f``; calls through an object of
unknown type are dynamic dispatch and are not followed). Each function is entered once. The trip is
the sequence of files the reader is in, calls and returns both:

- a **stay** is a run of steps in one file (re-entering a file is a new stay);
- a **climb** is a step into a file of a higher layer than the one the reader is in, by data flow:
  fogiac's top-level modules (state, deployment, certs, ...) < manifest < plan < net < provision <
  targets (and stacks/) < lifecycle < cli. A return to the caller counts when it climbs.

Not a test: a figure for the foundation issue's note. ``--trace`` prints the trip; ``--repo`` walks
another checkout (``git worktree add /tmp/base 5d5c9b4``); ``--between-files`` follows only calls into
another module: a module's own functions are not entered, so what they call out is not counted either
(work moved into a module's private helper leaves this figure; the default rules still count it, so give
both).

    python benchmarks/walk.py fogiac/cli/deploy.py:up manifest [--trace] [--between-files] [--repo DIR]

Calibration against the issue's walker (which is not in the repository; its rules are unknown). The issue
gives, for ``up``'s manifest: 54 stays / 21 files / 22 climbs on 5d5c9b4, re-entering state.py 9 times,
lifecycle/edge.py 7, net/middleware.py 6, deployment.py 5; and 20 / 13 / 5 "two days" earlier (taken as
2562250, 11-24 00:38; the commits of 11-23 18:52 to it measure within two stays of it). Rule variants tried (stays /
files / climbs, 5d5c9b4 then 2562250; state/edge/middleware/deployment stays on 5d5c9b4):

    this walker's default rules                  119/34/35   43/18/9    3/6/4/9
    --between-files                              55/22/21    25/11/9    2/3/3/5
    same, plus methods of typed receivers        69-75/22-23/23-25  29-31/12-13/11
    no returns in the trip, typed receivers,
      calls into other modules only              37/23/12    15/13/5    5/1/3/4
    no tracking of assigned names (any of these) <= 43/15/10  <= 21/10/5

No variant reproduces all three data points: --between-files comes within one of each total on
5d5c9b4 but not on the earlier commit nor the per-file re-entries; the walk without returns gets the
earlier commit's files and climbs but not its stays nor 5d5c9b4's. So this walker's figures are its
own; compare them across commits of this repository, not with the issue's 30 stays / 8 climbs. On
3bbf99c (main, 11-28): 103/38/32 by default, 59/21/23 with --between-files; after security groups checked
themselves when made and sequence.up made one call into edge.py for its last step: 101/37/32 by default,
55/20/23 with --between-files.
"""

from __future__ import annotations

import argparse
import ast
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RANK = {"manifest": 1, "plan": 2, "net": 3, "provision": 4, "targets": 5, "stacks": 5, "lifecycle": 6, "cli": 7}


@dataclass
class Module:
    name: str
    path: Path
    tree: ast.Module
    imports: dict[str, str] = field(default_factory=dict)  # local name -> "module" or "module:attr"
    functions: dict[str, ast.FunctionDef | ast.AsyncFunctionDef] = field(default_factory=dict)  # "f", "Class.m"


def _load(repo: Path = REPO) -> dict[str, Module]:
    out: dict[str, Module] = {}
    for root in ("fogiac", "stacks"):
        for path in sorted((repo / root).rglob("*.py")):
            parts = path.relative_to(repo).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = Module(name, path, ast.parse(path.read_text()))
    for mod in out.values():
        package = mod.name if mod.path.name == "__init__.py" else mod.name.rpartition(".")[0]
        for node in mod.tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                mod.functions[node.name] = node
            elif isinstance(node, ast.ClassDef):
                for item in node.body:
                    if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)):
                        mod.functions[f"{node.name}.{item.name}"] = item
        for found in ast.walk(mod.tree):
            if isinstance(found, ast.Import):
                for alias in found.names:
                    mod.imports[alias.asname or alias.name.split(".")[0]] = alias.name
            elif isinstance(found, ast.ImportFrom):
                base = found.module or ""
                if found.level:
                    up = package.split(".")[: len(package.split(".")) - found.level + 1]
                    base = ".".join([*up, *([found.module] if found.module else [])])
                for alias in found.names:
                    full = f"{base}.{alias.name}"
                    mod.imports[alias.asname or alias.name] = full if full in out else f"{base}:{alias.name}"
    return out


def _mentions(expr: ast.AST | None, tracked: set[str]) -> bool:
    return expr is not None and any(isinstance(n, ast.Name) and n.id in tracked for n in ast.walk(expr))


def _names(target: ast.AST) -> set[str]:
    return {n.id for n in ast.walk(target) if isinstance(n, ast.Name)}


class Walk:
    def __init__(self, modules: dict[str, Module], *, same_module: bool = True) -> None:
        self.modules = modules
        self.same_module = same_module  # False: a module's own functions are read within its stay
        self.seen: set[tuple[str, str]] = set()
        self.trip: list[tuple[str, str]] = []  # (module, function) the reader is in, step by step

    def resolve(self, mod: Module, func: ast.expr, cls: str | None) -> tuple[Module, str] | None:
        if isinstance(func, ast.Name):
            if func.id in mod.functions:
                return mod, func.id
            ref = mod.imports.get(func.id, "")
            where, _, attr = ref.partition(":")
            if attr and where in self.modules and attr in self.modules[where].functions:
                return self.modules[where], attr
        elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            owner = func.value.id
            if owner == "self" and cls and f"{cls}.{func.attr}" in mod.functions:
                return mod, f"{cls}.{func.attr}"
            where = mod.imports.get(owner, "")
            if where in self.modules and func.attr in self.modules[where].functions:
                return self.modules[where], func.attr
        return None

    def visit(self, mod: Module, name: str, tracked: set[str]) -> None:
        self.seen.add((mod.name, name))
        self.trip.append((mod.name, name))
        node = mod.functions[name]
        cls = name.split(".")[0] if "." in name else None
        tracked = set(tracked)
        for stmt in node.body:
            for sub in ast.walk(stmt):
                if isinstance(sub, (ast.Assign, ast.AnnAssign, ast.AugAssign)) and _mentions(sub.value, tracked):
                    for target in (sub.targets if isinstance(sub, ast.Assign) else [sub.target]):
                        tracked |= _names(target)
                elif isinstance(sub, (ast.For, ast.comprehension)) and _mentions(sub.iter, tracked):
                    tracked |= _names(sub.target)
                elif isinstance(sub, ast.withitem) and sub.optional_vars is not None \
                        and _mentions(sub.context_expr, tracked):
                    tracked |= _names(sub.optional_vars)
            calls = sorted((c for c in ast.walk(stmt) if isinstance(c, ast.Call)),
                           key=lambda c: (c.lineno, c.col_offset))
            for call in calls:
                if not any(_mentions(a, tracked) for a in [*call.args, *(k.value for k in call.keywords)]):
                    continue
                found = self.resolve(mod, call.func, cls)
                if found is not None and found[0] is mod and not self.same_module:
                    continue
                if found is None or (found[0].name, found[1]) in self.seen:
                    continue
                callee, fname = found
                params = self._receiving(callee.functions[fname], call, tracked)
                if params:
                    self.visit(callee, fname, params)
                    self.trip.append((mod.name, name))  # back in the caller

    @staticmethod
    def _receiving(fn: ast.FunctionDef | ast.AsyncFunctionDef, call: ast.Call, tracked: set[str]) -> set[str]:
        positional = [a.arg for a in (*fn.args.posonlyargs, *fn.args.args)]
        if positional and positional[0] in ("self", "cls"):
            positional = positional[1:]
        names = set(positional) | {a.arg for a in fn.args.kwonlyargs}
        out = {positional[i] for i, arg in enumerate(call.args)
               if i < len(positional) and _mentions(arg, tracked)}
        out |= {k.arg for k in call.keywords if k.arg in names and _mentions(k.value, tracked)}
        return out


def rank(module: str) -> int:
    """A module's layer: a folder's package (``fogiac.targets``, its ``__init__``) is of its folder's layer; a
    module at fogiac's top (``fogiac.state``, ``fogiac.middlewares``) of none (0)."""
    parts = module.split(".")
    if parts[0] == "stacks":
        return RANK["stacks"]
    return RANK.get(parts[1], 0) if len(parts) > 1 else 0


def summarise(trip: list[tuple[str, str]]) -> tuple[int, int, int, list[str]]:
    """(stays, files, climbs, the stays' files in order)."""
    stays: list[str] = []
    climbs = 0
    for i, (module, _) in enumerate(trip):
        if not stays or stays[-1] != module:
            stays.append(module)
        if i and rank(module) > rank(trip[i - 1][0]):
            climbs += 1
    return len(stays), len(set(stays)), climbs, stays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("start", help="path/to/module.py:function (or Class.method)")
    parser.add_argument("param", help="the parameter to follow")
    parser.add_argument("--trace", action="store_true", help="print the trip")
    parser.add_argument("--between-files", action="store_true",
                        help="follow only calls into another module (see the docstring's calibration)")
    parser.add_argument("--repo", type=Path, default=REPO, help="the checkout to walk (default: this one)")
    args = parser.parse_args()
    path, _, func = args.start.partition(":")
    module = ".".join(Path(path).with_suffix("").parts)
    modules = _load(args.repo.resolve())
    walk = Walk(modules, same_module=not args.between_files)
    walk.visit(modules[module], func, {args.param})
    stays, files, climbs, order = summarise(walk.trip)
    if args.trace:
        for module, fn in walk.trip:
            print(f"  {module}:{fn}")
    print(f"{args.start} {args.param}: {stays} stays in {files} files, {climbs} climbs back up")
    if args.trace:
        print("  stays: " + " > ".join(order))


if __name__ == "__main__":
    main()
