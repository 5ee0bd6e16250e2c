"""The manifest's blocks other than its nodes: ``ros``, ``cloud`` (with ``hosts`` and ``autostop``),
``network``, ``edge`` and ``relay``.

What a block leaves unsaid is the default provider's ``cloud:`` variant's to fill in (its name, its
region, the keys it adds to ``network:``): this module names no cloud."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Annotated, Literal
from urllib.parse import urlparse

from pydantic import (
    AfterValidator,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from fogiac.manifest.clouds import DEFAULT, default_region, variant
from fogiac.manifest.fields import (
    Compression,
    Distro,
    DnsName,
    PlainPath,
    Provider,
    Secret,
    Topic,
    _address,
    _Model,
    _topic,
    _user,
)
from fogiac.manifest.network import NetworkBlock
from fogiac.manifest.problems import FieldProblem, raise_all


def _not_a_bool(value: object, unit: str) -> object:
    """A YAML ``true``/``false`` where a number of ``unit`` is asked: refused, as pydantic would read it as 1/0."""
    if isinstance(value, bool):
        raise ValueError(f"{str(value).lower()} is not a number of {unit}")
    return value


class Ros(_Model):
    distro: Distro = Field(
        default="noetic",
        description="ROS distribution: noetic (ROS 1, fogiac's relay) or humble, jazzy, kilted (ROS 2, Zenoh).",
    )


class HostMachine(_Model):
    """An existing machine for the ``hosts`` target (a lab GPU server is fog too)."""

    name: DnsName = Field(description="Short DNS-safe name for the machine.")
    address: Annotated[str, AfterValidator(_address)] = Field(description="IP address or DNS name reachable over SSH.")
    user: Annotated[str, AfterValidator(_user)] = Field(default="ubuntu", description="SSH user.")
    port: int = Field(default=22, strict=True, ge=1, le=65535, description="SSH port.")
    key: PlainPath = Field(description="Private key file for SSH, relative to the manifest.")
    gpus: int = Field(default=0, strict=True, ge=0, description="GPUs the machine has.")


class Autostop(_Model):
    """Stop (or terminate) cloud hosts nobody uses: no edge connected and no message for idle_minutes."""

    idle_minutes: float = Field(default=30, ge=0.05, le=10080, allow_inf_nan=False,
                                description="Minutes without an edge and without traffic: 0.05 (3 s, for demos) to "
                                            "10080 (a week).")
    action: Literal["stop", "terminate"] = Field(
        default="stop", description="stop: keep the disk, `up` starts it again; terminate: delete the machine."
    )

    @field_validator("idle_minutes", mode="before")
    @classmethod
    def _minutes(cls, value: object) -> object:
        """YAML's ``true`` would read as 1 minute: a number of minutes is a number."""
        return _not_a_bool(value, "minutes")


class Registry(_Model):
    """A private container registry the hosts log in to before they pull: its password is a secret."""

    server: str = Field(pattern=r"^[A-Za-z0-9]([A-Za-z0-9.-]*[A-Za-z0-9])?(:[0-9]{1,5})?$",
                        description="The registry's host name (and port), e.g. ghcr.io.")
    username: str = Field(pattern=r"^[^\s\x00-\x1f\x7f]{1,256}$", description="The user to log in as.")
    password: Secret = Field(description="The password or token: {secret: env:NAME} or {secret: file:PATH}, read "
                             "at `up` and handed to the engine's login on the host, never recorded.")

    @field_validator("password", mode="before")
    @classmethod
    def _named(cls, value: object) -> object:
        if not isinstance(value, dict):  # the value itself: not repeated in the message (CI logs keep it)
            raise ValueError("a password is never written in the manifest: name where it is read, "
                             "{secret: env:NAME} or {secret: file:PATH}")
        return value


class Cloud(_Model):
    provider: Provider = Field(default=DEFAULT, description="Where cloud nodes run.")
    region: str = Field(default=default_region(), description="The provider's region (one its price table covers).")
    zone: str | None = Field(default=None, description="Availability zone; chosen by preflight if absent.")
    hosts: tuple[HostMachine, ...] = Field(default=(), description="Machines for the hosts target.")
    autostop: Literal["off"] | Autostop | None = Field(
        default=None, description="Idle shutdown; unset: the target's default (aws: 30 idle minutes, stop); off: never."
    )

    @field_validator("autostop", mode="before")
    @classmethod
    def _yaml_off(cls, value: object) -> object:
        """YAML 1.1 reads a bare ``off`` as false: that is the ``off`` the user wrote."""
        return "off" if value is False else value
    registries: tuple[Registry, ...] = Field(
        default=(), description="Private container registries the hosts log in to before pulling images.")
    runtime: Literal["auto", "container", "native"] = Field(
        default="auto",
        description="How nodes run on local and hosts machines: in containers (podman, or a docker that answers), "
        "natively, or auto (containers where `docker info` answers).",
    )
    budget_usd_per_hour: float | None = Field(
        default=None, gt=0, allow_inf_nan=False,
        description="The most the stack may cost an hour at on-demand prices: `up` refuses a plan over it, and one "
        "with a price the catalogue does not know unless `up --accept-unknown-cost`. Unset: no budget.")

    @field_validator("budget_usd_per_hour", mode="before")
    @classmethod
    def _dollars(cls, value: object) -> object:
        """YAML's ``true`` would read as $1: a budget is a number of dollars."""
        return _not_a_bool(value, "dollars")

    @field_validator("region")
    @classmethod
    def _region(cls, value: str, info: ValidationInfo) -> str:
        variant(info.data.get("provider")).check_region(value)  # the provider's own regions and words
        return value

    def chosen(self) -> str | None:
        """The provider, or None while it has a problem (the checks across fields then ask the default's
        variant, whose words every built-in variant shares, rather than skip)."""
        return self.provider if isinstance(self.provider, str) else None

    @model_validator(mode="after")
    def _zone_in_region(self) -> Cloud:
        if self.zone is not None:
            variant(self.chosen()).check_zone(self.zone, self.region)
        names = [h.name for h in self.hosts]
        raise_all([FieldProblem(f"duplicate host name {name!r}", field=f"hosts[{i}].name")
                   for i, name in enumerate(names) if name in names[:i]])
        return self


def network_model() -> type[NetworkBlock]:
    """The model of the ``network:`` block: the default variant's, with the keys it adds (every manifest
    has accepted them, whichever provider it names), else the neutral block."""
    found: type[NetworkBlock] = getattr(variant(), "network", NetworkBlock)
    return found


if TYPE_CHECKING:
    Network = NetworkBlock
else:  # the default provider's model: the neutral block and the keys its variant adds (aws: VPC ranges, flow logs)
    Network = network_model()


class Edge(_Model):
    ros_master: str = Field(
        default="http://localhost:11311", description="The robot's ROS master URI (ROS_MASTER_URI), ROS 1."
    )
    zenoh_router: str = Field(
        default="tcp/127.0.0.1:7447",
        description="ROS 2: where fogiac's edge router listens for the robot's rmw_zenoh nodes (loopback).",
    )

    @field_validator("ros_master")
    @classmethod
    def _uri(cls, value: str) -> str:
        url = urlparse(value)
        printable = value.isprintable() and value.strip() == value  # no line break or escape reaches a command line
        if not printable or url.scheme != "http" or not url.hostname or url.port is None:
            raise ValueError(f"{value!r} is not a ROS master URI like 'http://localhost:11311'")
        return value

    @field_validator("zenoh_router")
    @classmethod
    def _endpoint(cls, value: str) -> str:
        proto, _, rest = value.partition("/")
        host, _, port = rest.rpartition(":")
        if proto != "tcp" or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"{value!r} is not a Zenoh endpoint like 'tcp/127.0.0.1:7447'")
        return value


_ROBOT_NAME = re.compile(r"^[a-z][a-z0-9]{0,30}$")


def _robot_name(value: str) -> str:
    """A robot's name is its ROS namespace (``/<robot>/...``: no '-') and a DNS label in its certificate's
    name (no '_'): so lowercase letters and digits only."""
    if not _ROBOT_NAME.match(value):
        raise ValueError(f"{value!r} is not a robot name: a lowercase letter, then lowercase letters and digits "
                         "(up to 31), since it is both the robot's ROS namespace and a DNS label")
    return value


class Robot(Edge):
    """One robot of a fleet: its name (its namespace and its certificate), where its graph is reached, and what
    the middleware does differently for it."""

    name: Annotated[str, AfterValidator(_robot_name)] = Field(
        description="The robot's name: its topics' namespace (/<name>/...) and its certificate's identity.")
    compression: Compression | None = Field(
        default=None, description="Relay: this robot's compression for every topic (default: relay.compression).")


class Relay(_Model):
    topics: Literal["auto"] | tuple[Topic, ...] = Field(
        default="auto", description="auto: relay whatever has a publisher on one side and a subscriber on the other."
    )
    compression: Compression | dict[Topic, Compression] = Field(
        default="none", description="One algorithm for all topics, or per topic."
    )
    queue_size: int = Field(default=2, strict=True, ge=1, le=1000,
                            description="Per-topic queue; the oldest message is dropped.")

    @field_validator("topics")
    @classmethod
    def _topics(cls, value: object) -> object:
        return tuple(_topic(t) for t in value) if isinstance(value, tuple) else value

    @field_validator("compression")
    @classmethod
    def _per_topic(cls, value: object) -> object:
        if isinstance(value, dict):
            for topic in value:
                _topic(topic)
        return value
