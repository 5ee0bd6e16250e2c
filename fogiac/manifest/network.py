"""The manifest's ``network:`` block as every target reads it: how the edge reaches the hosts, who may
reach them, and which ports they may open to the internet.

A target's ``cloud:`` variant may add keys of its own (the aws target's VPC and VPN address ranges,
its flow logs) by publishing a subclass as its ``network`` attribute; the manifest's ``network:``
is the default provider's model (:func:`fogiac.manifest.clouds.network_model`), so the keys users
write stay where they are while their meaning and checks live with the target.
"""

from __future__ import annotations

import ipaddress
from typing import Literal

from pydantic import Field, field_validator

from fogiac.manifest.fields import _Model, ssh_from_problem

EGRESS_TCP = "TCP ports the hosts may open to the internet (packages, images)"


class NetworkBlock(_Model):
    mode: Literal["vpn", "proxy"] = Field(
        default="vpn", description="vpn: the edge joins the target's VPN; proxy: relay over TLS to the public address."
    )
    ssh_from: Literal["auto"] | tuple[ipaddress.IPv4Network, ...] = Field(
        default="auto", description="CIDRs allowed to SSH (and, in proxy mode, reach the relay); auto: your address."
    )
    egress_tcp: tuple[int, ...] = Field(default=(80, 443), description=EGRESS_TCP + ".")

    @field_validator("egress_tcp")
    @classmethod
    def _ports(cls, value: tuple[int, ...]) -> tuple[int, ...]:
        for port in value:
            if not 1 <= port <= 65535:
                raise ValueError(f"{port} is not a TCP port (1-65535)")
        return tuple(sorted(set(value)))

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
