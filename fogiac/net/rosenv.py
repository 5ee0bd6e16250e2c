"""The ROS 1 environment of one side (edge or a cloud host): master URI and own address.

Why: every ROS 1 node advertises an address that its peers dial back, so each side must say
which master it uses and which address it is reachable at (``ROS_IP`` for an address,
``ROS_HOSTNAME`` for a name). Shell scripts and service units source the rendered ``env.sh``;
Python callers take the same values as a dict, so both always agree.
"""

from __future__ import annotations

import ipaddress
import re
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from urllib.parse import urlsplit

from fogiac.render import render

_HOST_RE = re.compile(r"^(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9.-]*[A-Za-z0-9])?$")


@dataclass(frozen=True)
class RosEnv:
    """``env`` to pass to a process, ``text`` to write as ``env.sh``."""

    env: Mapping[str, str]
    text: str


def _check_master_uri(uri: str) -> str:
    parts = urlsplit(uri)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "http" or not parts.hostname or port is None or parts.path not in ("", "/"):
        raise ValueError(f"ROS master URI {uri!r} is not of the form http://HOST:PORT/")
    return uri


def _address_kind(address: str) -> str:
    try:
        ipaddress.ip_address(address)
    except ValueError:
        if not _HOST_RE.match(address):
            raise ValueError(f"{address!r} is neither an IP address nor a host name") from None
        return "ROS_HOSTNAME"
    return "ROS_IP"


def side_env(*, side: str, master_uri: str, address: str) -> RosEnv:
    """The environment of ``side``: its master, and ``address`` as ROS_IP or ROS_HOSTNAME.

    Inputs come from a compiled Plan, so a malformed one is a bug: ValueError, not a user error.
    """
    _check_master_uri(master_uri)
    key = _address_kind(address)
    env = {"ROS_MASTER_URI": master_uri, key: address}
    text = render(
        "ros/env.sh.j2", side=side, master_uri=master_uri,
        ros_ip=address if key == "ROS_IP" else "", ros_hostname=address if key == "ROS_HOSTNAME" else "",
    )
    return RosEnv(env=MappingProxyType(env), text=text)
