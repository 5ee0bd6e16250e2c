"""Offline plan: run the stack programs under Pulumi mocks and record what they declare.

No credentials, no Pulumi CLI, no files written: ``fogiac plan`` shows the exact resources a
manifest implies, with the inputs pulumi_aws would send. Values that only exist at ``up`` (ids,
the operator's address, certificates, the SSH key) appear as ``<...>`` placeholders, and every
secret as ``[secret]``. pulumi is imported inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import concurrent.futures
import functools
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from fogiac.certs import Bundle, KeyPair
from fogiac.plan.model import OPERATOR_PLACEHOLDER, Plan
from fogiac.targets.aws.sdk import need
from stacks import LAYERS, PROJECT

if TYPE_CHECKING:
    import pulumi.runtime

SECRET = "[secret]"
_PEM_KEY_MARK = "PRIVATE KEY-----"
_SECRET_SIG = ("4dabf18193072939515e22adb298388d", "1b47061264138c4ac30d75fd1eb44270")  # pulumi rpc


@dataclass(frozen=True)
class DeclaredResource:
    """One resource a stack program declares (a component when ``custom`` is False)."""

    stack: str  # layer: network | compute
    type: str  # e.g. aws:ec2/vpc:Vpc or fogiac:aws:Network
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
    resources: tuple[DeclaredResource, ...]  # declaration order, network stack first
    outputs: Mapping[str, Mapping[str, Any]]  # per layer, as the mocks resolved them

    def layer(self, stack: str, *, components: bool = False) -> tuple[DeclaredResource, ...]:
        return tuple(r for r in self.resources if r.stack == stack and (components or r.custom))

    def of_type(self, type_: str) -> tuple[DeclaredResource, ...]:
        return tuple(r for r in self.resources if r.type == type_)


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


def offline_bundle(stack: str) -> Bundle:
    """Stand-ins for the stack's certificates: a plan must neither write nor show real keys.

    Generating three RSA 2048 keys would cost more than the rest of a plan, and their bodies
    would change on every run; the certificates are made (once, persisted) at ``up``.
    """

    def pair(role: str) -> KeyPair:
        return KeyPair(f"<{role} certificate of {stack}, made at up>".encode(), f"<{role} key>".encode())

    return Bundle(ca=pair("CA"), vpn=pair("VPN endpoint"), client=pair("client"))


def offline_public_key(stack: str) -> str:
    return f"<ssh-ed25519 public key of {stack}, made at up>"


def run_program(
    program: Callable[[], None],
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
    return exports


@functools.lru_cache(maxsize=1)
def _serial_executor() -> concurrent.futures.ThreadPoolExecutor:
    return concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="fogiac-mocks")


def _mock_class() -> type:
    sdk = need("pulumi")

    class PlanMocks(sdk.runtime.Mocks):  # type: ignore[name-defined]
        """Answers every resource with ``<name.attr>`` placeholders and records its inputs."""

        def __init__(self) -> None:
            self.layer = "network"
            self.seen: dict[tuple[str, str, str], DeclaredResource] = {}
            self._lock = threading.Lock()

        def new_resource(self, args: Any) -> tuple[str, dict]:  # pulumi.runtime.MockResourceArgs
            record = DeclaredResource(
                stack=self.layer,
                type=args.typ,
                name=args.name,
                inputs=_freeze(redact(args.inputs)),
                custom=bool(args.custom),
            )
            with self._lock:
                self.seen[(self.layer, args.typ, args.name)] = record
            state = dict(args.inputs)
            for attr in _COMPUTED.get(args.typ, ()) + ("arn",):
                state.setdefault(attr, f"<{args.name}.{attr}>")
            return f"<{args.name}.id>", state

        def call(self, args: Any) -> dict:  # pulumi.runtime.MockCallArgs
            if args.token == "aws:ec2/getAmi:getAmi":
                pattern = next((f["values"][0] for f in args.args.get("filters", []) if f["name"] == "name"), "?")
                ami = f"<newest AMI named {pattern!r} by {','.join(args.args.get('owners', []))}>"
                return {"id": ami, "imageId": ami, "name": pattern, "architecture": "x86_64"}
            return {}

    return PlanMocks


# Attributes AWS computes that the programs read or export.
_COMPUTED: dict[str, tuple[str, ...]] = {
    "aws:ec2/instance:Instance": ("publicIp", "privateIp", "publicDns"),
    "aws:ec2clientvpn/endpoint:Endpoint": ("dnsName",),
}


def declare(plan: Plan, *, mocks: Any | None = None) -> OfflinePlan:
    """Run the network then the compute program for ``plan`` under mocks; a plan without a
    cloud network (another target's) declares nothing."""
    if plan.network is None:
        return OfflinePlan(plan=plan, resources=(), outputs=MappingProxyType({}))
    pulumi = need("pulumi")
    program = need("stacks.program")

    mocks = mocks if mocks is not None else _mock_class()()
    order: list[tuple[str, str, str]] = []

    def recording(layer: str, body: Callable[[], None]) -> Callable[[], None]:
        def run() -> None:
            def record(args: Any) -> None:  # pulumi.ResourceTransformationArgs
                order.append((layer, args.type_, args.name))
                return None

            pulumi.runtime.register_stack_transformation(record)
            body()

        return run

    outputs: dict[str, Mapping[str, Any]] = {}
    programs = program.layer_programs(
        plan, certs=offline_bundle(plan.stack), operator_cidrs=(OPERATOR_PLACEHOLDER,),  # stands in for ssh_from: auto
        public_key_openssh=offline_public_key(plan.stack), network_outputs=lambda: outputs["network"])
    for layer in LAYERS:
        if hasattr(mocks, "layer"):
            mocks.layer = layer
        outputs[layer] = run_program(recording(layer, programs[layer]), mocks=mocks, project=PROJECT,
                                     stack=plan.stack, preview=True)
    seen: Mapping[tuple[str, str, str], DeclaredResource] = getattr(mocks, "seen", {})
    resources = tuple(seen[key] for key in order if key in seen)
    return OfflinePlan(
        plan=plan,
        resources=resources,
        outputs=MappingProxyType({k: _freeze(redact(v)) for k, v in outputs.items()}),
    )
