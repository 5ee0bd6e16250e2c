"""The middleware table (entry point group ``fogiac.middlewares``): which middleware a ROS distribution
picks, and the little every layer may ask of it. Neutral on purpose.

Why here and not in ``net/``: validating a manifest needs a middleware's answers (the distributions it
serves, the model of its own top-level block, its rules about the manifest) and the manifest may
import nothing of ``net/``. Each middleware's folder publishes a :class:`MiddlewareEntry`; its facts
half answers :class:`MiddlewareFacts` (``fogiac.net.middleware.Middleware`` is the whole of what it
answers, its deployment half what ``up`` asks). Loading a name imports its facts half only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from fogiac import registry
from fogiac.errors import PlanError
from fogiac.registry import Registry

GROUP = "fogiac.middlewares"


@dataclass(frozen=True)
class MiddlewareEntry:
    """What a middleware publishes under the ``fogiac.middlewares`` entry point group: ``module:attr``
    references into its own folder, its facts half (compile) and its deployment half (up, down,
    provisioning), each loaded when first asked for."""

    name: str
    middleware: str
    deployment: str


class MiddlewareFacts(Protocol):
    """What the manifest asks of a middleware."""

    @property
    def name(self) -> str: ...  # registry key, shown in the plan document

    @property
    def distros(self) -> tuple[str, ...]: ...  # the ROS distributions it serves

    @property
    def block(self) -> type[Any] | None: ...  # the pydantic model of its own top-level manifest key (``name:``)

    def manifest_problems(self, manifest: Any) -> tuple[tuple[str, str], ...]:
        """What this middleware cannot carry in a validated manifest: (message, field path) pairs, which
        the schema reports as its own field problems (the middleware owns its block's rules)."""
        ...


FACTS: Registry[Any] = Registry(GROUP, what="middleware", make=lambda entry: registry.resolve(entry.middleware))
DEPLOYMENTS: Registry[Any] = Registry(GROUP, what="middleware",
                                      make=lambda entry: registry.resolve(entry.deployment))


def names() -> tuple[str, ...]:
    return FACTS.names()


def get(name: str) -> MiddlewareFacts:
    found: MiddlewareFacts = FACTS.get(name)
    return found


def for_distro(distro: str) -> MiddlewareFacts:
    """The middleware that serves ROS ``distro``; an unknown one fails listing those served."""
    served: list[str] = []
    for name in names():
        middleware = get(name)
        if distro in middleware.distros:
            return middleware
        served += middleware.distros
    raise PlanError(f"no middleware serves ROS {distro!r}; served: {', '.join(sorted(served))}")


def distros() -> tuple[str, ...]:
    """Every ROS distribution some middleware serves."""
    return tuple(d for name in names() for d in get(name).distros)


def block_model(key: str) -> type[Any] | None:
    """The model that validates the manifest's top-level ``key`` when an installed middleware of that name
    owns a block (its settings, which reach its deployment as ``Plan.middleware_settings``); else None."""
    return get(key).block if key in names() else None
