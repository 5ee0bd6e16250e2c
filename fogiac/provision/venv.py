"""The virtual environment fogiac's pushed code runs in on a host: the middleware, and native workload nodes.

Why: a host's system Python has ROS (rospy from Debian's or ROS's packages) but neither
fogiac's own requirements (typer, cryptography, ...: the relay's cloud end imports them), nor
the middleware's (eclipse-zenoh for a ROS 2 host's router), nor the workloads' (numpy, OMPL,
torch). Provisioning builds one virtual environment that sees the
system's packages (``--system-site-packages``) and holds both, named by a digest of the
requirement lines: a second ``up`` with the same lines installs nothing, a changed one builds a
fresh environment and removes the old.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import re
from dataclasses import dataclass
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.manifest.requirements import RequirementsProblem, specifiers
from fogiac.provision import workload
from fogiac.provision.host import Host, q

_HAS_VENV = "import ensurepip, venv"  # Debian's python3 has venv but not ensurepip without python3-venv


@dataclass(frozen=True)
class Venv:
    python: str  # the environment's interpreter on the host
    digest: str
    built: bool


def fogiac_requirements() -> tuple[str, ...]:
    """fogiac's own runtime requirements (no extras), as its installed metadata declares them."""
    try:
        declared = importlib.metadata.requires("fogiac") or []
    except importlib.metadata.PackageNotFoundError:
        raise ProvisionError("fogiac is not installed (pip install fogiac): its requirements for the host's "
                             "relay are read from the installed package") from None
    return tuple(re.sub(r"\s+", "", r) for r in declared if "extra ==" not in r)


def requirements(workloads: list[str], *, fogiac: bool = False, middleware: tuple[str, ...] = ()) -> tuple[str, ...]:
    """Every requirement of ``workloads`` (after fogiac's own, if asked, and the middleware's), each once,
    in a stable order."""
    found: list[str] = list(fogiac_requirements()) if fogiac else []
    found += [r for r in middleware if r not in found]
    for name in sorted(set(workloads)):
        for req in workload.recipe(name).requirements():
            if req not in found:
                found.append(req)
    return tuple(found)


def file_requirements(path: str) -> tuple[str, ...]:
    """The requirement lines of a launch package's requirements file (``manifest.requirements``)."""
    try:
        return specifiers(Path(path).read_text(), where=path)
    except OSError as err:
        raise ProvisionError(f"{path}: cannot read the requirements file ({err.strerror})") from None
    except RequirementsProblem as err:
        raise ProvisionError(str(err)) from None


def pins_digest(reqs: tuple[str, ...], python: str) -> str:
    return hashlib.sha256("\n".join((python, *reqs)).encode()).hexdigest()


def ensure(host: Host, *, root: str, marker: str, known: str, reqs: tuple[str, ...], python: str,
           allow_install: bool, log: str) -> Venv:
    """Make ``root/<digest>`` hold ``reqs`` over ``python``'s system packages; ``known`` is the marker's content."""
    digest = pins_digest(reqs, python)
    folder = f"{root}/{digest[:16]}"
    if known == digest:
        return Venv(python=f"{folder}/bin/python", digest=digest, built=False)
    if not host.run(f"{q(python)} -c {q(_HAS_VENV)}", check=False).ok:
        if not allow_install:
            raise ProvisionError(f"{host.name}: {python} cannot make virtual environments (python3-venv is missing); "
                                 "run: sudo apt-get install -y python3-venv")
        host.sudo("env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv", timeout=900)
    done = host.run(
        f"{{ mkdir -p {q(root)} && find {q(root)} -mindepth 1 -maxdepth 1 -exec rm -rf {{}} + && "
        f"{q(python)} -m venv --system-site-packages {q(folder)} && "
        f"{q(folder + '/bin/python')} -m pip install --disable-pip-version-check {' '.join(q(r) for r in reqs)}; "
        f"}} >{q(log)} 2>&1", check=False, timeout=3600)
    if not done.ok:
        tail = host.run(f"tail -n 1 {q(log)}", check=False).last_line()
        raise ProvisionError(f"{host.name}: installing the workloads' requirements failed ({tail}); log: {log}")
    host.put(f"{digest}\n".encode(), marker, mode=0o600)
    return Venv(python=f"{folder}/bin/python", digest=digest, built=True)
