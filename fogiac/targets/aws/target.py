"""The ``aws`` target's lifecycle: up, down, status, refresh, sweep and doctor (its placement, what
compile asks, is :mod:`.placement` and loads without this)."""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import time
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import Any

from fogiac import deployment
from fogiac.certs import SSH_KEY, load_or_create_bundle
from fogiac.errors import CloudError, ProvisionError
from fogiac.lifecycle.edge import edge_idle_since
from fogiac.lifecycle.events import OnEvent
from fogiac.lifecycle.report import autostop_line
from fogiac.manifest.schema import Manifest
from fogiac.plan import drift, guard
from fogiac.plan.model import Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.provision import SshAccess, idle, recorded_access
from fogiac.provision.runner import revoked_robots
from fogiac.pulumi_engine.workspace import pulumi_cli
from fogiac.state import StackState, read_json, stack_lock
from fogiac.tables import table
from fogiac.targets.aws import api, engine, iam, observe, offline, placement, quotas, robotvpn, spot
from fogiac.targets.aws import sweep as sweeping
from fogiac.targets.aws.catalog import catalog
from fogiac.targets.aws.errors import EngineError
from fogiac.targets.aws.model import vpn_of
from fogiac.targets.aws.vpn import write_client_profile
from fogiac.targets.base import (
    Check,
    Created,
    Destroyed,
    DownOptions,
    Feature,
    Machine,
    Prepared,
    Reach,
    Refreshed,
    SweepOutcome,
)

COMPUTE_KINDS = ("instance", "key-pair", "network-interface")  # what --keep-network still sweeps
NETWORK_SINCE = "network_since"  # in outputs.json: when the network stack (Client VPN association) was first applied
OPERATOR_CIDRS = "operator_cidrs"  # in outputs.json: what ssh_from resolved to at the last up (refresh compares)
HOST_KEYS_FILE = "host-keys.json"  # instance id -> SHA256 fingerprints pinned from its first boot's console
SSH_USER = "ubuntu"  # the login of both images compile chooses (Ubuntu, AWS Deep Learning Base)


@dataclass(frozen=True)
class _Preflight:
    """What ``prepare`` found, handed back to ``create``: the operator's CIDRs and what outputs.json held."""

    operator_cidrs: tuple[str, ...]
    recorded: Mapping[str, Any]
    asked_spot: frozenset[str]


class AwsTarget:
    name = "aws"
    summary = "EC2 machines in their own VPC, through a Client VPN (or proxy mode), made with Pulumi"
    features = frozenset({Feature.CREATES_MACHINES, Feature.PROVISIONS, Feature.INFRA_ONLY, Feature.KEEP_NETWORK,
                          Feature.REFUSES_ROBOTS})

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        return placement.place(manifest, stack=stack, tags=tags)

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return offline.declare(plan).rows()

    # -- up ---------------------------------------------------------------------------------------

    def ready(self, plan: Plan, *, verb: str) -> None:
        pulumi_cli()
        if verb == "down":
            api.identity(region=plan.region)

    def prepare(self, plan: Plan, *, ssh_from: str | None) -> Prepared:
        recorded = StackState(plan.stack).read(engine.OUTPUTS_FILE) or {}
        if recorded.get("zone") and not plan.zone_chosen:  # keep the subnets where they are
            plan = dataclasses.replace(plan, zone=recorded["zone"], zone_chosen=True)
        report = api.preflight(plan, operator_cidr=ssh_from, known_ids=engine.known_ids(plan.stack))
        with contextlib.suppress(quotas.QuotaUnavailable):  # unknown is not 0: the create would still tell
            if short := quotas.for_plan(plan):
                raise CloudError("\n".join(quotas.report(short)))
        plan = dataclasses.replace(plan, zone=report.zone)
        spot_hourly = plan.spot_hourly_usd
        price = guard.at_least(plan.hourly_usd, len(plan.unknown_costs), digits=4) + (
            f", about ${spot_hourly:.4f}/h with spot" if spot_hourly else "")
        summary = (f"{plan.stack}: {report.region} zone {report.zone}, account {report.account}, "
                   f"SSH from {', '.join(report.operator_cidrs)}",)
        return Prepared(plan=plan, question=f"Create these resources in {plan.region} ({price})?", summary=summary,
                        notices=(engine.VPN_NOTICE,) if plan.vpn is not None else (),
                        facts=_Preflight(report.operator_cidrs, recorded,
                                         frozenset(h.name for h in plan.hosts if h.spot)))

    def create(self, plan: Plan, prepared: Prepared, *, announce: Callable[[str], None],
               on_event: OnEvent | None) -> Created:
        facts: _Preflight = prepared.facts
        drift.clear(plan.stack)  # the apply changes the cloud: the last refresh no longer describes it
        started = api.start_stopped(plan.stack, region=plan.region, known_ids=engine.known_ids(plan.stack))
        if started:
            announce(f"started {', '.join(started)} again (stopped while idle): the same instances, "
                     "nothing recreated")
        plan, outputs = self._apply(plan, facts.operator_cidrs, facts.recorded.get(spot.ON_DEMAND, ()),
                                    announce=announce, on_event=on_event)
        since = facts.recorded.get(NETWORK_SINCE) or round(time.time())  # what the cost guard counts from
        fallen = [h.name for h in plan.hosts if not h.spot and h.name in facts.asked_spot]
        StackState(plan.stack).write(engine.OUTPUTS_FILE, {
            "zone": plan.zone, NETWORK_SINCE: since, OPERATOR_CIDRS: list(facts.operator_cidrs), **outputs,
            **({spot.ON_DEMAND: fallen} if fallen else {})})
        hosts = outputs.get("compute", {}).get("hosts", {})
        machines = tuple(Machine(name, str(h.get("instance_id")), str(h.get("machine")), h.get("public_ip"),
                                 h.get("private_ip")) for name, h in sorted(hosts.items()))
        return Created(plan=plan, outputs=outputs, machines=machines)

    def _apply(self, plan: Plan, operator_cidrs: tuple[str, ...], fallen: Collection[str], *,
               announce: Callable[[str], None], on_event: OnEvent | None) -> tuple[Plan, dict[str, Any]]:
        """Run the engine; spot hosts AWS has no capacity for are made again on-demand, once, and named."""
        plan = spot.on_demand(plan, fallen)  # fell back before: switching market would replace the instance
        try:
            return plan, engine.Engine(plan, on_event=on_event).up(operator_cidrs=operator_cidrs)
        except EngineError as err:
            code = spot.no_capacity(str(err))
            if not code:
                raise
            have = {r.name for r in api.status(plan.stack, region=plan.region) if r.state in {"pending", "running"}}
            hosts = [h.name for h in plan.hosts if h.spot and h.name not in have]  # spot hosts that got nothing
            if not hosts:
                raise
        for host in hosts:
            announce(spot.fallback_line(plan, host, code))
        plan = spot.on_demand(plan, hosts)
        return plan, engine.Engine(plan, on_event=on_event).up(operator_cidrs=operator_cidrs)

    def reach(self, plan: Plan, created: Created, *, announce: Callable[[str], None]) -> Reach:
        """After the stacks: the edge's VPN profile, and each host's address with host keys pinned from its console."""
        outputs = created.outputs
        if plan.vpn is not None and not plan.fleet:
            profile = write_client_profile(
                endpoint_dns=outputs["network"]["vpn_dns_name"], stack=plan.stack,
                bundle=load_or_create_bundle(plan.stack, StackState(plan.stack).certs))
            announce(f"VPN profile: {profile} (connect with: sudo fogiac vpn up; the relays retry until it is up)")
        elif plan.vpn is not None:
            self._robot_profiles(plan, outputs["network"], announce=announce)
        announce("waiting for each instance to print its SSH host keys on its console (pinned, never trusted on sight)")
        access, connect = access_from_outputs(plan, outputs, fingerprints=lambda iid: pinned_host_keys(
            plan.stack, iid, fetch=lambda: api.host_fingerprints(iid, region=plan.region)))
        return Reach(access=access, connect=connect)

    def _robot_profiles(self, plan: Plan, network: Mapping[str, Any], *, announce: Callable[[str], None]) -> None:
        """A fleet's robots each dial the Client VPN with a certificate of their own; the endpoint refuses the
        revoked and removed ones' (and the stack's shared one) by the CRL it is handed here."""
        spec = vpn_of(plan)
        assert spec is not None
        for robot in robotvpn.retire_dropped(plan.stack, [e.name for e in plan.edges]):
            announce(f"robot {robot} left robots:, so its VPN certificate is revoked for good")
        profiles = robotvpn.write_profiles(plan, endpoint_dns=network["vpn_dns_name"], port=spec.port,
                                           proto=spec.transport)
        for robot, profile in profiles.items():
            announce(f"VPN profile of robot {robot}: {profile} (connect with: sudo fogiac vpn up --robot {robot}, "
                     "or on the robot itself: sudo fogiac vpn up --profile PATH)")
        announce(self.refuse_revoked(plan, endpoint_id=network["vpn_endpoint_id"]))

    def refuse_revoked(self, plan: Plan, *, endpoint_id: str | None = None) -> str:
        """Hand the Client VPN endpoint the CRL of the robots revoked or removed (``up``, ``robot revoke`` and
        ``restore``); one line says what it refuses. Only when that changed: importing resets every tunnel."""
        if endpoint_id is None:
            network = (StackState(plan.stack).read(engine.OUTPUTS_FILE) or {}).get("network", {})
            endpoint_id = network.get("vpn_endpoint_id")
        if plan.vpn is None or not plan.fleet or not endpoint_id:
            return "no Client VPN endpoint: nothing to refuse there"
        revocations = robotvpn.write_crl(plan, revoked_robots(StackState(plan.stack).folder))
        refused = ", ".join(revocations.robots) or "no robot"
        if not robotvpn.needs_import(plan.stack, endpoint_id, revocations):
            return f"Client VPN {endpoint_id} already refuses {refused} (the stack's shared certificate too)"
        api.import_revocations(endpoint_id, revocations.pem, region=plan.region)
        robotvpn.imported(plan.stack, endpoint_id, revocations)
        return (f"Client VPN {endpoint_id} now refuses {refused} (the stack's shared certificate too); "
                "the other robots' tunnels redial")

    def access_from(self, description: Mapping[str, Any]) -> SshAccess:
        """Its instances are reached over SSH only (the host keys pinned apart, in ``host-keys.json``)."""
        return SshAccess.from_description(description)

    # -- down -------------------------------------------------------------------------------------

    def recorded(self, plan: Plan) -> bool:
        return True  # what the cloud holds is known only by asking it: down always destroys and sweeps

    def destroy(self, plan: Plan, opts: DownOptions) -> Destroyed:
        layers = ("compute",) if opts.keep_network else ("compute", "network")
        errors = engine.Engine(plan, on_event=opts.on_event).destroy(layers=layers)
        result = self._sweep(plan, dry_run=False, kinds=COMPUTE_KINDS if opts.keep_network else None)
        drift.clear(plan.stack)
        kept = None
        if opts.keep_network:
            kept = (f"kept the network stack: ${kept_network_usd_per_hour(plan):.2f}/h while kept "
                    "(Client VPN association; VPC, subnets and gateway are free)")
        return Destroyed(errors=tuple(errors), left=tuple(str(f) for f in result.left),
                         not_checked=result.not_checked, deleted=tuple(str(f) for f in result.deleted), kept=kept)

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        state = StackState(plan.stack)
        # No instance is left to know its keys by, and the public addresses go back to AWS's pool.
        state.remove(HOST_KEYS_FILE, state.KNOWN_HOSTS)
        outputs = state.read(engine.OUTPUTS_FILE) or {}
        if keep_network and outputs:
            state.write(engine.OUTPUTS_FILE, {k: v for k, v in outputs.items() if k != "compute"})
        else:
            state.remove(engine.OUTPUTS_FILE)

    # -- status, doctor, refresh, sweep ---------------------------------------------------------------

    def describe(self, plan: Plan, *, now: float) -> dict[str, Any]:
        """Each instance (state, when and by whom it stopped) and the cost guard over all the stack still has."""
        rows = api.status(plan.stack, region=plan.region, now=_dt.datetime.fromtimestamp(now, _dt.timezone.utc))
        outputs = StackState(plan.stack).read(engine.OUTPUTS_FILE) or {}
        watched = watchdogs(plan, rows)
        return {"region": plan.region, "network_only": "network" in outputs and "compute" not in outputs, "hosts": [
            {"host": r.name, "instance_id": r.instance_id, "state": r.state, "machine": r.machine,
             "public_ip": r.public_ip, "private_ip": r.private_ip, "launched": r.launched.isoformat(),
             "uptime_s": round(r.uptime_s), "cost_usd": r.cost_usd,
             "stopped_at": r.stopped_at.isoformat() if r.stopped_at else None, "stopped_by": r.stopped_by,
             "market": "spot" if r.spot else "on-demand", "autostop": watched.get(r.name)}
            for r in rows], "cost": cost_guard(plan, rows, outputs, now=now, watched=watched)}

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        guarded = guard.render(doc["cost"]) if doc.get("cost") else []
        partial = []
        if doc.get("partial") and doc.get("network_only"):
            partial = [f"{doc['stack']}: network only (down --keep-network); `fogiac up` makes the compute "
                       "again, `fogiac down` removes the network"]
        elif doc.get("partial"):
            partial = [f"{doc['stack']}: partial: the last up did not finish; `fogiac up` completes it, "
                       "`fogiac down` removes what it made"]
        if not doc["hosts"]:
            return [*partial, f"{doc['stack']}: no instances", *guarded]
        out = table(f"{doc['stack']} ({doc['region']})", "host", "instance", "state", "type", "public", "private",
                    "uptime", "cost so far")
        for h in doc["hosts"]:
            state = h["state"]
            if h.get("stopped_at"):
                state += f" at {h['stopped_at'][11:19]} UTC" + (f" by {h['stopped_by']}" if h["stopped_by"] else "")
            machine = h["machine"] + (" (spot)" if h.get("market") == "spot" else "")
            out.add_row(h["host"], h["instance_id"], state, machine, h["public_ip"] or "-",
                        h["private_ip"] or "-", f"{h['uptime_s'] / 3600:.1f} h",
                        "unknown" if h["cost_usd"] is None else f"${h['cost_usd']:.2f}")
        idle_lines = [f"{h['host']}: {autostop_line(h['autostop'])}" for h in doc["hosts"] if h.get("autostop")]
        return [*partial, out, *idle_lines, *guarded]

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """Every check ``up`` would make, each as (what, ok, detail); nothing is created."""
        checks: list[Check] = []
        try:
            checks.append(Check("Pulumi CLI", True, str(pulumi_cli())))
        except CloudError as err:
            checks.append(Check("Pulumi CLI", False, str(err)))
        declared = {str(r["type"]) for r in self.declare(plan)}
        checks.append(iam.doctor_check(plan, declared))
        checks.append(iam.boundary_check(plan, declared))
        known = engine.known_ids(plan.stack) if StackState(plan.stack).exists() else frozenset()
        try:
            report = api.preflight(plan, operator_cidr=ssh_from, known_ids=known)
        except CloudError as err:
            return checks + [Check("preflight", False, line) for line in str(err).splitlines()]
        machines = ", ".join(sorted({h.machine for h in plan.hosts}))
        return checks + [
            Check("credentials", True, f"account {report.account}"), Check("region", True, report.region),
            Check("zone", True, f"{report.zone} offers {machines}"),
            Check("images", True, ", ".join(f"{h}: {ami}" for h, ami in report.images) or "none needed"),
            Check("ssh_from", True, ", ".join(report.operator_cidrs)),
            *quotas.doctor_checks(plan),
        ]

    def refresh(self, plan: Plan) -> list[Refreshed]:
        """The engine's refresh of each layer, then what EC2 reports, recorded with its drift for ``plan``."""
        with stack_lock(plan.stack, operation="refresh"):
            layers = engine.Engine(plan).refresh()
            lines = [Refreshed(r.layer, r.ok, r.summary) for r in layers]
            applied = deployment.read_applied(plan.stack)
            if applied is None:
                return lines  # nothing applied: nothing the cloud could have drifted from
            seen = observe.observe(plan.stack, region=plan.region)
            recorded = StackState(plan.stack).read(engine.OUTPUTS_FILE) or {}
            found = observe.compare(applied, seen, operator_cidrs=recorded.get(OPERATOR_CIDRS))
            drift.record(plan.stack, outputs={r.layer: dict(r.outputs) for r in layers if r.ok}, observed=seen,
                         drift=found)
            what = (f"{len(seen['instances'])} instance(s) and {len(seen['security_groups'])} security group(s) "
                    "as AWS reports them; ")
            if not found:
                return [*lines, Refreshed("cloud", True, what + "no drift from what was applied")]
            names = ", ".join(f"{d.name} ({drift.VERB[d.status]})" for d in found)
            return [*lines, Refreshed("cloud", True, what + f"{len(found)} drifted: {names}; `fogiac plan` shows how")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        # Deleting takes the stack's lock, so a sweep cannot delete what a running up is creating;
        # a dry run only lists.
        with contextlib.nullcontext() if dry_run else stack_lock(plan.stack, operation="sweep"):
            result = self._sweep(plan, dry_run=dry_run)
        return SweepOutcome(found=tuple(map(str, result.found)), deleted=tuple(map(str, result.deleted)),
                            left=tuple(map(str, result.left)), errors=result.errors, not_checked=result.not_checked)

    def _sweep(self, plan: Plan, *, dry_run: bool, kinds: tuple[str, ...] | None = None) -> sweeping.SweepResult:
        return sweeping.sweep(plan.stack, ec2=api.client("ec2", region=plan.region),
                              acm=api.client("acm", region=plan.region), logs=api.client("logs", region=plan.region),
                              iam=api.client("iam", region=plan.region), dry_run=dry_run, kinds=kinds,
                              owner=plan.manifest_name)


def watchdogs(plan: Plan, rows: list[api.InstanceStatus]) -> dict[str, dict[str, Any] | None]:
    """Each running instance's autostop watchdog, read over SSH as provisioning reached it.

    The address is the instance's current one (a stopped and started instance may have a new
    public address) and the host key the one pinned from its first boot's console: an instance
    without a pinned key is not asked, since trusting a key on sight is what pinning avoids.
    """
    state = StackState(plan.stack)
    folder = state.folder
    if plan.autostop is None or not folder.exists():
        return {}
    recorded = recorded_access(folder, SshAccess.from_description)
    pinned = read_json(state.target_file(HOST_KEYS_FILE)) or {}
    ask: dict[str, tuple[Any, str]] = {}
    unpinned: dict[str, dict[str, Any] | None] = {}
    for r in rows:
        entry = recorded.get(r.name)
        if r.state != "running" or entry is None or not r.public_ip:
            continue
        keys = tuple(pinned.get(r.instance_id) or ())
        if not keys:
            unpinned[r.name] = {idle.UNREACHABLE: f"no host key pinned for {r.instance_id}"}
            continue
        ask[r.name] = (dataclasses.replace(entry[0], address=r.public_ip, fingerprints=keys), entry[1])
    return {**unpinned, **idle.read_all(ask, known_hosts=state.known_hosts, stack=plan.stack)}


def cost_guard(plan: Plan, rows: list[api.InstanceStatus], outputs: Mapping[str, Any], *,
               now: float, watched: Mapping[str, Mapping[str, Any] | None] | None = None) -> dict[str, Any]:
    """What the stack still has on AWS, priced; "no edge" from the watchdogs, autostop's stops and
    this machine's edge relays.

    The running hosts' watchdogs (``watched``) say since when each saw no edge; a host the
    instance itself powered off (autostop) saw no edge for the autostop time before it stopped,
    so the edge has been gone since at least then; the edge relays' stats files say when this
    machine last ran one.
    """
    billed = [guard.Billed(f"instance {r.name} ({r.machine}{', spot' if r.spot else ''}, {r.state})", r.usd_per_hour,
                           r.launched.timestamp() if r.usd_per_hour else None,
                           running=r.state in {"pending", "running", "stopping"},
                           spot_estimate=r.spot_estimate and (r.usd_per_hour or 0.0) > 0) for r in rows]
    if plan.vpn is not None and outputs.get("network", {}).get("vpn_endpoint_id"):
        billed.append(guard.Billed("Client VPN subnet association", catalog().vpn_association_usd_per_hour,
                                   outputs.get(NETWORK_SINCE)))
    autostop_s = plan.autostop.idle_s if plan.autostop is not None else None
    running = [r.name for r in rows if r.state == "running"]
    readings = [(watched or {}).get(name) or {} for name in running]
    if running and all("idle_since" in w for w in readings):  # every running host's watchdog answered
        idle_since = [w["idle_since"] for w in readings]
        since = None if None in idle_since else max(idle_since)
        return guard.guard(billed, now=now, autostop_s=autostop_s, edge_idle_since=since)
    seen = [edge_idle_since(plan, now=now)]
    if autostop_s is not None and rows and all(r.stopped_by == "the instance" and r.stopped_at for r in rows):
        seen.append(max(r.stopped_at.timestamp() for r in rows if r.stopped_at) - autostop_s)
    known = [t for t in seen if t is not None]
    return guard.guard(billed, now=now, autostop_s=autostop_s, edge_idle_since=max(known) if known else None)


def kept_network_usd_per_hour(plan: Plan) -> float:
    """A kept network costs its Client VPN association (VPC, subnets and gateways are free)."""
    return catalog().vpn_association_usd_per_hour if plan.vpn is not None else 0.0


def pinned_host_keys(stack: str, instance_id: str, *, fetch: Callable[[], tuple[str, ...]]) -> tuple[str, ...]:
    """The instance's SSH host keys as first pinned from its console; read from the console only once.

    cloud-init prints them on the first boot only, so an instance autostop stopped and ``up``
    started again is known by the keys recorded then (same instance id, same disk, same keys).
    """
    state = StackState(stack)
    recorded = state.read(HOST_KEYS_FILE) or {}
    if recorded.get(instance_id):
        return tuple(recorded[instance_id])
    found = fetch()
    state.write(HOST_KEYS_FILE, {**recorded, instance_id: list(found)})
    return found


def access_from_outputs(plan: Plan, outputs: Mapping[str, Any], *, fingerprints: Callable[[str], tuple[str, ...]]
                        ) -> tuple[dict[str, SshAccess], dict[str, str]]:
    """SSH access (host keys pinned from each console) and relay addresses from the stack outputs.

    In vpn mode the edge reaches a host's private address through the Client VPN; in proxy mode
    its public address, which the security group opens to ``ssh_from`` only.
    """
    key = StackState(plan.stack).ssh_dir / SSH_KEY
    hosts = outputs.get("compute", {}).get("hosts", {})
    access: dict[str, SshAccess] = {}
    connect: dict[str, str] = {}
    for spec in plan.hosts:
        out = hosts.get(spec.name)
        if not out or not out.get("public_ip"):
            raise ProvisionError(f"host {spec.name}: the compute stack reported no public address")
        access[spec.name] = SshAccess(address=out["public_ip"], user=SSH_USER, key=key,
                                      fingerprints=fingerprints(out["instance_id"]))
        route = next(r for r in plan.routes if r.host == spec.name)
        via = out["private_ip"] if route.connect_via == "private" else out["public_ip"]
        connect[spec.name] = f"{via}:{route.port}"
    return access, connect


AWS = AwsTarget()
