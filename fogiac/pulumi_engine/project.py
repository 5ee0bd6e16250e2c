"""What a cloud feeds the engine: its Pulumi project for one fogiac stack and the programs of its layers."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from fogiac.pulumi_engine.errors import EngineError

Program = Callable[[], None]  # declares one layer's resources; run inside a Pulumi program
Earlier = Callable[[str], Mapping[str, Any]]  # an earlier layer's outputs, once that layer has run
# Given how to read earlier layers' outputs, the program of each layer: the one place a cloud wires
# its layers together, whether the outputs come from an applied stack or from mocks.
Programs = Callable[[Earlier], Mapping[str, Program]]


@dataclass(frozen=True)
class Project:
    """One fogiac stack as Pulumi sees it: ``layers`` are Pulumi stacks named ``<stack>-<layer>``, made in
    this order and destroyed in the reverse; ``config`` is set on each (the provider's own keys)."""

    name: str  # the Pulumi project (the cloud's Pulumi.yaml names the same)
    stack: str  # fogiac's stack: <manifest>-<environment>
    layers: tuple[str, ...]
    config: Mapping[str, str] = field(default_factory=dict)

    def layer_stack(self, layer: str) -> str:
        """The Pulumi stack of one layer: ``<manifest>-<environment>-<layer>``."""
        if layer not in self.layers:
            raise EngineError(f"unknown layer {layer!r}; valid: {', '.join(self.layers)}")
        return f"{self.stack}-{layer}"
