"""Where the ``local`` target puts a manifest's nodes: one sandbox per node (per replica of a
replicated node), on loopback.

The host is this machine, so ``cloud.runtime: auto`` is decided here, at plan time, for a manifest
with image (or build) nodes: docker if ``docker info`` answers, else podman if ``podman info`` does
(the host runs containers: runtime ``container``), else the plan is refused in one line. Before,
auto asked docker alone at ``up``, fell back to native and failed there with a partial stack.
"""

from __future__ import annotations

import functools
import shutil
import subprocess
from typing import Literal

from fogiac.errors import FogiacError
from fogiac.manifest.schema import Manifest
from fogiac.plan.placement import Placement, Tags, autostop_for, host_per_node, replica_groups

ENGINES = ("docker", "podman")  # the order provisioning prefers them in


@functools.cache
def answering_engine() -> str | None:
    """The first container engine whose ``info`` answers on this machine (asked once per process)."""
    for engine in ENGINES:
        path = shutil.which(engine)
        if path is None:
            continue
        try:
            if subprocess.run([path, "info"], capture_output=True, timeout=30, check=False).returncode == 0:
                return engine
        except (OSError, subprocess.TimeoutExpired):
            continue
    return None


def _runtime(manifest: Manifest) -> Literal["auto", "container", "native"]:
    runtime = manifest.cloud.runtime
    images = [n for n in manifest.nodes if n.kind == "image"]
    if runtime == "native" or not images:
        return runtime
    engine = answering_engine()
    if engine is None:
        node = images[0]
        raise FogiacError(
            f"node {node.name} runs a container image, but no container engine answers on this machine "
            "(`docker info` and `podman info` failed): install one (apt-get install podman runc; cloud.runtime: "
            "container then uses it), or make the node a launch, workload or command node")
    return "container" if engine != ENGINES[0] else runtime  # podman: only runtime container asks for it


def place(manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
    hosts, node_hosts = host_per_node(manifest, stack=stack, tags=tags, address="127.0.0.1",
                                      runtime=_runtime(manifest))
    return Placement(hosts=hosts, node_hosts=node_hosts, mode="relay", connect_via="loopback",
                     autostop=autostop_for(manifest, power="services", default_minutes=None),
                     replica_hosts=replica_groups(manifest))
