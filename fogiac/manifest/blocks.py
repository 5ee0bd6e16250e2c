"""The manifest's blocks other than its nodes: ``ros``, ``cloud`` (with ``hosts`` and ``autostop``),
``network``, ``edge`` and ``relay``."""

from __future__ import annotations

import ipaddress
from typing import Annotated, Literal
from urllib.parse import urlparse

from pydantic import (
    AfterValidator,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from fogiac.manifest.clouds import variant
from fogiac.manifest.fields import (
    _MIN_SUBNET_PREFIX,
    Compression,
    Distro,
    DnsName,
    PlainPath,
    Provider,
    Topic,
    _address,
    _Model,
    _sizing,
    _topic,
    _user,
    ssh_from_problem,
)
from fogiac.manifest.problems import FieldProblem, raise_all


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
    port: int = Field(default=22, ge=1, le=65535, description="SSH port.")
    key: PlainPath = Field(description="Private key file for SSH, relative to the manifest.")
    gpus: int = Field(default=0, ge=0, description="GPUs the machine has.")


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
        if isinstance(value, bool):
            raise ValueError(f"{str(value).lower()} is not a number of minutes")
        return value


class Cloud(_Model):
    provider: Provider = Field(default="aws", description="Where cloud nodes run.")
    region: str = Field(default="us-west-2", description="AWS region (one the price table covers).")
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
    runtime: Literal["auto", "container", "native"] = Field(
        default="auto",
        description="How nodes run on local and hosts machines: in containers (podman, or a docker that answers), "
        "natively, or auto (containers where `docker info` answers).",
    )

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


class Network(_Model):
    mode: Literal["vpn", "proxy"] = Field(
        default="vpn", description="vpn: the edge joins the target's VPN; proxy: relay over TLS to the public address."
    )
    vpc_cidr: ipaddress.IPv4Network = Field(
        default=ipaddress.IPv4Network("10.10.0.0/16"), description="VPC address range (/16 to /26)."
    )
    client_cidr: ipaddress.IPv4Network = Field(
        default=ipaddress.IPv4Network("10.200.0.0/22"),
        description="The edge's VPN address range (the target's VPN sets its limits), outside the VPC.",
    )
    ssh_from: Literal["auto"] | tuple[ipaddress.IPv4Network, ...] = Field(
        default="auto", description="CIDRs allowed to SSH (and, in proxy mode, reach the relay); auto: your address."
    )
    egress_tcp: tuple[int, ...] = Field(
        default=(80, 443), description="TCP ports the hosts may open to the internet (packages, images); "
        "DNS and time use the VPC's resolver and Amazon Time Sync, which security groups do not filter."
    )
    flow_logs: bool = Field(
        default=False, description="VPC flow logs to a CloudWatch log group that goes with the stack (billed per GB)."
    )

    @field_validator("egress_tcp")
    @classmethod
    def _ports(cls, value: tuple[int, ...]) -> tuple[int, ...]:
        for port in value:
            if not 1 <= port <= 65535:
                raise ValueError(f"{port} is not a TCP port (1-65535)")
        return tuple(sorted(set(value)))

    @field_validator("vpc_cidr")
    @classmethod
    def _vpc(cls, value: ipaddress.IPv4Network) -> ipaddress.IPv4Network:
        if not 16 <= value.prefixlen <= _MIN_SUBNET_PREFIX - 1:
            raise ValueError(
                f"{value} must be between /16 and /{_MIN_SUBNET_PREFIX - 1} "
                f"(it holds two subnets of at least /{_MIN_SUBNET_PREFIX})"
            )
        return value

    @field_validator("client_cidr")
    @classmethod
    def _client(cls, value: ipaddress.IPv4Network, info: ValidationInfo) -> ipaddress.IPv4Network:
        _sizing(info).check_edge_vpn_range(str(value), value.prefixlen)  # the target's VPN says what it allows
        return value

    @field_validator("ssh_from")
    @classmethod
    def _no_world(cls, value: object) -> object:
        if isinstance(value, tuple):
            for net in value:
                if net.prefixlen == 0:
                    raise ValueError(f"{net} opens SSH to the whole internet; name your own network")
            problem = ssh_from_problem(value)
            if problem:
                raise ValueError(problem)
        return value

    @model_validator(mode="after")
    def _no_overlap(self) -> Network:
        if self.mode == "vpn" and self.client_cidr.overlaps(self.vpc_cidr):
            raise FieldProblem(
                f"{self.client_cidr} overlaps vpc_cidr {self.vpc_cidr}", field="client_cidr"
            )
        return self


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


class Relay(_Model):
    topics: Literal["auto"] | tuple[Topic, ...] = Field(
        default="auto", description="auto: relay whatever has a publisher on one side and a subscriber on the other."
    )
    compression: Compression | dict[Topic, Compression] = Field(
        default="none", description="One algorithm for all topics, or per topic."
    )
    queue_size: int = Field(default=2, ge=1, le=1000, description="Per-topic queue; the oldest message is dropped.")

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
