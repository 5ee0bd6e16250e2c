"""The layering the lifecycle issue asks for, checked over the source with ``ast`` (nothing is imported).

Every import counts: at module level, inside functions, under ``TYPE_CHECKING``, through
``importlib.import_module("...")``, as ``"fogiac.x:attr"`` registry strings, and through an entry point
group: a module that names a group ``pyproject.toml`` declares (``registry.load("fogiac.x", ...)``,
``Registry("fogiac.x", ...)``, ``GROUP = "fogiac.x"``) imports the modules that group's entry points name.
An entry point in a plug-in's own folder (a target's, a middleware's, a workload's) is the other way
round: the plug-in answers the loader's protocol, and its own imports of that protocol are the edge; an
entry point anywhere else is a plain import in disguise and counts as one.

- manifest never imports plan, net, provision, lifecycle, cli or a target's folder;
- plan never imports a middleware's folder, provision, lifecycle or a target's folder;
- provision never imports a middleware's folder or a target's folder;
- net never imports targets, lifecycle or cli; cli imports no target's folder;
- the Pulumi engine (``fogiac/pulumi_engine/``) never imports targets, provision, net, cli or a middleware:
  a cloud's target feeds it, never the reverse;
- no import cycle spans two folders;
- only ``fogiac/targets/aws/`` (and ``stacks/aws/``) touch boto3, botocore, pulumi, pulumi_aws or ``stacks``,
  except that the provider-neutral engine ``fogiac/pulumi_engine/`` imports ``pulumi`` (and nothing else
  of these), and the shared state's modules (``fogiac/sealed.py``: secrets sealed under a KMS key) import
  and name boto3 and botocore, whichever target the stack runs on; no code line outside ``targets/aws/``
  names Client VPN, EC2 or the instance catalogue
  (comments and docstrings may);
- the neutral core (manifest, plan, lifecycle, provision, cli) names no cloud in code: no AWS name
  (aws, VPC, its ranges, flow logs, Amazon Time Sync), no region default, no tag limit or subnet-derived
  cap; those are the aws ``cloud:`` variant's and target's (comments, docstrings and the documentation
  strings of a field's ``description=`` or an option's ``help=`` may name them);
- ``fogiac/errors.py`` is one neutral tree: it names no middleware, VPN, cloud or engine, whose errors
  subclass its classes in their own folders;
- ``fogiac/certs.py`` keeps what every middleware shares (the CA, edge identities, signing a host's CSR) and
  names no middleware in code: a middleware's certificate names and files live in its folder
  (``net/relay/tls.py``, ``net/zenoh/tls.py``);
- no branch on a target's name outside that target's own folder;
- ``stacks/`` holds one folder per cloud, named after that cloud's target (``stacks/aws/``), and nothing
  else but its empty top.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest
import tomllib

REPO = Path(__file__).resolve().parents[1]
CLOUD = ("boto3", "botocore", "pulumi", "pulumi_aws", "stacks")
# Where a stack's state is kept with a team: its KMS key belongs to the state, not to a target.
SHARED_STATE = ("fogiac.sealed",)
ENGINE = "fogiac.pulumi_engine"  # the one Pulumi engine: pulumi, and no cloud's SDK or program
TARGET_NAMES = ("aws", "hosts", "local")
MIDDLEWARES = ("fogiac.net.relay", "fogiac.net.zenoh")
TARGET_FOLDERS = tuple(f"fogiac.targets.{name}" for name in TARGET_NAMES)
# What "naming AWS" means in a code line: the SDKs, the Client VPN, EC2 and its catalogue.
AWS_WORDS = re.compile(r"boto3|botocore|pulumi_aws|client[ _]?vpn|clientvpn|\bec2\b|instance_types\.json", re.I)
REF = re.compile(r"^((?:fogiac|stacks|workloads)(?:\.\w+)+):\w+$")
# Where a plug-in lives: an entry point here is the plug-in answering its loader, not the loader importing it.
PLUGIN_FOLDERS = (*TARGET_FOLDERS, *MIDDLEWARES, "workloads")
# group -> {name: "module:attr"}, as fogiac declares its own plug-ins.
ENTRY_POINTS: dict[str, dict[str, str]] = tomllib.loads((REPO / "pyproject.toml").read_text())["project"].get(
    "entry-points", {})
NEUTRAL_CORE = ("fogiac.manifest", "fogiac.plan", "fogiac.lifecycle", "fogiac.provision", "fogiac.cli")
# A cloud's own words in a neutral code line: the provider, its network (VPC, the VPN's client range,
# flow logs to CloudWatch), its time service, a region name (us-west-2, ap-southeast-1, us-gov-east-1).
CLOUD_WORDS = re.compile(r"\baws\b|amazon|cloudwatch|\bvpcs?\b|vpc_|vpc[A-Z]|client_cidr|flow_?logs?|time ?sync|"
                         r"169\.254\.169\.123|\b[a-z]{2}-(?:gov-)?(?:north|south|east|west|central)[a-z]*-\d\b", re.I)
# A cloud's limits: a tag count or length (AWS: 50 a resource, keys of 128, values of 256) and a node cap
# its subnet sets (250); fogiac's own numbers may sit on other lines.
TAG_LINE, TAG_LIMIT, NODE_CAP = re.compile(r"tag", re.I), re.compile(r"^(50|128|256)$"), re.compile(r"^25[01]$")
# Importers of another tool's files, which are AWS-only by that tool's design (FogROS, FogROS2): they
# read and name its AWS calls, regions and images (fogros2_nearest: where the regions FogROS2 lists are).
CLOUD_IMPORTERS = ("fogiac.manifest.fogros", "fogiac.manifest.fogros2", "fogiac.manifest.fogros2_nearest")
# What errors.py may not name: a middleware (relay, Zenoh), a VPN, a cloud, an engine.
PLUGIN_WORDS = re.compile(r"relay|zenoh|vpn|aws|amazon|pulumi|engine|boto", re.I)
MIDDLEWARE_WORDS = re.compile(r"relay|zenoh", re.I)  # what certs.py may not name in code
ERROR_FOLDERS = ("fogiac.net", "fogiac.targets", "fogiac.pulumi_engine")  # where plug-ins keep their own errors


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted((REPO / "fogiac").rglob("*.py")):
        parts = path.relative_to(REPO).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


MODULES = _modules()


def _under(module: str, prefixes: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def _resolve(name: str) -> str:
    """The fogiac module ``name`` denotes (``pkg.mod.attr`` -> ``pkg.mod``), or ``name`` if outside fogiac."""
    while name and name not in MODULES and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def imports(module: str) -> set[str]:
    """Every module ``module`` imports, by any of the ways listed at the top."""
    path = MODULES[module]
    tree = ast.parse(path.read_text())
    base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            prefix = base[: len(base) - node.level + 1] if node.level else []
            target = ".".join(prefix + ([node.module] if node.module else []))
            found.update(_resolve(f"{target}.{alias.name}") if f"{target}.{alias.name}" in MODULES else target
                         for alias in node.names)
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str) and ast.unparse(node.func).endswith(("import_module", "need")):
            found.add(node.args[0].value)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and REF.match(node.value):
            found.add(node.value.split(":")[0])
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in ENTRY_POINTS:
            found.update(name for name in group_modules(node.value) if not _under(name, PLUGIN_FOLDERS))
    return {_resolve(name) for name in found} - {module}


def group_modules(group: str) -> set[str]:
    """The modules the entry points of ``group`` name (``module:attr`` or a module)."""
    return {_resolve(value.partition(":")[0]) for value in ENTRY_POINTS[group].values()}


GRAPH = {name: imports(name) for name in MODULES}


def folder(module: str) -> str:
    """``fogiac.plan.model`` -> ``plan``; a module at fogiac's top (``fogiac.state``) is a folder of its own."""
    return module.split(".")[1] if module.count(".") >= 1 else module


RULES = [
    ("fogiac.manifest", ("fogiac.plan", "fogiac.net", "fogiac.provision", "fogiac.lifecycle", "fogiac.cli",
                         *TARGET_FOLDERS)),
    ("fogiac.plan", (*MIDDLEWARES, "fogiac.provision", "fogiac.lifecycle", *TARGET_FOLDERS)),
    ("fogiac.provision", (*MIDDLEWARES, *TARGET_FOLDERS)),
    ("fogiac.net", ("fogiac.targets", "fogiac.lifecycle", "fogiac.cli")),
    ("fogiac.cli", TARGET_FOLDERS),
    (ENGINE, ("fogiac.targets", "fogiac.provision", "fogiac.net", "fogiac.cli")),
]


@pytest.mark.parametrize(("layer", "forbidden"), RULES, ids=[rule[0] for rule in RULES])
def test_a_layer_imports_only_what_is_below_it(layer: str, forbidden: tuple[str, ...]) -> None:
    offenders = sorted(f"{MODULES[m].relative_to(REPO)} imports {imported}" for m in MODULES if _under(m, (layer,))
                       for imported in GRAPH[m] if _under(imported, forbidden))
    assert offenders == []


def test_an_entry_point_group_is_an_import_of_its_loader() -> None:
    """The CLI names its verbs' modules only through ``fogiac.commands``: the graph sees its own, not the
    verbs a target's folder adds (``fogiac vpn``: the plug-in's side), and every group fogiac declares is
    loaded somewhere (a table nothing reads is a table to remove)."""
    verbs = group_modules("fogiac.commands")
    own = {m for m in verbs if not _under(m, PLUGIN_FOLDERS)}
    assert own and own <= GRAPH["fogiac.cli"]
    assert verbs - own and not (verbs - own) & GRAPH["fogiac.cli"]
    loaders = {group: sorted(m for m, path in MODULES.items() if f'"{group}"' in path.read_text())
               for group in ENTRY_POINTS}
    assert [group for group, found in loaders.items() if not found] == []


def test_no_import_cycle_spans_two_folders() -> None:
    """Tarjan's strongly connected components over every import: a component in two folders is a cycle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(m for m in GRAPH[node] if m in MODULES):
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
            if len({folder(m) for m in component}) > 1:
                cycles.append(sorted(component))

    for node in sorted(GRAPH):
        if node not in index:
            connect(node)
    assert cycles == []


def _may_import(module: str, top: str) -> bool:
    """Whether ``module`` may import the cloud package ``top``: the aws target all of them, the engine pulumi,
    the shared state's own modules (secrets sealed under a KMS key) boto3 and botocore, whatever the target."""
    return (_under(module, ("fogiac.targets.aws",)) or (_under(module, (ENGINE,)) and top == "pulumi")
            or (_under(module, SHARED_STATE) and top in ("boto3", "botocore")))


def test_only_the_aws_target_touches_cloud_sdks_and_stacks() -> None:
    offenders = sorted(f"{MODULES[m].relative_to(REPO)} imports {imported}" for m in MODULES for imported in GRAPH[m]
                       if imported.split(".")[0] in CLOUD and not _may_import(m, imported.split(".")[0]))
    assert offenders == []


def test_stacks_hold_one_folder_per_cloud() -> None:
    """A cloud's programs sit in ``stacks/<target>/``, so a second cloud's never mix with aws's."""
    strays = sorted(str(p.relative_to(REPO)) for p in (REPO / "stacks").rglob("*.py")
                    if p.parent == REPO / "stacks" and p.name != "__init__.py"
                    or p.parent != REPO / "stacks" and p.relative_to(REPO / "stacks").parts[0] not in TARGET_NAMES)
    top = ast.parse((REPO / "stacks" / "__init__.py").read_text()).body
    assert (strays, [type(node).__name__ for node in top[1:]]) == ([], [])


def test_the_engine_imports_pulumi() -> None:
    """The rule above lets the engine import pulumi; it does (so the exception is not stale)."""
    assert any(imported.split(".")[0] == "pulumi" for m in MODULES if _under(m, (ENGINE,)) for imported in GRAPH[m])


def _code_tokens(path: Path) -> list[tuple[tuple[int, int], tuple[int, int], str]]:
    """The file's code without comments and docstrings: (start, end, text) of its names and strings."""
    source = path.read_text()
    docstrings = {(n.body[0].value.lineno, n.body[0].value.end_lineno) for n in ast.walk(ast.parse(source))
                  if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and n.body
                  and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)
                  and isinstance(n.body[0].value.value, str)}
    skipped = {line for first, last in docstrings for line in range(first, (last or first) + 1)}
    out: list[tuple[tuple[int, int], tuple[int, int], str]] = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type in (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE) or token.start[0] in skipped:
            continue
        out.append((token.start, token.end, token.string))
    return out


def _code_lines(path: Path) -> list[tuple[int, str]]:
    """The file's code without comments and docstrings: (line, text of its names and strings)."""
    return [(start[0], text) for start, _, text in _code_tokens(path)]


def test_no_code_line_outside_the_aws_target_names_aws() -> None:
    offenders = sorted({f"{path.relative_to(REPO)}:{line}" for m, path in MODULES.items()
                        if not _under(m, ("fogiac.targets.aws", *SHARED_STATE))
                        for line, text in _code_lines(path) if AWS_WORDS.search(text)})
    assert offenders == []


def _documentation(path: Path) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Where the strings given as ``description=`` or ``help=`` are (a field's or an option's documentation)."""
    return [((node.value.lineno, node.value.col_offset), (node.value.end_lineno or 0, node.value.end_col_offset or 0))
            for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.keyword) and node.arg in ("description", "help")
            and not any(isinstance(n, ast.Call) for n in ast.walk(node.value))]


def _cloud_lines(path: Path, root: Path = REPO) -> list[str]:
    """The code lines of ``path`` that name a cloud's words or limits (:data:`CLOUD_WORDS`, the limits)."""
    documentation = _documentation(path)
    lines: dict[int, list[str]] = {}
    for start, end, text in _code_tokens(path):
        if not any(first <= start and end <= last for first, last in documentation):
            lines.setdefault(start[0], []).append(text)
    out = []
    for line, tokens in lines.items():
        text = " ".join(tokens)
        if CLOUD_WORDS.search(text) or any(NODE_CAP.match(t) for t in tokens) \
                or (TAG_LINE.search(text) and any(TAG_LIMIT.match(t) for t in tokens)):
            out.append(f"{path.relative_to(root)}:{line}: {text}")
    return out


def test_the_neutral_core_names_no_cloud() -> None:
    offenders = sorted(found for m, path in MODULES.items() if _under(m, NEUTRAL_CORE) and m not in CLOUD_IMPORTERS
                       for found in _cloud_lines(path))
    assert offenders == []


def test_the_cloud_check_sees_what_it_is_meant_to(tmp_path: Path) -> None:
    """The words and limits the neutral-core check looks for are found where they were (and would be again)."""
    sample = tmp_path / "sample.py"
    sample.write_text('"""Docstrings may say aws, VPC and us-west-2."""\n'
                      'DEFAULT = "aws"  # comments may too\n'
                      'REGION = "us-west-2"\n'
                      'vpc_cidr = client_cidr = flow_logs = "169.254.169.123"\n'
                      'MAX_TAGS, MAX_TAG_KEY, MAX_TAG_VALUE = 50, 128, 256\n'
                      'MAX_NODES = 250\n'
                      'PORT = 128  # a number alone is not a limit\n'
                      'Field(default=1, description="AWS region (documentation)")\n'
                      'Field(default="aws", description="Where cloud nodes run.")\n')
    assert [line.split(":")[1] for line in _cloud_lines(sample, tmp_path)] == ["2", "3", "4", "5", "6", "9"]


def test_errors_is_one_neutral_tree() -> None:
    """errors.py names no middleware, VPN, cloud or engine in code; their errors live in their folders,
    each a subclass of a neutral error rather than of FogiacError itself."""
    path = REPO / "fogiac" / "errors.py"
    named = sorted(f"errors.py:{line}: {text}" for line, text in _code_lines(path) if PLUGIN_WORDS.search(text))
    assert named == []
    direct = sorted(f"{path.relative_to(REPO)}:{node.lineno}: {node.name}" for m, path in MODULES.items()
                    if _under(m, ERROR_FOLDERS) for node in ast.walk(ast.parse(path.read_text()))
                    if isinstance(node, ast.ClassDef)
                    and any(ast.unparse(base).endswith("FogiacError") for base in node.bases))
    assert direct == []


def test_certs_name_no_middleware() -> None:
    """The shared certificate module names no middleware in code: the relay's host names and its hand-run
    lab files are the relay's (:mod:`fogiac.net.relay.tls`), as the Zenoh router's are Zenoh's."""
    path = REPO / "fogiac" / "certs.py"
    assert sorted(f"certs.py:{line}: {text}" for line, text in _code_lines(path) if MIDDLEWARE_WORDS.search(text)) == []


def test_no_branch_on_a_target_name_outside_its_own_folder() -> None:
    offenders = []
    for name, path in MODULES.items():
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


def test_only_the_stack_state_names_the_stack_folder() -> None:
    """A :class:`fogiac.state.StackState` owns a stack's folder: nothing else builds its path."""
    offenders = sorted(f"{path.relative_to(REPO)}:{line}" for m, path in MODULES.items() if m != "fogiac.state"
                       for line, text in _code_lines(path) if text == "stack_dir")
    assert offenders == []
