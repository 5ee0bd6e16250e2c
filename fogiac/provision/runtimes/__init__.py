"""Node runtimes as strategies: ``container`` and ``native``, each one module, chosen once per host.

``choose`` is the one place that reads the manifest's ``cloud.runtime`` (auto, container, native)
against what the host's probe found; everything after asks the chosen :class:`HostRuntime`.
"""

from __future__ import annotations

from fogiac.errors import ProvisionError
from fogiac.plan.model import HostSpec
from fogiac.provision.probe import Facts
from fogiac.provision.runtimes.base import HostRuntime, Run
from fogiac.provision.runtimes.container import CONTAINER
from fogiac.provision.runtimes.native import NATIVE

__all__ = ["CONTAINER", "NATIVE", "HostRuntime", "Run", "choose", "engines"]


# Engines in order of preference: a docker that answers (AWS hosts have one), else podman.
_ENGINES = ("docker", "podman")


def engines(spec: HostSpec) -> tuple[str, ...]:
    """The container engines the host's probe asks about: podman too only where containers are asked for."""
    return _ENGINES if spec.runtime == CONTAINER.name else _ENGINES[:1]


def choose(spec: HostSpec, facts: Facts) -> tuple[HostRuntime, str]:
    """(runtime, engine): ``auto`` keeps containers for hosts where ``docker info`` answers."""
    if spec.runtime == NATIVE.name:
        return NATIVE, ""
    if facts.engines:
        return CONTAINER, facts.engines[0]
    if spec.runtime == CONTAINER.name:
        raise ProvisionError(
            f"{spec.name}: runtime is container but no container engine answers (`docker info` and `podman info` "
            "failed); install one (apt-get install podman runc) or set cloud.runtime: native"
        )
    return NATIVE, ""
