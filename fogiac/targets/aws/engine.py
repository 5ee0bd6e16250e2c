"""The Pulumi engine through its Automation API: two stacks per manifest and environment.

State stays on the user's disk (a file backend in the stack's state folder), secrets are
encrypted with a passphrase (``$PULUMI_CONFIG_PASSPHRASE``, else a generated 0600 file), and
the stack programs are called inline, so no Pulumi project directory is needed. Network goes
up before compute (compute is fed network's outputs) and comes down after it.
``pulumi.automation`` is imported lazily: importing this module costs nothing.
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import subprocess
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.certs import SSH_KEY, load_or_create_bundle, load_or_create_ssh_key, write_private
from fogiac.errors import EngineError
from fogiac.lifecycle.events import OnEvent, Progress
from fogiac.lifecycle.events import Timers as _Timers
from fogiac.plan.model import Plan
from fogiac.state import StackState, read_json
from fogiac.targets.aws.sdk import need
from stacks import LAYERS, PROJECT

# The one place the Pulumi CLI version is pinned: the release matching the pulumi SDK in use.
PULUMI_CLI_VERSION = "3.272.0"
INSTALL = f"curl -fsSL https://get.pulumi.com | sh -s -- --version {PULUMI_CLI_VERSION}"
PASSPHRASE_FILE = "pulumi-passphrase"
OUTPUTS_FILE = "outputs.json"
SSH_KEY_FILE = Path(StackState.SSH) / SSH_KEY  # in the stack folder, where stacks/entry.py (plain pulumi up) keeps it
CERTS_DIR = StackState.CERTS
VPN_NOTICE = ("The Client VPN endpoint's subnet association takes about 10 minutes to create "
              "(and again to delete); its resources wait up to 30 minutes.")


def layer_stack(stack: str, layer: str) -> str:
    """The Pulumi stack of one layer: ``<manifest>-<environment>-<layer>``."""
    if layer not in LAYERS:
        raise EngineError(f"unknown layer {layer!r}; valid: {', '.join(LAYERS)}")
    return f"{stack}-{layer}"


def backend_dir(stack: str, *, create: bool = True) -> Path:
    return StackState(stack).target_file("pulumi", create=create)


def pulumi_cli() -> Path:
    """The Pulumi CLI on PATH (or where its installer puts it), at least the pinned version."""
    found = shutil.which("pulumi") or next(
        (str(p) for p in [Path.home() / ".pulumi" / "bin" / "pulumi"] if p.is_file() and os.access(p, os.X_OK)), None)
    if found is None:
        raise EngineError(f"the Pulumi CLI is not installed (fogiac needs {PULUMI_CLI_VERSION}); "
                          f"install it with: {INSTALL}")
    try:
        out = subprocess.run([found, "version"], capture_output=True, text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError) as err:
        raise EngineError(f"the Pulumi CLI at {found} does not run ({err}); reinstall it with: {INSTALL}") from None
    match = re.search(r"(\d+)\.(\d+)\.(\d+)", out)
    have = tuple(int(x) for x in match.groups()) if match else (0, 0, 0)
    want = tuple(int(x) for x in PULUMI_CLI_VERSION.split("."))
    if have[0] != want[0] or have < want:
        raise EngineError(f"the Pulumi CLI at {found} is {'.'.join(map(str, have))}, fogiac needs "
                          f"{PULUMI_CLI_VERSION} or a later 3.x; install it with: {INSTALL}")
    return Path(found)


def passphrase(stack: str) -> str:
    """The secrets passphrase: from the environment, else the stack's generated 0600 file."""
    given = os.environ.get("PULUMI_CONFIG_PASSPHRASE")
    if given is not None:
        return given
    given_file = os.environ.get("PULUMI_CONFIG_PASSPHRASE_FILE")
    if given_file:
        return Path(given_file).read_text().strip()
    path = StackState(stack).target_file(PASSPHRASE_FILE, create=True)
    if not path.exists():
        write_private(path, secrets.token_urlsafe(32).encode())
    return path.read_text().strip()


def workspace_env(stack: str) -> dict[str, str]:
    """What the Pulumi CLI needs: the file backend, the passphrase, no update nagging."""
    backend = backend_dir(stack)
    backend.mkdir(mode=0o700, exist_ok=True)
    return {
        "PULUMI_BACKEND_URL": backend.as_uri(),
        "PULUMI_CONFIG_PASSPHRASE": passphrase(stack),
        "PULUMI_SKIP_UPDATE_CHECK": "true",
        "PULUMI_AUTOMATION_API_SKIP_VERSION_CHECK": "false",
    }


def stack_config(plan: Plan) -> dict[str, str]:
    return {"aws:region": plan.region}


def ssh_public_key(stack: str) -> str:
    """The stack's SSH key (ed25519, private half 0600), created on first use.

    Kept where ``stacks/entry.py`` (plain ``pulumi up``) keeps it, so both paths use one key.
    """
    state = StackState(stack)
    state.ensure()
    return load_or_create_ssh_key(state.ssh_dir)


def known_ids(stack: str) -> frozenset[str]:
    """Every cloud id fogiac's state knows for ``stack`` (outputs and Pulumi checkpoints)."""
    ids: set[str] = set()
    state = StackState(stack)

    def walk(value: Any) -> None:
        if isinstance(value, Mapping):
            for key, item in value.items():
                if key in {"id", "vpc_id", "instance_id", "vpn_endpoint_id"} and isinstance(item, str):
                    ids.add(item)
                walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)

    walk(read_json(state.target_file(OUTPUTS_FILE)))
    for checkpoint in state.target_file("pulumi").glob(".pulumi/stacks/**/*.json") if state.exists() else ():
        walk(read_json(checkpoint))
    return frozenset(ids)


@dataclass(frozen=True)
class LayerResult:
    layer: str
    ok: bool
    outputs: Mapping[str, Any]
    summary: str  # e.g. "create 12" or the engine's error, one line


class Engine:
    """Runs one manifest's layers through the Automation API (the Pulumi CLI does the work)."""

    def __init__(self, plan: Plan, *, on_event: OnEvent | None = None) -> None:
        self.plan = plan
        self.on_event = translated(on_event)
        pulumi_cli()  # fail with the install line before touching any state

    def _options(self) -> Any:
        auto = need("pulumi.automation")

        env = workspace_env(self.plan.stack)
        project = auto.ProjectSettings(name=PROJECT, runtime="python",
                                       backend=auto.ProjectBackend(url=env["PULUMI_BACKEND_URL"]))
        return auto.LocalWorkspaceOptions(env_vars=env, secrets_provider="passphrase", project_settings=project)

    def _stack(self, layer: str, program: Callable[[], None]) -> Any:
        auto = need("pulumi.automation")

        stack = auto.create_or_select_stack(stack_name=layer_stack(self.plan.stack, layer), project_name=PROJECT,
                                            program=program, opts=self._options())
        for key, value in stack_config(self.plan).items():
            stack.set_config(key, auto.ConfigValue(value=value))
        return stack

    def _existing(self, layer: str) -> Any | None:
        """The layer's stack if it was ever created (destroy and refresh skip the others)."""
        auto = need("pulumi.automation")

        if not backend_dir(self.plan.stack, create=False).exists():
            return None  # never applied: no state to open (and none to create)
        try:
            return auto.select_stack(stack_name=layer_stack(self.plan.stack, layer), project_name=PROJECT,
                                     program=lambda: None, opts=self._options())
        except auto.StackNotFoundError:
            return None

    def programs(self, *, operator_cidrs: tuple[str, ...],
                 network_outputs: Callable[[], Mapping[str, Any]]) -> dict[str, Callable[[], None]]:
        stack = self.plan.stack
        return need("stacks.program").layer_programs(
            self.plan, certs=load_or_create_bundle(stack, StackState(stack).certs),
            operator_cidrs=operator_cidrs, public_key_openssh=ssh_public_key(stack), network_outputs=network_outputs)

    def preview(self, *, operator_cidrs: tuple[str, ...]) -> list[LayerResult]:
        results: list[LayerResult] = []
        programs = self.programs(operator_cidrs=operator_cidrs, network_outputs=lambda: results[0].outputs)
        for layer in LAYERS:
            if layer == "compute" and not results[0].outputs.get("subnet_ids"):
                results.append(LayerResult(layer, True, {}, "previewed once the network stack exists"))
                continue
            stack = self._stack(layer, programs[layer])
            result = stack.preview(on_event=self.on_event, color="never")
            outputs = {k: v.value for k, v in stack.outputs().items()}
            results.append(LayerResult(layer, True, outputs, _changes(result.change_summary)))
        return results

    def up(self, *, operator_cidrs: tuple[str, ...]) -> dict[str, Mapping[str, Any]]:
        """Network, then compute fed network's outputs; raises EngineError naming the failed layer."""
        auto = need("pulumi.automation")

        outputs: dict[str, Mapping[str, Any]] = {}
        programs = self.programs(operator_cidrs=operator_cidrs, network_outputs=lambda: outputs["network"])
        for layer in LAYERS:
            stack = self._stack(layer, programs[layer])
            try:
                # refresh first: a sweep or a console click may have deleted what the state lists
                result = stack.up(on_event=self.on_event, color="never", refresh=True)
            except auto.CommandError as err:
                raise EngineError(f"{layer} stack failed: {_last_error(err)}; "
                                  f"`fogiac down` removes what was made") from None
            outputs[layer] = {k: v.value for k, v in result.outputs.items()}
        return outputs

    def destroy(self, *, layers: tuple[str, ...] = ("compute", "network")) -> list[str]:
        """Destroy ``layers`` in that order, continuing past errors; return one line per failure."""
        auto = need("pulumi.automation")

        errors: list[str] = []
        for layer in layers:
            stack = self._existing(layer)
            if stack is None:
                continue
            try:
                stack.destroy(on_event=self.on_event, continue_on_error=True, color="never")
            except auto.CommandError as err:
                errors.append(f"{layer} stack: {_last_error(err)}")
        return errors

    def refresh(self) -> list[LayerResult]:
        auto = need("pulumi.automation")

        results = []
        for layer in LAYERS:
            stack = self._existing(layer)
            if stack is None:
                continue
            try:
                result = stack.refresh(on_event=self.on_event, color="never")
                outputs = {k: v.value for k, v in stack.outputs().items()}
                results.append(LayerResult(layer, True, outputs, _changes(result.summary.resource_changes)))
            except auto.CommandError as err:
                results.append(LayerResult(layer, False, {}, _last_error(err)))
        return results


def _changes(summary: Mapping[str, int] | None) -> str:
    parts = [f"{op} {n}" for op, n in sorted((summary or {}).items()) if n]
    return ", ".join(parts) or "no changes"


def _last_error(err: Exception) -> str:
    """The most telling line of an engine failure (its stderr's last 'error:' line)."""
    text = str(getattr(err, "stderr", "") or err)
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error" in ln.lower()]
    return (errors or lines or ["unknown error"])[-1][:400]


def progress(event: Any) -> Progress | None:
    """A Pulumi engine event as the lifecycle's neutral :class:`Progress` (None: nothing to show)."""
    pre = getattr(event, "resource_pre_event", None)
    done = getattr(event, "res_outputs_event", None)
    failed = getattr(event, "res_op_failed_event", None)
    diag = getattr(event, "diagnostic_event", None)
    if pre is not None and not pre.planning and _shown(pre.metadata):
        meta = pre.metadata
        return Progress("start", meta.urn, meta.urn.rsplit("::", 1)[-1], meta.type,
                        str(getattr(meta.op, "value", meta.op)))
    if done is not None:
        return Progress("done", done.metadata.urn)
    if failed is not None:
        return Progress("failed", failed.metadata.urn)
    if diag is not None and diag.severity == "error" and diag.message.strip():
        return Progress("diagnostic", message=diag.message.strip().splitlines()[-1])
    return None


def translated(on_event: OnEvent | None) -> Callable[[Any], None] | None:
    """The engine's ``on_event``: each Pulumi event handed on as :class:`Progress`."""
    if on_event is None:
        return None

    def hand_on(event: Any) -> None:
        found = progress(event)
        if found is not None:
            on_event(found)
    return hand_on


class Timers(_Timers):
    """The neutral timers fed straight from Pulumi engine events (tests and tools that hold raw events)."""

    def __call__(self, event: Any) -> None:
        found = event if isinstance(event, Progress) else progress(event)
        if found is not None:
            super().__call__(found)


def _shown(meta: Any) -> bool:
    """Real changes to real resources (not the stack itself, not 'same')."""
    op = str(getattr(meta.op, "value", meta.op))
    return op not in {"same", "read"} and not meta.type.startswith("pulumi:")
