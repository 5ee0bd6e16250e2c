"""``up``, ``down`` and ``status``, written once for every target.

Up: show the plan, ask, lock, start (or check) the robot's side, record the deployment, let the
target create its machines, provision and connect every host (a target whose platform runs the
nodes itself, without ``Feature.PROVISIONS``, answers the links and only the edge's end starts
here), record what was applied. Down:
stop the edge, stop what runs on machines that stay, let the target destroy what it made, prove
nothing is left, forget. Status: the record, the target's machines and cost, the edge's links.
A target (:class:`~fogiac.lifecycle.driver.Target`) answers only the questions that differ.
"""

from __future__ import annotations

import dataclasses
import shutil
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from fogiac import deployment
from fogiac.errors import CredentialsError, FogiacError
from fogiac.lifecycle.driver import (
    Created,
    DownOptions,
    DownResult,
    Feature,
    Target,
    UpOptions,
    UpResult,
)
from fogiac.lifecycle.edge import (
    edge_services,
    edge_status,
    ensure_edge_master,
    provision_and_connect,
    running_edge,
    stop_edge,
)
from fogiac.lifecycle.events import OnEvent, Phase, Progress
from fogiac.lifecycle.robots import robot_status
from fogiac.plan.document import plan_document
from fogiac.plan.model import Plan
from fogiac.provision import recorded_access, recorded_hosts, teardown
from fogiac.state import StackState, changing


def up(target: Target, plan: Plan, opts: UpOptions) -> UpResult:
    """Apply ``plan`` on ``target``: nothing before the user said yes; a failure leaves a record ``down`` finds."""
    target.ready(plan, verb="up")  # before any state is touched
    # the applied section is the document `fogiac plan` builds from the compiled plan, so that
    # `plan --detailed-exitcode` compares like with like.
    doc = plan_document(plan, target.declare(plan), manifest=opts.manifest_path)
    infra_only = opts.infra_only and Feature.INFRA_ONLY in target.features
    existed = StackState(plan.stack).exists()
    with changing(plan.stack, operation="up") as commit:
        prepared = target.prepare(plan, ssh_from=opts.ssh_from)
        opts.show(doc, prepared.summary)
        for line in prepared.notices:
            opts.announce(line)
        if not opts.yes and not opts.confirm(prepared.question):
            raise FogiacError("not applied: nothing was changed")
        master = opts.edge_master or plan.edge_master
        commit()
        # recorded before anything exists, so down always finds it; undone if the robot's side does not answer
        with deployment.begun(prepared.plan, opts.manifest_path, existed=existed):
            if not infra_only:  # before anything is made: the robot's side must be there to connect
                with _step(opts.on_event, "edge", "robot's ROS master", master):
                    ensure_edge_master(prepared.plan, master, start=opts.start_edge_master)
        created = target.create(prepared.plan, prepared, announce=opts.announce, on_event=opts.on_event)
        plan = created.plan
        report, relays = None, {}
        if not infra_only:
            reach = target.reach(plan, created, announce=opts.announce)
            # a target without Feature.PROVISIONS: its platform runs the nodes and their end of the link,
            # and it answered the links itself (reach.connect); only the edge's end starts
            done = provision_and_connect(plan, access=reach.access, connect=reach.connect, master=master,
                                         started_edge_master=opts.start_edge_master, ports=reach.ports,
                                         progress=_provision_steps(opts.on_event),
                                         provisions=Feature.PROVISIONS in target.features)
            for note in done.notes:
                opts.announce(note)
            report, relays = done.report, dict(done.relays)
        deployment.finish(plan, opts.manifest_path, plan_digest=doc["plan_digest"], applied=doc)
        applied = StackState(plan.stack).where()
    return UpResult(outputs=created.outputs or {"relays": relays}, applied=applied, report=report, relays=relays,
                    edge_master=master, plan=plan, machines=created.machines)


@contextmanager
def _step(on_event: OnEvent | None, name: str, kind: str, detail: str) -> Iterator[None]:
    """One step of ``up`` outside any host's provisioning, shown as it starts and ends."""
    key = f"{kind}:{name}"
    if on_event is not None:
        on_event(Progress(phase="start", key=key, name=name, type=kind, op="check", message=detail))
    try:
        yield
    except BaseException as err:
        if on_event is not None:
            said = "interrupted" if isinstance(err, KeyboardInterrupt) else detail
            on_event(Progress(phase="failed", key=key, name=name, type=kind, op="check", message=said))
        raise
    if on_event is not None:
        on_event(Progress(phase="done", key=key, name=name, type=kind, op="check", message=detail))


def _provision_steps(on_event: OnEvent | None) -> Callable[[str, str, str], None] | None:
    """Provisioning's per-step callback as progress events: each host's steps (``runtime``, ``services``,
    ``link``: the names the provisioning report and ``status`` use) as they start and end, so ``up``
    is never silent while a host is set up."""
    if on_event is None:
        return None

    def progress(host: str, step: str, status: str) -> None:
        phase: Phase = "start" if status == "running" else "failed" if status == "failed" else "done"
        on_event(Progress(phase=phase, key=f"provision:{host}:{step}", name=host, type=step, op="provision",
                          message=status))
    return progress


def _recorded_hosts_too(target: Target, plan: Plan, access: Mapping[str, Any]
                        ) -> tuple[Plan, dict[str, Any], dict[str, Any]]:
    """The plan's hosts and every other host the stack's provisioning record names, with their access (the
    target reads back what it recorded): a ``down --force`` with another manifest of the same stack stops
    the first manifest's hosts too. A recorded host is reached where it was provisioned, not where ``reach``
    puts it from this operator's state folder (another operator's ``local`` sandbox is under their folder,
    and its pid files may not have reached the shared store before their ``up`` died); the third map holds
    the hosts ``reach`` puts elsewhere, this operator's copy of them, to be removed too."""
    recorded = recorded_access(StackState(plan.stack).folder, target.access_from)
    reached = {**access, **{name: entry[0] for name, entry in recorded.items()}}
    copies = {name: mine for name, mine in access.items()
              if name in recorded and recorded[name][0].describe() != mine.describe()}
    extra = {name: entry for name, entry in recorded.items() if name not in access}
    if not extra or not plan.hosts:
        return plan, reached, copies
    specs = tuple(dataclasses.replace(plan.hosts[0], name=name, nodes=entry[2]) for name, entry in extra.items())
    return dataclasses.replace(plan, hosts=plan.hosts + specs), reached, copies


def down(target: Target, plan: Plan, opts: DownOptions) -> DownResult:
    """Stop the edge, stop what runs on machines that stay, destroy what was made, prove nothing is left."""
    target.ready(plan, verb="down")  # missing credentials: one line, before anything is destroyed
    state = StackState(plan.stack)
    folder = state.folder
    record = deployment.read(plan.stack)
    known = record is not None and record.exists
    if not known and not recorded_hosts(folder) and not edge_services(plan) and not target.recorded(plan):
        return DownResult(engine_errors=(), left=(), not_checked=(), existed=False)  # and nothing created
    errors: list[str] = []
    deleted = [f"edge process {e['name']}" for e in running_edge(plan)]
    with changing(plan.stack, operation="down"):
        stop_edge(plan, keep_master=True)  # the edge relays first: their peers are about to go
        # the machines stay: stop what fogiac started there (a platform that runs the nodes stops its own)
        if Feature.PROVISIONS in target.features and Feature.CREATES_MACHINES not in target.features:
            try:
                access = target.reach(plan, Created(plan=plan), announce=lambda _: None).access
                every, hosts, copies = _recorded_hosts_too(target, plan, access)
                for where in (hosts, copies):  # where each host was provisioned, then this operator's copy of it
                    if not where:
                        continue
                    part = dataclasses.replace(every, hosts=tuple(h for h in every.hosts if h.name in where))
                    report = teardown(part, hosts=where, state_dir=folder)
                    errors += [o.error or f"{o.host}: failed" for o in report.failed]
                    deleted += [f"{o.host} process {name}" for o in report.hosts for name in o.stopped]
            except FogiacError as err:
                errors.append(str(err))
        stop_edge(plan)
        destroyed = target.destroy(plan, opts)
        deleted += destroyed.deleted
        left = [f"process {e['name']} (pid {e['pid']})" for e in running_edge(plan)] + list(destroyed.left)
        if not left and not errors:
            state.drop(state.EDGES, state.APPLIED)
            shutil.rmtree(state.edge, ignore_errors=True)  # nothing runs there now: its logs (the edge master's too)
            target.forget(plan, keep_network=opts.keep_network)
            if destroyed.kept:
                deployment.cut_back(plan.stack)
            else:
                deployment.removed(plan.stack)
    return DownResult(engine_errors=(*errors, *destroyed.errors), left=tuple(left),
                      not_checked=destroyed.not_checked, deleted=tuple(deleted), kept=destroyed.kept)


def status(target: Target, plan: Plan, *, now: float | None = None) -> dict[str, Any]:
    """The record (deployed, partial), the target's machines and cost, and the edge's processes and links."""
    now = time.time() if now is None else now
    head = {"stack": plan.stack, "target": plan.target}
    state = StackState(plan.stack)
    folder = state.folder
    record = deployment.read(plan.stack)
    known = record is not None and record.exists
    provisioned = bool(recorded_hosts(folder))  # provisioning's own record of the hosts it reached
    nothing = {**head, "deployed": False, "hosts": [], "relays": [], "edge": []}
    if not known and not provisioned and not target.recorded(plan):
        return nothing
    try:
        described = target.describe(plan, now=now)  # a target that cannot answer (no credentials) stops here...
    except CredentialsError as err:
        if known or provisioned:
            raise
        # ...unless nothing here says the stack exists: never deployed from this machine, and the cloud was
        # not asked for what another machine may have left (aws: status asks the cloud, not only the record)
        return {**nothing, "unchecked": str(err)}
    if not known and not provisioned and not described.get("hosts"):
        return {**nothing, "checked": "the cloud reports no instances"}  # asked, and nothing runs there
    edge = edge_status(plan)
    robots = robot_status(plan, edge["edge"])  # a fleet's robots, one row each; none for a stack of one robot
    return {**head, "deployed": True, "partial": record.partial if record is not None and known else provisioned,
            "edge_master": edge["edge_master"], **described,
            "relays": edge["relays"], "edge": edge["edge"], **({"robots": robots} if robots else {})}
