"""The beacon as a :class:`fogiac.net.middleware.Middleware`, and its manifest block."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from fogiac.hostmodel import Launching

SERVICE = "beacon"  # the host's service, which nodes start after


class BeaconBlock(BaseModel):
    """The manifest's ``beacon:`` block."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    interval_s: float = Field(default=1.0, description="Seconds between two beats of a host's beacon.")
    greeting: str = Field(default="beat", description="The word each beat carries.")

    @field_validator("interval_s")
    @classmethod
    def _interval(cls, value: float) -> float:
        if not 0.05 <= value <= 60:
            raise ValueError(f"a beacon beats every 0.05 to 60 seconds, not every {value:g}")
        return value

    @field_validator("greeting")
    @classmethod
    def _word(cls, value: str) -> str:
        if not value.isalpha():
            raise ValueError(f"{value!r} is not one word a beacon can shout (letters only)")
        return value


@dataclass(frozen=True)
class BeaconMiddleware:
    name: str = "beacon"
    distros: tuple[str, ...] = ("lighthouse",)
    port: int = 11611
    label: str = "beacon: each host beats, the edge dials out and counts"
    edge_side: str = "beacon listener (dials out)"
    cloud_side: str = "beacon per host"
    rule_description: str = "beacon (plain TCP, tests only)"
    credentials_first: bool = False
    node_master: bool = False  # nothing registers: a node is up while its process runs
    nodes_after: str = SERVICE
    host_requirements: tuple[str, ...] = ()  # the beacon is one file of the standard library
    block: type[Any] | None = BeaconBlock
    launching: Launching = Launching(command=("false",), has_packages="false", tool="true", build="true",
                                     overlay="setup.bash", package_path=False, image_has_tool=True)

    def edge_entry(self, edge: Any) -> str:
        return "beacon listener"  # the beacon has no robot-side graph to reach

    def manifest_problems(self, manifest: Any) -> tuple[tuple[str, str], ...]:
        return ()


BEACON = BeaconMiddleware()
