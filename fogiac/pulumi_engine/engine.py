"""The Pulumi engine through its Automation API: one Pulumi stack per layer of a cloud's project.

The stack programs are called inline, so no Pulumi project directory is needed; the cloud gives
the programs and the stack config (:class:`~.project.Project`), this module everything else. Layers
go up in the project's order, each fed the outputs of those before it, and come down in the reverse.
Where a cloud's API is answered in-process by Pulumi's mocks (a cloud defined in the tests), the
same ``up`` runs each layer under them instead (:mod:`.offline`'s runner): no CLI, no backend.
``pulumi.automation`` is imported lazily: importing this module costs nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from fogiac.lifecycle.events import OnEvent
from fogiac.pulumi_engine import offline
from fogiac.pulumi_engine.errors import EngineError
from fogiac.pulumi_engine.events import translated
from fogiac.pulumi_engine.project import Program, Programs, Project
from fogiac.pulumi_engine.workspace import backend_dir, need, pulumi_cli, shared_backend, workspace_env

# Before a layer's preview: why it cannot be previewed yet (the earlier layers' outputs it needs are
# not there), or None to preview it.
Pending = Callable[[str, Mapping[str, Mapping[str, Any]]], str | None]


@dataclass(frozen=True)
class LayerResult:
    layer: str
    ok: bool
    outputs: Mapping[str, Any]
    summary: str  # e.g. "create 12" or the engine's error, one line


class Engine:
    """Runs one project's layers through the Automation API (the Pulumi CLI does the work), or, given
    ``mocks``, under Pulumi's mocks (the cloud's API answered in-process; the mocks keep its record)."""

    def __init__(self, project: Project, *, on_event: OnEvent | None = None, mocks: Any | None = None) -> None:
        self.project = project
        self.mocks = mocks
        self._on_progress = on_event
        self.on_event = translated(on_event)
        if mocks is None:
            pulumi_cli()  # fail with the install line before touching any state

    def _options(self) -> Any:
        auto = need("pulumi.automation")

        env = workspace_env(self.project.stack)
        settings = auto.ProjectSettings(name=self.project.name, runtime="python",
                                        backend=auto.ProjectBackend(url=env["PULUMI_BACKEND_URL"]))
        return auto.LocalWorkspaceOptions(env_vars=env, secrets_provider="passphrase", project_settings=settings)

    def _stack(self, layer: str, program: Program) -> Any:
        auto = need("pulumi.automation")

        stack = auto.create_or_select_stack(stack_name=self.project.layer_stack(layer), project_name=self.project.name,
                                            program=program, opts=self._options())
        for key, value in self.project.config.items():
            stack.set_config(key, auto.ConfigValue(value=value))
        return stack

    def _existing(self, layer: str) -> Any | None:
        """The layer's stack if it was ever created (destroy and refresh skip the others)."""
        auto = need("pulumi.automation")

        if shared_backend(self.project.stack) is None and not backend_dir(self.project.stack, create=False).exists():
            return None  # never applied: no state to open (and none to create)
        try:
            return auto.select_stack(stack_name=self.project.layer_stack(layer), project_name=self.project.name,
                                     program=lambda: None, opts=self._options())
        except auto.StackNotFoundError:
            return None

    def preview(self, programs: Programs, *, pending: Pending | None = None) -> list[LayerResult]:
        outputs: dict[str, Mapping[str, Any]] = {}
        results: list[LayerResult] = []
        layers = programs(lambda layer: outputs[layer])
        for layer in self.project.layers:
            waiting = pending(layer, outputs) if pending is not None else None
            if waiting is not None:
                results.append(LayerResult(layer, True, {}, waiting))
                continue
            stack = self._stack(layer, layers[layer])
            result = stack.preview(on_event=self.on_event, color="never")
            outputs[layer] = {k: v.value for k, v in stack.outputs().items()}
            results.append(LayerResult(layer, True, outputs[layer], _changes(result.change_summary)))
        return results

    def up(self, programs: Programs) -> dict[str, Mapping[str, Any]]:
        """Each layer in order, fed the outputs of those before; raises EngineError naming the failed layer."""
        outputs: dict[str, Mapping[str, Any]] = {}
        layers = programs(lambda layer: outputs[layer])
        for layer in self.project.layers:
            outputs[layer] = self._up_layer(layer, layers[layer])
        return outputs

    def _up_layer(self, layer: str, program: Program) -> Mapping[str, Any]:
        if self.mocks is not None:
            mocks = offline.recorder(self.mocks, on_event=self._on_progress)
            mocks.layer = layer
            return offline.run_program(program, mocks=mocks, project=self.project.name,
                                       stack=self.project.layer_stack(layer), preview=False)
        auto = need("pulumi.automation")
        stack = self._stack(layer, program)
        try:
            # refresh first: a sweep or a console click may have deleted what the state lists
            result = stack.up(on_event=self.on_event, color="never", refresh=True)
        except auto.CommandError as err:
            raise EngineError(f"{layer} stack failed: {_last_error(err)}; "
                              f"`fogiac down` removes what was made") from None
        return {k: v.value for k, v in result.outputs.items()}

    def destroy(self, *, layers: tuple[str, ...] | None = None) -> list[str]:
        """Destroy ``layers`` (all, last made first) in that order, continuing past errors; one line per failure.

        Under mocks the engine keeps no state to destroy: deleting is the cloud's API's own.
        """
        if self.mocks is not None:
            return []
        auto = need("pulumi.automation")

        errors: list[str] = []
        for layer in layers if layers is not None else tuple(reversed(self.project.layers)):
            stack = self._existing(layer)
            if stack is None:
                continue
            try:
                stack.destroy(on_event=self.on_event, continue_on_error=True, color="never")
            except auto.CommandError as err:
                errors.append(f"{layer} stack: {_last_error(err)}")
        return errors

    def refresh(self) -> list[LayerResult]:
        if self.mocks is not None:
            return []
        auto = need("pulumi.automation")

        results = []
        for layer in self.project.layers:
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
