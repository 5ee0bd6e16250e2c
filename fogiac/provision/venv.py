"""The virtual environment fogiac's pushed code runs in on a host: the middleware, and native workload nodes.

Why: a host's system Python has ROS (rospy from Debian's or ROS's packages) but neither
fogiac's own requirements (typer, cryptography, ...: the relay's cloud end imports them), nor
the middleware's (eclipse-zenoh for a ROS 2 host's router), nor the workloads' (numpy, OMPL,
torch). Provisioning builds one virtual environment that sees the
system's packages (``--system-site-packages``) and holds both, named by a digest of the
requirement lines: a second ``up`` with the same lines installs nothing, a changed one builds a
fresh environment and removes the old.

A host that cannot reach a package index (a lab network) gets the wheels from the operator's
machine, as SkyPilot carries its own code: with ``FOGIAC_CARRY_WHEELS=1`` in the operator's
environment, ``pip download`` here fetches every requirement for the host's Python and machine into
a cache named by their digest (``$FOGIAC_STATE_DIR/wheels/<digest>``), provisioning pushes that
folder to the host once (a marker names the digest), and the host installs with ``--no-index``.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import os
import platform
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.manifest.requirements import RequirementsProblem, specifiers
from fogiac.provision import workload
from fogiac.provision.host import Host, q
from fogiac.state import state_root  # the operator's wheel cache, beside the stacks

CARRY_ENV = "FOGIAC_CARRY_WHEELS"
_HAS_VENV = "import ensurepip, venv"
_HOST_PYTHON = "import platform, sys; print('%d.%d' % sys.version_info[:2], platform.machine())"
NO_INDEX_HINT = (f"a host without a package index: set {CARRY_ENV}=1 here and fogiac carries the wheels from "
                 "this machine")  # Debian's python3 has venv but not ensurepip without python3-venv


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
    carried = carry_wheels(host, reqs, python=python, root=root) if reqs and carrying() else None
    source = f"--no-index --find-links {q(carried)} " if carried else ""
    done = host.run(
        f"{{ mkdir -p {q(root)} && find {q(root)} -mindepth 1 -maxdepth 1 ! -name wheels -exec rm -rf {{}} + && "
        f"{q(python)} -m venv --system-site-packages {q(folder)} && "
        f"{q(folder + '/bin/python')} -m pip install --disable-pip-version-check {source}"
        f"{' '.join(q(r) for r in reqs)}; }} >{q(log)} 2>&1", check=False, timeout=3600)
    if not done.ok:
        tail = host.run(f"tail -n 1 {q(log)}", check=False).last_line()
        hint = "" if carried else f" ({NO_INDEX_HINT})"
        raise ProvisionError(f"{host.name}: installing the workloads' requirements failed ({tail}); log: {log}{hint}")
    host.put(f"{digest}\n".encode(), marker, mode=0o600)
    return Venv(python=f"{folder}/bin/python", digest=digest, built=True)


def carrying() -> bool:
    """The operator asked for the wheels to travel from this machine (opt-in)."""
    return os.environ.get(CARRY_ENV, "") == "1"


def _download(reqs: tuple[str, ...], *, version: str, machine: str, into: Path) -> None:
    """``pip download`` of ``reqs`` and their dependencies as wheels for ``version`` on ``machine``."""
    same = version == f"{sys.version_info[0]}.{sys.version_info[1]}" and machine == platform.machine()
    # Wheels only, for this Python too: a source distribution's build (setup.py, a build backend) would run
    # here, on the operator's machine, with the operator's rights.
    target = ["--only-binary=:all:"] + ([] if same else [
        "--implementation", "cp", "--python-version", version,
        *(a for tag in ("manylinux2014", "manylinux_2_28", "manylinux_2_17", "linux")
          for a in ("--platform", f"{tag}_{machine}"))])
    tmp = into.with_name(into.name + ".part")
    shutil.rmtree(tmp, ignore_errors=True)
    done = subprocess.run([sys.executable, "-m", "pip", "download", "--disable-pip-version-check", "-q",
                           "--dest", str(tmp), *target, *reqs], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        shutil.rmtree(tmp, ignore_errors=True)
        last = (done.stderr.strip().splitlines() or ["pip download failed"])[-1]
        raise ProvisionError(f"carrying wheels ({CARRY_ENV}=1): pip download on this machine failed: {last}")
    tmp.rename(into)


def carry_wheels(host: Host, reqs: tuple[str, ...], *, python: str, root: str) -> str:
    """The folder on ``host`` holding wheels for ``reqs``, downloaded here once per digest and pushed once."""
    asked = host.run(f"{q(python)} -c {q(_HOST_PYTHON)}", check=False)
    version, _, machine = asked.stdout.strip().partition(" ")
    if not asked.ok or not version or not machine:
        raise ProvisionError(f"{host.name}: cannot tell {python}'s version and machine to carry wheels for it")
    digest = hashlib.sha256("\n".join((version, machine, *reqs)).encode()).hexdigest()[:16]
    cache = state_root() / "wheels" / digest
    if not cache.is_dir():
        cache.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        _download(reqs, version=version, machine=machine, into=cache)
    remote = f"{root}/wheels/{digest}"
    if host.run(f"cat {q(remote + '/.complete')} 2>/dev/null", check=False).stdout.strip() != digest:
        host.run(f"rm -rf {q(root + '/wheels')} && mkdir -p {q(remote)}")
        for wheel in sorted(cache.iterdir()):
            host.put(wheel.read_bytes(), f"{remote}/{wheel.name}", mode=0o644)
        host.put(f"{digest}\n".encode(), f"{remote}/.complete", mode=0o644)
    return remote
