"""up and down per target: check, show, ask, apply, record; destroy, sweep, prove.

Targets are a registry (name -> :class:`Target`), so wiring ``hosts`` and ``local`` adds an
entry and touches no caller. Rendering and asking are callbacks from the CLI: this module
decides, the CLI shows. Whatever fails before anything is applied leaves the state directory
as it was (a stack folder this run created is removed again).
"""

from __future__ import annotations

import dataclasses
import shutil
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fogiac.errors import FogiacError
from fogiac.plan import Plan
from fogiac.state import read_json, stack_dir, stack_lock, write_json_atomic

COMPUTE_KINDS = ("instance", "key-pair", "network-interface")  # what --keep-network still sweeps


@dataclass(frozen=True)
class UpOptions:
    manifest_path: Path
    yes: bool = False
    ssh_from: str | None = None
    show: Callable[[Mapping[str, Any], Any], None] = lambda doc, report: None  # the plan document, preflight
    confirm: Callable[[str], bool] = lambda question: False
    announce: Callable[[str], None] = lambda line: None
    on_event: Callable[[Any], None] | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)  # target-specific flags


@dataclass(frozen=True)
class UpResult:
    outputs: Mapping[str, Mapping[str, Any]]
    applied: Path
    report: Any = None  # the provisioning report, where the target provisions hosts


@dataclass(frozen=True)
class DownOptions:
    keep_network: bool = False
    on_event: Callable[[Any], None] | None = None


@dataclass(frozen=True)
class DownResult:
    engine_errors: tuple[str, ...]
    left: tuple[str, ...]  # resources still tagged with the stack
    not_checked: tuple[str, ...]
    deleted: tuple[str, ...] = ()
    kept_usd_per_hour: float | None = None  # with --keep-network: what the kept network costs

    @property
    def clean(self) -> bool:
        """Nothing tagged with the stack is left (engine errors the sweep made good do not count)."""
        return not self.left


@dataclass(frozen=True)
class Target:
    up: Callable[[Plan, UpOptions], UpResult]
    down: Callable[[Plan, DownOptions], DownResult]
    status: Callable[[Plan], dict[str, Any]]  # JSON-ready: {"stack", "target", "hosts": [{"host", ...}]}


def target(name: str) -> Target:
    """The wired target ``name``; the others fail in one line naming the wired ones."""
    found = TARGETS.get(name)
    if found is None:
        raise FogiacError(f"target {name}: not wired yet (wired: {', '.join(sorted(TARGETS))})")
    return found


@contextmanager
def untouched_on_failure(stack: str) -> Iterator[Callable[[], None]]:
    """Remove the stack folder again if this run created it and fails before ``commit()``."""
    existed = stack_dir(stack, create=False).exists()
    committed = False

    def commit() -> None:
        nonlocal committed
        committed = True

    try:
        yield commit
    except BaseException:
        path = stack_dir(stack, create=False)
        if not existed and not committed and path.exists():
            shutil.rmtree(path, ignore_errors=True)
        raise


def _aws_up(plan: Plan, opts: UpOptions) -> UpResult:
    from fogiac import aws, engine
    from fogiac.offline import APPLIED_FILE, plan_document

    engine.pulumi_cli()  # before any state is touched
    # applied.json is the same document `fogiac plan` builds from the compiled plan, so that
    # `plan --detailed-exitcode` compares like with like; the zone actually used is in outputs.json.
    doc = plan_document(plan, manifest=opts.manifest_path)
    with untouched_on_failure(plan.stack) as commit, stack_lock(plan.stack, operation="up"):
        recorded = read_json(stack_dir(plan.stack) / engine.OUTPUTS_FILE) or {}
        if recorded.get("zone") and not plan.zone_chosen:  # keep the subnets where they are
            plan = dataclasses.replace(plan, zone=recorded["zone"], zone_chosen=True)
        report = aws.preflight(plan, operator_cidr=opts.ssh_from, known_ids=engine.known_ids(plan.stack))
        plan = dataclasses.replace(plan, zone=report.zone)
        opts.show(doc, report)
        if plan.vpn is not None:
            opts.announce(engine.VPN_NOTICE)
        if not opts.yes and not opts.confirm(f"Create these resources in {plan.region} (${plan.hourly_usd:.4f}/h)?"):
            raise FogiacError("not applied: nothing was changed")
        infra_only = bool(opts.extras.get("infra_only"))
        master = opts.extras.get("edge_master") or plan.edge_master
        if not infra_only:  # before money is spent: the robot's side must be there to connect
            from fogiac.fleet import ensure_edge_master

            ensure_edge_master(plan, master, start=bool(opts.extras.get("start_edge_master")))
        commit()
        outputs = engine.Engine(plan, on_event=opts.on_event).up(operator_cidrs=report.operator_cidrs)
        folder = stack_dir(plan.stack)
        write_json_atomic(folder / engine.OUTPUTS_FILE, {"zone": plan.zone, **outputs})
        write_json_atomic(folder / APPLIED_FILE, doc)
        if infra_only:
            return UpResult(outputs=outputs, applied=folder / APPLIED_FILE)
        return UpResult(outputs=outputs, applied=folder / APPLIED_FILE,
                        report=_aws_connect(plan, outputs, master=master, announce=opts.announce))


def _aws_connect(plan: Plan, outputs: Mapping[str, Any], *, master: str, announce: Callable[[str], None]) -> Any:
    """After the stacks: the edge's VPN profile, then provisioning and relays as on every target."""
    from fogiac import aws
    from fogiac.fleet import aws_access, provision_and_connect

    if plan.vpn is not None:
        from fogiac.certs import load_or_create_bundle
        from fogiac.net.vpn import write_client_profile

        profile = write_client_profile(
            endpoint_dns=outputs["network"]["vpn_dns_name"], stack=plan.stack,
            bundle=load_or_create_bundle(plan.stack, stack_dir(plan.stack) / "certs"))
        announce(f"VPN profile: {profile} (connect with: sudo fogiac vpn up; the relays retry until it is up)")
    announce("waiting for each instance to print its SSH host keys on its console (pinned, never trusted on sight)")
    access, connect = aws_access(plan, outputs, fingerprints=lambda iid: aws.host_fingerprints(iid, region=plan.region))
    return provision_and_connect(plan, access=access, connect=connect, master=master).report


def kept_network_usd_per_hour(plan: Plan) -> float:
    """A kept network costs its Client VPN association (VPC, subnets and gateways are free)."""
    from fogiac.catalog import catalog

    return catalog().vpn_association_usd_per_hour if plan.vpn is not None else 0.0


def _aws_down(plan: Plan, opts: DownOptions) -> DownResult:
    from fogiac import aws, engine
    from fogiac.offline import APPLIED_FILE

    engine.pulumi_cli()
    aws.identity(region=plan.region)  # missing credentials: one line, before anything is destroyed
    with untouched_on_failure(plan.stack), stack_lock(plan.stack, operation="down"):
        from fogiac.fleet import stop_edge

        stop_edge(plan)  # the edge relays first: their peers are about to go
        layers = ("compute",) if opts.keep_network else ("compute", "network")
        errors = engine.Engine(plan, on_event=opts.on_event).destroy(layers=layers)
        result = aws.sweep(plan.stack, region=plan.region, dry_run=False,
                           kinds=COMPUTE_KINDS if opts.keep_network else None)
        folder = stack_dir(plan.stack)
        if not result.left:
            (folder / APPLIED_FILE).unlink(missing_ok=True)
            outputs = read_json(folder / engine.OUTPUTS_FILE) or {}
            if opts.keep_network and outputs:
                write_json_atomic(folder / engine.OUTPUTS_FILE, {k: v for k, v in outputs.items() if k != "compute"})
            else:
                (folder / engine.OUTPUTS_FILE).unlink(missing_ok=True)
        return DownResult(
            engine_errors=tuple(errors), left=tuple(str(f) for f in result.left),
            not_checked=result.not_checked, deleted=tuple(str(f) for f in result.deleted),
            kept_usd_per_hour=kept_network_usd_per_hour(plan) if opts.keep_network else None,
        )


def _aws_status(plan: Plan) -> dict[str, Any]:
    from fogiac import aws

    rows = aws.status(plan.stack, region=plan.region)
    return {"stack": plan.stack, "target": plan.target, "region": plan.region, "hosts": [
        {"host": r.name, "instance_id": r.instance_id, "state": r.state, "machine": r.machine,
         "public_ip": r.public_ip, "private_ip": r.private_ip, "launched": r.launched.isoformat(),
         "uptime_s": round(r.uptime_s), "cost_usd": r.cost_usd} for r in rows]}


def _fleet_up(plan: Plan, opts: UpOptions) -> UpResult:
    from fogiac.fleet import FleetOptions, fleet_up

    done = fleet_up(plan, FleetOptions(
        yes=opts.yes, confirm=opts.confirm,
        start_edge_master=bool(opts.extras.get("start_edge_master")), edge_master=opts.extras.get("edge_master"),
    ))
    return UpResult(outputs={"relays": dict(done.relays)}, applied=done.deployment, report=done.report)


def _fleet_down(plan: Plan, opts: DownOptions) -> DownResult:
    from fogiac.fleet import fleet_down

    errors, left = fleet_down(plan)
    return DownResult(engine_errors=errors, left=left, not_checked=())


def _fleet_status(plan: Plan) -> dict[str, Any]:
    from fogiac.fleet import fleet_status

    return {"stack": plan.stack, "target": plan.target, **fleet_status(plan)}


TARGETS: dict[str, Target] = {
    "aws": Target(up=_aws_up, down=_aws_down, status=_aws_status),
    "hosts": Target(up=_fleet_up, down=_fleet_down, status=_fleet_status),
    "local": Target(up=_fleet_up, down=_fleet_down, status=_fleet_status),
}


def doctor(plan: Plan, *, ssh_from: str | None = None) -> list[tuple[str, bool, str]]:
    """Every check ``up`` would make, each as (what, ok, detail); nothing is created."""
    from fogiac import aws, engine
    from fogiac.errors import CloudError

    checks: list[tuple[str, bool, str]] = []
    try:
        checks.append(("Pulumi CLI", True, str(engine.pulumi_cli())))
    except CloudError as err:
        checks.append(("Pulumi CLI", False, str(err)))
    try:
        report = aws.preflight(plan, operator_cidr=ssh_from,
                               known_ids=engine.known_ids(plan.stack) if stack_dir(plan.stack, create=False).exists()
                               else frozenset())
    except CloudError as err:
        checks += [("preflight", False, line) for line in str(err).splitlines()]
    else:
        checks += [("credentials", True, f"account {report.account}"), ("region", True, report.region),
                   ("zone", True, f"{report.zone} offers {', '.join(sorted({h.machine for h in plan.hosts}))}"),
                   ("images", True, ", ".join(f"{h}: {ami}" for h, ami in report.images) or "none needed"),
                   ("ssh_from", True, ", ".join(report.operator_cidrs))]
    return checks
