"""A Pulumi Mocks that keeps every resource's raw inputs (secrets still wrapped) and options."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import pulumi

from fogiac.pulumi_engine.offline import run_program


class Recorder(pulumi.runtime.Mocks):
    def __init__(self) -> None:
        self.inputs: dict[str, dict[str, Any]] = {}
        self.types: dict[str, str] = {}
        self.options: dict[str, pulumi.ResourceOptions] = {}
        self.calls: list[tuple[str, dict[str, Any]]] = []
        self._lock = threading.Lock()

    def new_resource(self, args: pulumi.runtime.MockResourceArgs) -> tuple[str, dict]:
        with self._lock:
            self.inputs[args.name] = args.inputs
            self.types[args.name] = args.typ
        state = dict(args.inputs)
        if args.typ == "pulumi:pulumi:StackReference":
            state = {"name": args.inputs.get("name"), "outputs": self.stack_outputs, "secretOutputNames": []}
        state.setdefault("arn", f"arn:aws:test:::{args.name}")
        state.setdefault("dnsName", f"*.{args.name}.example")
        state.setdefault("publicIp", "203.0.113.10")
        state.setdefault("privateIp", "10.10.0.10")
        return f"id-{args.name}", state

    def call(self, args: pulumi.runtime.MockCallArgs) -> dict:  # type: ignore[override]
        with self._lock:
            self.calls.append((args.token, args.args))
        if args.token == "aws:index/getCallerIdentity:getCallerIdentity":
            return {"id": "123456789012", "accountId": "123456789012", "arn": "arn:aws:iam::123456789012:user/ci",
                    "userId": "AIDA"}
        return {"id": f"ami-{len(self.calls)}"}

    stack_outputs: dict[str, Any] = {}

    def run(self, program: Callable[[], None], *, stack: str = "test-dev") -> dict[str, Any]:
        def recording() -> None:
            def record(args: pulumi.ResourceTransformationArgs) -> None:
                self.options[args.name] = args.opts
                return None

            pulumi.runtime.register_stack_transformation(record)
            program()

        return run_program(recording, mocks=self, project="fogiac", stack=stack, preview=False)


def is_secret(value: Any) -> bool:
    return isinstance(value, dict) and value.get("4dabf18193072939515e22adb298388d") == "1b47061264138c4ac30d75fd1eb44270"
