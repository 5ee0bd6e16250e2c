"""The offline preview: a cloud's stack programs run under Pulumi's mocks, every declared resource recorded.

No credentials, no Pulumi CLI, no files written: ``fogiac plan`` shows the exact resources a
manifest implies, with the inputs the provider would be sent. The cloud says what its mocks answer
(:class:`Placeholders`: ``<name.attr>`` for what only the cloud computes, its function calls); values
that only exist at ``up`` appear as ``<...>`` placeholders and every secret as ``[secret]``. The same
runner (:func:`run_program`) runs a program against any mocks, e.g. a test cloud whose API they are.
pulumi is imported inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import concurrent.futures
import functools
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from fogiac.lifecycle.events import OnEvent, Progress
from fogiac.plan.model import Plan
from fogiac.pulumi_engine.project import Program, Programs, Project
from fogiac.pulumi_engine.workspace import need

if TYPE_CHECKING:
    import pulumi.runtime

SECRET = "[secret]"
_PEM_KEY_MARK = "PRIVATE KEY-----"
_SECRET_SIG = ("4dabf18193072939515e22adb298388d", "1b47061264138c4ac30d75fd1eb44270")  # pulumi rpc


@dataclass(frozen=True)
class DeclaredResource:
    """One resource a stack program declares (a component when ``custom`` is False)."""

    stack: str  # the layer, e.g. network | compute
    type: str  # the Pulumi type token, e.g. aws:ec2/vpc:Vpc or fogiac:aws:Network
    name: str
    inputs: Mapping[str, Any]
    custom: bool = True
    action: str = "create"

    def to_dict(self) -> dict[str, Any]:
        return {"stack": self.stack, "type": self.type, "name": self.name, "action": self.action,
                "inputs": _thaw(self.inputs)}


@dataclass(frozen=True)
class OfflinePlan:
    plan: Plan
    resources: tuple[DeclaredResource, ...]  # declaration order, first layer first
    outputs: Mapping[str, Mapping[str, Any]]  # per layer, as the mocks resolved them

    def layer(self, stack: str, *, components: bool = False) -> tuple[DeclaredResource, ...]:
        return tuple(r for r in self.resources if r.stack == stack and (components or r.custom))

    def of_type(self, type_: str) -> tuple[DeclaredResource, ...]:
        return tuple(r for r in self.resources if r.type == type_)

    def rows(self) -> tuple[dict[str, Any], ...]:
        """The resources the cloud makes (components left out), as the plan document lists them."""
        return tuple(r.to_dict() for r in self.resources if r.custom)


def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return MappingProxyType({k: _freeze(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


def _thaw(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _thaw(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [_thaw(v) for v in value]
    return value


def redact(value: Any) -> Any:
    """``value`` with Pulumi secrets (and any PEM private key, secret or not) as ``[secret]``,
    keys sorted and whole numbers as ints."""
    if isinstance(value, Mapping):
        if value.get(_SECRET_SIG[0]) == _SECRET_SIG[1]:
            return SECRET
        return {k: redact(value[k]) for k in sorted(value)}
    if isinstance(value, (list, tuple)):
        return [redact(v) for v in value]
    if isinstance(value, str) and _PEM_KEY_MARK in value:
        return SECRET
    if isinstance(value, float) and value.is_integer():
        return int(value)  # the wire format has only floats; ports and sizes read better as ints
    return value


def run_program(
    program: Program,
    *,
    mocks: pulumi.runtime.Mocks,
    project: str,
    stack: str,
    preview: bool,
) -> dict[str, Any]:
    """Run ``program`` to completion under ``mocks`` and return its exports as plain values.

    Each resource reaches ``mocks.new_resource`` once its inputs are known, so dependencies
    register first and the ids and state a mock returns flow into dependants' inputs. The
    mocks are called one at a time, from one worker thread, in an order fixed by the program:
    a mock that creates real resources fails at the same resource every run. Unknown exports
    come back as None.
    """
    pulumi = need("pulumi")
    settings = need("pulumi.runtime.settings")
    run_pulumi_func = need("pulumi.runtime.stack").run_pulumi_func
    sync_await = need("pulumi.runtime.sync_await")

    settings.ROOT.set(None)  # a fresh root stack per run, so runs never share exports
    pulumi.runtime.set_mocks(mocks, project=project, stack=stack, preview=preview)
    settings.SETTINGS.outputs.clear()
    root = settings.get_root_resource()
    exports: dict[str, Any] = {}

    async def collect() -> None:
        for key, value in dict(root.outputs).items():
            exports[key] = await pulumi.Output.from_input(value).future()

    def body() -> Any:
        program()
        return collect()

    # The SDK sends every monitor call through the loop's default executor; one worker
    # serialises them. Restored afterwards (a private attribute: set_default_executor
    # cannot put back "none yet").
    loop = sync_await._ensure_event_loop()
    previous = getattr(loop, "_default_executor", None)
    loop.set_default_executor(_serial_executor())
    try:
        sync_await._sync_await(run_pulumi_func(body))
    finally:
        loop._default_executor = previous
        settings.ROOT.set(None)
        # A failed run's first error (with its traceback, so every future of the run) stays with the SDK
        # until the next run; let it go now, where collecting it costs nothing.
        settings.SETTINGS.rpc_manager.clear()
        settings.SETTINGS.outputs.clear()
    return exports


@functools.lru_cache(maxsize=1)
def _serial_executor() -> concurrent.futures.ThreadPoolExecutor:
    return concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="fogiac-mocks")


@dataclass(frozen=True)
class Placeholders:
    """Mocks' answers for a plan: each resource is its inputs plus ``<name.attr>`` for what only the cloud
    computes (``computed`` by type, ``always`` for every type), its id ``<name.id>``; a function call is
    answered by ``calls[token](args)``, else with nothing."""

    computed: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    always: tuple[str, ...] = ()
    calls: Mapping[str, Callable[[Mapping[str, Any]], dict[str, Any]]] = field(default_factory=dict)

    def new_resource(self, args: Any) -> tuple[str, dict[str, Any]]:  # pulumi.runtime.MockResourceArgs
        state = dict(args.inputs)
        for attr in tuple(self.computed.get(args.typ, ())) + self.always:
            state.setdefault(attr, f"<{args.name}.{attr}>")
        return f"<{args.name}.id>", state

    def call(self, args: Any) -> dict[str, Any]:  # pulumi.runtime.MockCallArgs
        answer = self.calls.get(args.token)
        return answer(args.args) if answer is not None else {}


def recorder(answers: Any, *, on_event: OnEvent | None = None) -> Any:
    """Mocks that record every resource declared (by layer, type and name) and hand each to ``answers``
    (a :class:`Placeholders` or any Pulumi ``Mocks``: a cloud's API answered in-process); with
    ``on_event``, each resource the answers make is a start and a done (or failed) :class:`Progress`."""
    return _recorder_class()(answers, on_event)


@functools.cache
def _recorder_class() -> type:
    sdk = need("pulumi")

    class Recorder(sdk.runtime.Mocks):  # type: ignore[name-defined]
        def __init__(self, answers: Any, on_event: OnEvent | None) -> None:
            self.answers = answers
            self.on_event = on_event
            self.layer = ""
            self.seen: dict[tuple[str, str, str], DeclaredResource] = {}
            self._lock = threading.Lock()

        def new_resource(self, args: Any) -> Any:  # pulumi.runtime.MockResourceArgs
            record = DeclaredResource(stack=self.layer, type=args.typ, name=args.name,
                                      inputs=_freeze(redact(args.inputs)), custom=bool(args.custom))
            with self._lock:
                self.seen[(self.layer, args.typ, args.name)] = record
            if self.on_event is None or not args.custom:
                return self.answers.new_resource(args)
            key = f"{self.layer}::{args.typ}::{args.name}"
            self.on_event(Progress("start", key, args.name, args.typ, "create"))
            try:
                answer = self.answers.new_resource(args)
            except Exception:
                self.on_event(Progress("failed", key))
                raise
            self.on_event(Progress("done", key))
            return answer

        def call(self, args: Any) -> Any:  # pulumi.runtime.MockCallArgs
            return self.answers.call(args)

    return Recorder


def declare(plan: Plan, project: Project, programs: Programs, *, answers: Any) -> OfflinePlan:
    """Run each layer's program for ``plan`` in order under mocks that hand ``answers`` every resource;
    return what was declared, in declaration order, and each layer's outputs (redacted)."""
    pulumi = need("pulumi")
    mocks = recorder(answers)
    order: list[tuple[str, str, str]] = []

    def recording(layer: str, body: Program) -> Program:
        def run() -> None:
            def record(args: Any) -> None:  # pulumi.ResourceTransformationArgs
                order.append((layer, args.type_, args.name))
                return None

            pulumi.runtime.register_stack_transformation(record)
            body()

        return run

    outputs: dict[str, Mapping[str, Any]] = {}
    layers = programs(lambda layer: outputs[layer])
    for layer in project.layers:
        mocks.layer = layer
        outputs[layer] = run_program(recording(layer, layers[layer]), mocks=mocks, project=project.name,
                                     stack=project.stack, preview=True)
    resources = tuple(mocks.seen[key] for key in order if key in mocks.seen)
    return OfflinePlan(
        plan=plan,
        resources=resources,
        outputs=MappingProxyType({k: _freeze(redact(v)) for k, v in outputs.items()}),
    )
