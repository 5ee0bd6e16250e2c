"""The link step asks the middleware what its link needs on a host (``Deployment.link_program``) and names
no middleware itself: a host without that program gets the link's service scripts, not started; one with
it (fogiac's own code, here) starts them. The probe looks for the program in the same round trip as the rest.

Hosts are real sandbox folders run through :class:`LocalHost`; the middlewares are the relay, a copy of
it whose link program no host has, and Zenoh (whose router, a host service, is the link).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.net import middleware
from fogiac.net.relay.deploy import RelayDeployment
from fogiac.net.relay.middleware import RELAY
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision.host import HostPorts
from fogiac.provision.local import LocalAccess
from fogiac.provision.probe import gather
from fogiac.provision.runtimes.base import SKIPPED
from fogiac.provision.steps import HostRun, Options, link_available, step_link
from tests.conftest import EXAMPLES

LINKLESS = "linkless"


class _ElsewhereDeployment(RelayDeployment):
    link_program = "fogiac/cli/no-such-link.py"  # what no host has


@pytest.fixture
def linkless() -> Iterator[str]:
    middleware.register(dataclasses.replace(RELAY, name=LINKLESS, distros=()), _ElsewhereDeployment())
    yield LINKLESS
    middleware.unregister(LINKLESS)


def _run(tmp_path: Path, plan: Plan) -> HostRun:
    spec = plan.hosts[0]
    access = LocalAccess(sandbox=tmp_path / "host")
    host = access.open(name=spec.name, known_hosts=tmp_path / "known_hosts", stack=plan.stack)
    host.connect()
    certs = tmp_path / "operator" / "certs"
    load_or_create_bundle(plan.stack, certs)
    return HostRun(plan=plan, spec=spec, access=access, host=host, options=Options(certs_dir=certs),
                   ports=HostPorts(master_port=1, relay_port=2))


def test_a_host_without_the_link_program_gets_the_scripts_only(tmp_path: Path, linkless: str) -> None:
    plan = dataclasses.replace(compile_plan(load_manifest(EXAMPLES / "motion-planning.yaml")), middleware=linkless)
    run = _run(tmp_path, plan)
    assert not link_available(run)
    run.facts = gather(run.host, run.layout, link_program=f"{tmp_path}/elsewhere/fogiac/cli/no-such-link.py")
    assert "linkprogram" not in run.facts.flags
    status, detail = step_link(run)
    assert (status, detail) == (SKIPPED, "fogiac's code is not on the host; service scripts rendered only")
    wanted = run.deploying.link_services(plan, plan.hosts[0], run.where())
    assert wanted and all(Path(f"{run.layout.services}/{s.name}.sh").is_file() for s in wanted)
    assert run.link_services() == ()  # nothing of the link is health-checked: it was not started


def test_the_program_the_middleware_names_is_what_the_probe_looks_for(tmp_path: Path) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "motion-planning.yaml"))
    run = _run(tmp_path, plan)
    program = Path(__file__).resolve().parents[2] / run.deploying.link_program  # fogiac's code, this checkout's
    assert run.deploying.link_program == "fogiac/cli/relay.py" and program.is_file()
    assert link_available(run)
    assert "linkprogram" in gather(run.host, run.layout, link_program=str(program)).flags


def test_a_middleware_without_link_services_asks_for_nothing(tmp_path: Path) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "ros2-zenoh.yaml"))
    run = _run(tmp_path, plan)
    assert run.deploying.link_program == "" and link_available(run)
    assert step_link(run)[1] == "the host's services carry the link"
