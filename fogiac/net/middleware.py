"""Middleware: how ROS traffic crosses between the robot and the cloud hosts, one registry.

::

    relay/   ROS 1 (noetic): fogiac's relay, TCPROS bytes over one mutual-TLS link the edge opens
    zenoh/   ROS 2 (humble, jazzy, kilted): a Zenoh router per cloud host (mutual TLS, per-topic
             access control) and an edge router that dials out to them

The ROS distribution picks the middleware (:func:`for_distro`). A variant is one
:class:`Middleware` in its own folder, listed in :data:`BUILTIN`; nothing else in fogiac names it,
so compile, the targets' firewalls, plan, cost and graph ask it for its port and its words.
"""

from __future__ import annotations

import importlib
from typing import Protocol

from fogiac.errors import PlanError


class Middleware(Protocol):
    """What the rest of fogiac may know about a middleware."""

    @property
    def name(self) -> str: ...  # registry key, shown in the plan document

    @property
    def distros(self) -> tuple[str, ...]: ...  # the ROS distributions it serves

    @property
    def port(self) -> int: ...  # the TCP port the edge dials on each cloud host

    @property
    def label(self) -> str: ...  # one line for plan, cost and graph: what crosses and how

    @property
    def edge_side(self) -> str: ...  # what runs on the robot's side

    @property
    def cloud_side(self) -> str: ...  # what runs on each cloud host

    @property
    def rule_description(self) -> str: ...  # the security-group rule's description for ``port``

    @property
    def needs_listed_topics(self) -> bool: ...  # True: topics "auto" cannot be honoured


# The built-in middlewares, imported when first asked for.
BUILTIN: dict[str, str] = {"relay": "fogiac.net.relay.middleware:RELAY", "zenoh": "fogiac.net.zenoh.middleware:ZENOH"}
_REGISTRY: dict[str, Middleware] = {}


def register(middleware: Middleware) -> Middleware:
    _REGISTRY[middleware.name] = middleware
    return middleware


def get(name: str) -> Middleware:
    found = _REGISTRY.get(name)
    if found is None and name in BUILTIN:
        module, attr = BUILTIN[name].split(":")
        found = register(getattr(importlib.import_module(module), attr))
    if found is None:
        raise PlanError(f"unknown middleware {name!r}; valid: {', '.join(sorted(set(_REGISTRY) | set(BUILTIN)))}")
    return found


def for_distro(distro: str) -> Middleware:
    """The middleware that serves ROS ``distro``; an unknown one fails listing those served."""
    served: list[str] = []
    for name in sorted(set(_REGISTRY) | set(BUILTIN)):
        middleware = get(name)
        if distro in middleware.distros:
            return middleware
        served += middleware.distros
    raise PlanError(f"no middleware serves ROS {distro!r}; served: {', '.join(sorted(served))}")


def distros() -> tuple[str, ...]:
    """Every ROS distribution some built-in middleware serves."""
    return tuple(d for name in sorted(BUILTIN) for d in get(name).distros)
