"""Container images a host builds for its nodes: the shipped workloads' recipes and users' ``build:`` folders.

Why on the host: no registry stands between this machine and the hosts, and the host's engine
keeps the layers. Each image is tagged by a digest of what goes into it (the Dockerfile, every
file of the context, the base image's id), so an unchanged node builds nothing and a changed
file rebuilds that node's image only, as ``docker compose build`` would.

A lab's hosts often reach no public index: their admins point pip at a mirror in the login
environment (``PIP_INDEX_URL`` and friends). The build's pip steps read the same settings from a
pip config file mounted as a build secret (``--secret id=pip.conf``), so an image installs from
the mirror the host's own pip uses. A secret, not build arguments: an argument's value is kept in
the image's history (a mirror URL's credentials with it) and is part of every layer's cache key
(a moved mirror reinstalls torch). They are not part of the digest either: a mirror serves the
same pins. Users' own ``build:`` Dockerfiles get the same secret, and, as before, the settings as
build arguments for the ``ARG`` lines they may declare.
"""

from __future__ import annotations

import hashlib
import re
import shutil
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.plan.model import NodeSpec, Plan
from fogiac.provision import venv, workload
from fogiac.provision.host import Host, q
from fogiac.provision.sync import push_tree
from fogiac.render import render
from fogiac.resources import package_dir

_BUILD_LOG_LINES = ("STEP ", "#")  # podman/buildah prints "STEP 3/7: RUN ...", BuildKit "#5 [3/7] RUN ..."
# The host's pip settings a build passes on, and their names in a pip config file.
PIP_CONFIG_KEYS = {"PIP_INDEX_URL": "index-url", "PIP_EXTRA_INDEX_URL": "extra-index-url",
                   "PIP_FIND_LINKS": "find-links", "PIP_NO_INDEX": "no-index", "PIP_TRUSTED_HOST": "trusted-host"}
PIP_SETTINGS = tuple(PIP_CONFIG_KEYS)
PIP_SECRET = "pip.conf"  # the build secret's id; the shipped recipes' pip steps mount it (RUN --mount=type=secret)


@dataclass(frozen=True)
class Recipe:
    """What one node's image is built from: a local context folder and a Dockerfile inside it."""

    node: str
    repo: str  # the image name without its tag
    context: Path
    dockerfile: str


@dataclass(frozen=True)
class Built:
    node: str
    tag: str
    built: bool  # False: an image with this digest was there already


def base_image(plan: Plan) -> str:
    return f"ros:{plan.ros_distro}-ros-core"


def workload_repo(workload: str) -> str:
    return f"fogiac/{workload}"


def needs_image(node: NodeSpec) -> bool:
    """Workload and ``build:`` nodes run their own image; so does a launch node whose package names requirements."""
    launch_reqs = node.launch is not None and node.launch.requirements is not None
    return node.kind == "workload" or node.build is not None or launch_reqs


def workload_context(node: NodeSpec, *, flavour: str, into: Path) -> Recipe:
    """Lay out a workload's build context under ``into``: fogiac/, workloads/<name>/ and its Dockerfile."""
    name = node.workload or ""
    container = workload.recipe(name)
    overrides = container.FLAVOURS.get(flavour, {})
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "tests")
    dockerfile = container.dockerfile(**overrides)
    fogiac = package_dir("fogiac")
    for part in fogiac_copied(dockerfile):  # only what the recipe takes: the digest then moves with that alone
        if part == "":
            shutil.copytree(fogiac, into / "fogiac", ignore=ignore)
        else:
            (into / "fogiac" / part).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(fogiac / part, into / "fogiac" / part)
    workloads = package_dir("workloads")
    (into / "workloads").mkdir()
    shutil.copy2(workloads / "__init__.py", into / "workloads" / "__init__.py")
    shutil.copytree(workloads / name, into / "workloads" / name, ignore=ignore)
    (into / "Dockerfile").write_text(dockerfile)
    return Recipe(node=node.name, repo=workload_repo(name), context=into, dockerfile="Dockerfile")


def fogiac_copied(dockerfile: str) -> list[str]:
    """The parts of fogiac a workload recipe's ``COPY`` lines take, relative to the package ("" for all of it).

    Why: the image's tag is a digest of its whole build context, so a context holding all of fogiac would
    rebuild a recipe that takes two of its files (the grasp planner's, SLAM's) on every upgrade of fogiac,
    and push the whole package to each host for nothing."""
    parts: list[str] = []
    for line in dockerfile.splitlines():
        words = line.split()
        if len(words) < 3 or words[0].upper() != "COPY":
            continue
        for source in words[1:-1]:
            if source.rstrip("/") == "fogiac":
                return [""]
            if source.startswith("fogiac/"):
                parts.append(source.removeprefix("fogiac/"))
    return parts


def launch_context(node: NodeSpec, *, plan: Plan, into: Path, base: str = "") -> Recipe:
    """A launch node's image: the ROS image (``base``, else the plan's) plus its package's requirements
    (the workspace is mounted, as without)."""
    assert node.launch is not None and node.launch.requirements is not None
    into.mkdir(parents=True)
    lines = venv.file_requirements(node.launch.requirements)
    (into / "requirements.txt").write_text("".join(f"{line}\n" for line in lines))
    dockerfile = render("provision/launch_image.Dockerfile.j2", base_image=base or base_image(plan))
    (into / "Dockerfile").write_text(dockerfile)
    return Recipe(node=node.name, repo=f"fogiac/{plan.stack}-{node.name}", context=into, dockerfile="Dockerfile")


def user_context(node: NodeSpec, *, stack: str) -> Recipe:
    assert node.build is not None
    return Recipe(node=node.name, repo=f"fogiac/{stack}-{node.name}", context=Path(node.build.context),
                  dockerfile=node.build.dockerfile)


def pip_config(settings: Mapping[str, str]) -> str:
    """The host's pip settings as a pip config file (what pip itself reads from ``PIP_CONFIG_FILE``).
    A value with a line break is left out: it could not be one setting's value."""
    lines = [f"{PIP_CONFIG_KEYS[key]} = {value}" for key, value in sorted(settings.items())
             if key in PIP_CONFIG_KEYS and "\n" not in value and "\r" not in value]
    return "\n".join(["[global]", *lines]) + "\n"


def build(host: Host, recipe: Recipe, *, engine: str, base_id: str, dest: str, tmp_dir: str, log: str,
          pip: Mapping[str, str] | None = None, user: bool = False) -> Built:
    """Push the context, then build it unless an image tagged with its digest is there already.

    ``pip``: the host's pip settings, given to the build as the ``pip.conf`` secret (and, for a user's own
    Dockerfile, ``user``, as build arguments too); they do not change the digest.
    """
    pushed = push_tree(host, recipe.context, dest, tmp_dir=tmp_dir)
    digest = hashlib.sha256(f"{pushed.digest}\n{recipe.dockerfile}\n{base_id}\n".encode()).hexdigest()
    tag = f"{recipe.repo}:{digest[:16]}"
    if host.run(f"{engine} image inspect {q(tag)} >/dev/null 2>&1", check=False).ok:
        return Built(node=recipe.node, tag=tag, built=False)
    args, secret = "", ""
    if pip:
        secret = f"{tmp_dir}/{recipe.node}.{PIP_SECRET}"
        host.put(pip_config(pip).encode(), secret, mode=0o600)
        args = f" --secret id={PIP_SECRET},src={q(secret)}"
        if user:
            args += "".join(f" --build-arg {q(f'{key}={value}')}" for key, value in sorted(pip.items()))
    try:
        done = host.run(f"{engine} build --network host{args} -t {q(tag)} -f {q(dest + '/' + recipe.dockerfile)} "
                        f"{q(dest)} >{q(log)} 2>&1", check=False, timeout=3600)
    finally:
        if secret:
            host.run(f"rm -f {q(secret)}", check=False)
    if not done.ok:
        step = last_step(host.run(f"tail -n 400 {q(log)}", check=False).stdout)
        raise ProvisionError(f"{host.name}: node {recipe.node}: image build failed at {step}; log: {log}")
    # Older digests of this image go, unless a container still runs on one (rmi refuses then).
    host.run(f"for t in $({engine} images --format '{{{{.Repository}}}}:{{{{.Tag}}}}' {q(recipe.repo)}); do "
             f"case $t in *:{digest[:16]}) ;; *) {engine} rmi $t >/dev/null 2>&1 ;; esac; done", check=False)
    return Built(node=recipe.node, tag=tag, built=True)


def last_step(log: str) -> str:
    """The build step that was running when the build stopped, from the engine's own output."""
    steps = [line.strip() for line in log.splitlines() if line.startswith(_BUILD_LOG_LINES)]
    if not steps:
        return "the start (no step ran)"
    return re.sub(r"\s+", " ", steps[-1])[:160]
