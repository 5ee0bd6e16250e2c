"""The probe's "init" fact: whether the host's container engine can run a node under an init (`run --init`).

Podman runs catatonit from its ``init_path``, a package of its own (Debian's podman only recommends it); without
it ``run --init`` fails, so the probe says init only where the file is there, and the node's line then goes
without it, as before. Checked against the real podman, pointed at its settings by ``CONTAINERS_CONF``."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision.local import LocalAccess
from fogiac.provision.probe import gather
from fogiac.provision.steps import HostRun, Options
from tests.conftest import EXAMPLES

pytestmark = pytest.mark.skipif(shutil.which("podman") is None, reason="needs podman (apt-get install podman runc)")


def _run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, init_path: Path) -> HostRun:
    conf = tmp_path / "containers.conf"
    conf.write_text(f'[engine]\n# init_path = "/not/this/one"\ninit_path = "{init_path}"\n')
    monkeypatch.setenv("CONTAINERS_CONF", str(conf))
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"))
    spec = plan.hosts[0]
    access = LocalAccess(sandbox=tmp_path / "host")
    host = access.open(name=spec.name, known_hosts=tmp_path / "known_hosts", stack=plan.stack)
    host.connect()
    run = HostRun(plan=plan, spec=spec, access=access, host=host, options=Options())
    run.facts = gather(host, run.layout, link_program="", engines=("podman",))
    run.engine = "podman" if "podman" in run.facts.engines else ""
    return run


def test_podman_with_its_init_runs_nodes_under_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    init = tmp_path / "catatonit"
    init.write_text("#!/bin/sh\n")
    init.chmod(0o755)
    run = _run(tmp_path, monkeypatch, init)
    assert run.facts is not None and "podman" in run.facts.engines and run.facts.inits == {"podman"}
    assert run.where().init


def test_podman_without_its_init_runs_nodes_as_before(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run = _run(tmp_path, monkeypatch, tmp_path / "no-catatonit")
    assert run.facts is not None and "podman" in run.facts.engines and run.facts.inits == set()
    assert not run.where().init
