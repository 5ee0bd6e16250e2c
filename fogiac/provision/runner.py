"""Provision every host of a plan at once and report each host's outcome.

Why threads: the work is waiting on SSH round trips and remote processes, so one thread per
host makes N hosts take about as long as the slowest one. A failing host never stops or hides
the others; :class:`ProvisionReport` carries every host's steps and error line.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from fogiac.errors import FogiacError, ProvisionError
from fogiac.hostmodel import Layout
from fogiac.net import middleware
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision.host import Host, HostAccess, HostPorts, planned_ports, q
from fogiac.provision.managers import manager_for
from fogiac.provision.steps import CHANGED, HostRun, Options, put_unless_same, step
from fogiac.state import LEGACY_FILES, StackState

Progress = Callable[[str, str, str], None]  # (host, step, status)
RECORD = LEGACY_FILES[StackState.HOSTS]  # where an older fogiac kept what the record's hosts section holds
KNOWN_HOSTS = StackState.KNOWN_HOSTS  # the SSH host keys provisioning has seen, in the stack's folder


@dataclass(frozen=True)
class StepOutcome:
    name: str
    status: str  # changed | ok | skipped | failed
    detail: str
    seconds: float


@dataclass(frozen=True)
class HostOutcome:
    host: str
    address: str
    steps: tuple[StepOutcome, ...]
    error: str | None
    files_pushed: int
    bytes_sent: int
    seconds: float
    base: str = ""
    stopped: tuple[str, ...] = ()  # teardown: the services it stopped

    @property
    def ok(self) -> bool:
        return self.error is None

    @property
    def changed(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.steps if s.status == CHANGED)


@dataclass(frozen=True)
class ProvisionReport:
    hosts: tuple[HostOutcome, ...]
    seconds: float

    @property
    def ok(self) -> bool:
        return all(h.ok for h in self.hosts)

    @property
    def failed(self) -> tuple[HostOutcome, ...]:
        return tuple(h for h in self.hosts if not h.ok)

    @property
    def no_changes(self) -> bool:
        return self.ok and not any(h.changed for h in self.hosts)

    @property
    def bytes_sent(self) -> int:
        return sum(h.bytes_sent for h in self.hosts)

    def summary(self) -> str:
        if not self.ok:
            return f"{len(self.failed)} of {len(self.hosts)} host(s) failed"
        if self.no_changes:
            return "no changes"
        changed = sum(1 for h in self.hosts if h.changed)
        return f"{changed} of {len(self.hosts)} host(s) changed"


def _provision_one(plan: Plan, spec: HostSpec, access: HostAccess, *, ports: HostPorts, known_hosts: Path,
                   options: Options, progress: Progress | None) -> HostOutcome:
    started = time.monotonic()
    host = access.open(name=spec.name, known_hosts=known_hosts, stack=plan.stack)
    run = HostRun(plan=plan, spec=spec, access=access, host=host, options=options, ports=ports)
    done: list[StepOutcome] = []
    error = None
    try:
        for name in spec.steps:
            t0 = time.monotonic()
            if progress:
                progress(spec.name, name, "running")
            try:
                status, detail = step(name)(run)
            except FogiacError as err:  # named by its host once, whether the step named it or not
                error = str(err) if str(err).startswith((f"{spec.name}: ", f"{spec.name} (")) else f"{spec.name}: {err}"
            except Exception as err:  # a host's unexpected failure must not hide the others
                error = f"{spec.name}: {name}: {type(err).__name__}: {err}"
            if error is not None:
                done.append(StepOutcome(name, "failed", error, time.monotonic() - t0))
                if progress:
                    progress(spec.name, name, "failed")
                break
            done.append(StepOutcome(name, status, detail, time.monotonic() - t0))
            if progress:
                progress(spec.name, name, status)
    finally:
        host.close()
    return HostOutcome(host=spec.name, address=access.location, steps=tuple(done), error=error,
                       files_pushed=run.files_pushed, bytes_sent=host.bytes_sent,
                       seconds=time.monotonic() - started, base=host.base)


def _for_each(plan: Plan, hosts: Mapping[str, HostAccess], work: Callable[[HostSpec, HostAccess], HostOutcome]
              ) -> tuple[HostOutcome, ...]:
    missing = [h.name for h in plan.hosts if h.name not in hosts]
    if missing:
        raise ProvisionError(f"no access given for host(s) {', '.join(missing)}")
    specs = list(plan.hosts)
    with ThreadPoolExecutor(max_workers=max(1, len(specs)), thread_name_prefix="fogiac-provision") as pool:
        return tuple(pool.map(lambda s: work(s, hosts[s.name]), specs))


def provision(plan: Plan, *, hosts: Mapping[str, HostAccess], state_dir: Path, certs_dir: Path | None = None,
              progress: Progress | None = None, health_timeout: float = 30.0,
              allow_install: bool = False, dialed: Mapping[str, str] | None = None,
              ports: Mapping[str, HostPorts] | None = None) -> ProvisionReport:
    """Run each host's steps (``HostSpec.steps``) on all hosts in parallel; never raises per host.

    ``state_dir`` is the stack's state folder: its ``known_hosts`` records SSH host keys, and the
    record's hosts section how each host was reached so ``fogiac logs``/``ssh`` find it.
    ``dialed``: host -> the address the edge dials (a certificate may name it); unset, the SSH address.
    ``ports``: host -> what its services listen on, where the target chose (unset: the plan's).
    """
    started = time.monotonic()
    options = Options(certs_dir=certs_dir, health_timeout=health_timeout, allow_install=allow_install,
                      dialed=dict(dialed or {}), revoked=revoked_robots(state_dir))
    known_hosts = StackState.at(state_dir).known_hosts
    record_access(state_dir, plan, hosts, {})  # first: an interrupted run's hosts are found again
    listen = {**planned_ports(plan), **(ports or {})}
    outcomes = _for_each(plan, hosts, lambda spec, access: _provision_one(
        plan, spec, access, ports=listen[spec.name], known_hosts=known_hosts, options=options, progress=progress))
    record_access(state_dir, plan, hosts, {o.host: o.base for o in outcomes if o.base})
    return ProvisionReport(hosts=outcomes, seconds=time.monotonic() - started)


def revoked_robots(state_dir: Path) -> tuple[str, ...]:
    """The fleet's robots the record keeps revoked (``fogiac robot revoke``), refused by every host's link."""
    revoked = StackState.at(state_dir).get(StackState.REVOKED)
    return tuple(sorted(str(r) for r in revoked)) if isinstance(revoked, list) else ()


def _rewrite_one(plan: Plan, spec: HostSpec, access: HostAccess, *, known_hosts: Path,
                 revoked: tuple[str, ...]) -> HostOutcome:
    started = time.monotonic()
    host = access.open(name=spec.name, known_hosts=known_hosts, stack=plan.stack)
    error, status, detail = None, "ok", "access files as they were"
    try:
        host.connect()
        layout = Layout(host.base, plan.stack)
        written = []
        for name, data, mode in middleware.fleet_files(plan.middleware, plan, spec, revoked=revoked):
            if put_unless_same(host, data, f"{layout.certs}/{name}", mode=mode):  # replaced at once: the link
                written.append(name)  # never reads half of it
        if written:
            status, detail = CHANGED, f"rewrote {', '.join(written)}"
    except FogiacError as err:
        error, status, detail = str(err), "failed", str(err)
    finally:
        host.close()
    return HostOutcome(host=spec.name, address=access.location, steps=(StepOutcome("access", status, detail,
                       time.monotonic() - started),), error=error, files_pushed=0, bytes_sent=0,
                       seconds=time.monotonic() - started, base=host.base)


def rewrite_fleet_access(plan: Plan, *, hosts: Mapping[str, HostAccess], state_dir: Path) -> ProvisionReport:
    """Rewrite every host's fleet access files from the plan and the record's revoked robots, and nothing else:
    a robot revoked or restored by hand reaches every cloud end within its poll, and no process restarts."""
    started = time.monotonic()
    revoked = revoked_robots(state_dir)
    outcomes = _for_each(plan, hosts, lambda spec, access: _rewrite_one(
        plan, spec, access, known_hosts=StackState.at(state_dir).known_hosts, revoked=revoked))
    return ProvisionReport(hosts=outcomes, seconds=time.monotonic() - started)


def record_access(state_dir: Path, plan: Plan, hosts: Mapping[str, HostAccess], bases: Mapping[str, str]) -> None:
    """Record each planned host's access description (opaque here), base folder and nodes in the
    record's hosts section; a base not known this time is kept from before."""
    def change(document: dict[str, Any]) -> None:
        recorded = document.get(StackState.HOSTS)
        recorded = dict(recorded) if isinstance(recorded, Mapping) else {}
        for spec in plan.hosts:
            entry = dict(hosts[spec.name].describe())
            before = recorded.get(spec.name)
            entry["base"] = bases.get(spec.name) or (before.get("base", "") if isinstance(before, Mapping) else "")
            entry["nodes"] = list(spec.nodes)
            recorded[spec.name] = entry
        document[StackState.HOSTS] = recorded

    StackState.at(state_dir).update(change)


A = TypeVar("A", bound=HostAccess)
_NOT_ACCESS = ("base", "nodes")  # what the record keeps beside each host's access description


def recorded_hosts(state_dir: Path) -> dict[str, dict[str, Any]]:
    """{host: its record entry} as the last provisioning wrote them: the access description, ``base``
    and ``nodes``. Read as data: whether anything is recorded needs no target to rebuild it."""
    found = StackState.at(state_dir).section(StackState.HOSTS)
    if found is None or found.value is None:
        return {}
    if not isinstance(found.value, Mapping) or not all(isinstance(e, Mapping) for e in found.value.values()):
        raise ProvisionError(f"{found.where}: not fogiac's record of provisioned hosts (each host should be a "
                             "mapping); remove it if the stack is gone")
    return {name: dict(entry) for name, entry in found.value.items()}


def recorded_access(state_dir: Path, rebuild: Callable[[Mapping[str, Any]], A]
                    ) -> dict[str, tuple[A, str, tuple[str, ...]]]:
    """{host: (access, base folder, nodes)} as the last provisioning recorded them; ``rebuild`` is the
    target's (:meth:`~fogiac.lifecycle.driver.Target.access_from`): each description goes back to the
    target that made it, so fogiac keeps no table of access kinds."""
    return {name: (rebuild({k: v for k, v in entry.items() if k not in _NOT_ACCESS}), str(entry.get("base", "")),
                   tuple(entry.get("nodes", ())))
            for name, entry in recorded_hosts(state_dir).items()}


def _stop_one(plan: Plan, spec: HostSpec, access: HostAccess, *, known_hosts: Path, remove: bool) -> HostOutcome:
    started = time.monotonic()
    host = access.open(name=spec.name, known_hosts=known_hosts, stack=plan.stack)
    error, detail, status = None, "", "ok"
    stopped: list[str] = []
    try:
        host.connect()
        layout = Layout(host.base, plan.stack)
        stopped = manager_for(host).stop_all(host, layout)
        stopped += remove_containers(host, layout, stack=plan.stack, host_name=spec.name)
        detail = f"stopped {', '.join(stopped)}" if stopped else "nothing running"
        status = CHANGED if stopped else "ok"
        if remove:
            access.remove_base(host)  # the access knows its folder: a sandbox entirely, a remote one by path
            detail += "; removed files"
    except FogiacError as err:
        error, status, detail = str(err), "failed", str(err)
    finally:
        host.close()
    return HostOutcome(host=spec.name, address=access.location, steps=(StepOutcome("stop", status, detail,
                       time.monotonic() - started),), error=error, files_pushed=0, bytes_sent=0,
                       seconds=time.monotonic() - started, base=host.base, stopped=tuple(stopped))


# Containers fogiac ran carry the stack and host as labels (as Compose labels its project's):
# whatever a killed engine client left running is found and removed by them. Engines are asked
# only where a service script ran one, so native hosts pay nothing.
_REMOVE = ("grep -qs -- '--label fogiac.stack=' {services}/*.sh || exit 0; "
           "for e in docker podman; do command -v $e >/dev/null && $e info >/dev/null 2>&1 || continue; "
           "ids=$($e ps -aq --filter label=fogiac.stack={stack} --filter label=fogiac.host={host}); "
           "[ -z \"$ids\" ] || {{ $e rm -f $ids >/dev/null && echo \"$ids\" | wc -l; }}; done")


def remove_containers(host: Host, layout: Layout, *, stack: str, host_name: str) -> list[str]:
    """Remove every container of ``stack`` on ``host_name``; one entry per engine that had some."""
    done = host.run(_REMOVE.format(services=q(layout.services), stack=q(stack), host=q(host_name)), check=False)
    return [f"{n.strip()} container(s)" for n in done.stdout.split() if n.strip()]


def stop_all(plan: Plan, *, hosts: Mapping[str, HostAccess], state_dir: Path) -> ProvisionReport:
    """Stop every service fogiac started on every host (files stay, so ``provision`` restarts them)."""
    started = time.monotonic()
    outcomes = _for_each(plan, hosts, lambda spec, access: _stop_one(
        plan, spec, access, known_hosts=StackState.at(state_dir).known_hosts, remove=False))
    return ProvisionReport(hosts=outcomes, seconds=time.monotonic() - started)


def teardown(plan: Plan, *, hosts: Mapping[str, HostAccess], state_dir: Path) -> ProvisionReport:
    """Stop everything and remove fogiac's folder on each host (a local sandbox entirely)."""
    started = time.monotonic()
    outcomes = _for_each(plan, hosts, lambda spec, access: _stop_one(
        plan, spec, access, known_hosts=StackState.at(state_dir).known_hosts, remove=True))
    if all(o.ok for o in outcomes):
        StackState.at(state_dir).drop(StackState.HOSTS)
    return ProvisionReport(hosts=outcomes, seconds=time.monotonic() - started)
