"""The ``aws`` target: EC2 instances in a VPC of their own, reached through a Client VPN or,
in proxy mode, over the relay's mutual TLS to public addresses open only to ``ssh_from``.

Pulumi creates and deletes (:mod:`.engine`, programs in ``stacks/``); boto3 checks before,
reports during and proves after (:mod:`.api`, :mod:`.sweep`). Offline, the same programs run
under Pulumi's mocks (:mod:`.offline`) so ``fogiac plan`` needs no credentials. This folder is
the only code in fogiac that imports boto3, pulumi, pulumi_aws or ``stacks``.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

from fogiac.certs import SSH_KEY, load_or_create_bundle
from fogiac.errors import CloudError, FogiacError, ProvisionError
from fogiac.manifest.schema import Manifest
from fogiac.net.vpn import write_client_profile
from fogiac.orchestrate import ensure_edge_master, provision_and_connect, stop_edge
from fogiac.plan.catalog import catalog
from fogiac.plan.document import APPLIED_FILE, plan_document
from fogiac.plan.model import Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.provision import SshAccess
from fogiac.provision.runner import KNOWN_HOSTS
from fogiac.state import read_json, stack_dir, stack_lock, write_json_atomic
from fogiac.tables import table
from fogiac.targets.aws import api, engine, offline, placement
from fogiac.targets.aws import sweep as sweeping
from fogiac.targets.base import (
    Check,
    DownOptions,
    DownResult,
    Refreshed,
    SweepOutcome,
    UpOptions,
    UpResult,
    untouched_on_failure,
)

COMPUTE_KINDS = ("instance", "key-pair", "network-interface")  # what --keep-network still sweeps
SSH_USER = "ubuntu"  # the login of both images compile chooses (Ubuntu, AWS Deep Learning Base)


class AwsTarget:
    name = "aws"
    summary = "EC2 machines in their own VPC, through a Client VPN (or proxy mode), made with Pulumi"
    makes_resources = True

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        return placement.place(manifest, stack=stack, tags=tags)

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return tuple(r.to_dict() for r in offline.declare(plan).resources if r.custom)

    # -- up ---------------------------------------------------------------------------------------

    def up(self, plan: Plan, opts: UpOptions) -> UpResult:
        engine.pulumi_cli()  # before any state is touched
        # applied.json is the same document `fogiac plan` builds from the compiled plan, so that
        # `plan --detailed-exitcode` compares like with like; the zone actually used is in outputs.json.
        doc = plan_document(plan, self.declare(plan), manifest=opts.manifest_path)
        with untouched_on_failure(plan.stack) as commit, stack_lock(plan.stack, operation="up"):
            recorded = read_json(stack_dir(plan.stack) / engine.OUTPUTS_FILE) or {}
            if recorded.get("zone") and not plan.zone_chosen:  # keep the subnets where they are
                plan = dataclasses.replace(plan, zone=recorded["zone"], zone_chosen=True)
            report = api.preflight(plan, operator_cidr=opts.ssh_from, known_ids=engine.known_ids(plan.stack))
            plan = dataclasses.replace(plan, zone=report.zone)
            opts.show(doc, report)
            if plan.vpn is not None:
                opts.announce(engine.VPN_NOTICE)
            question = f"Create these resources in {plan.region} (${plan.hourly_usd:.4f}/h)?"
            if not opts.yes and not opts.confirm(question):
                raise FogiacError("not applied: nothing was changed")
            master = opts.edge_master or plan.edge_master
            if not opts.infra_only:  # before money is spent: the robot's side must be there to connect
                ensure_edge_master(plan, master, start=opts.start_edge_master)
            commit()
            outputs = engine.Engine(plan, on_event=opts.on_event).up(operator_cidrs=report.operator_cidrs)
            folder = stack_dir(plan.stack)
            write_json_atomic(folder / engine.OUTPUTS_FILE, {"zone": plan.zone, **outputs})
            write_json_atomic(folder / APPLIED_FILE, doc)
            if opts.infra_only:
                return UpResult(outputs=outputs, applied=folder / APPLIED_FILE)
            done = self._connect(plan, outputs, master=master, announce=opts.announce)
            return UpResult(outputs=outputs, applied=folder / APPLIED_FILE, report=done.report,
                            relays=done.relays, edge_master=master)

    def _connect(self, plan: Plan, outputs: Mapping[str, Any], *, master: str,
                 announce: Callable[[str], None]) -> Any:
        """After the stacks: the edge's VPN profile, then provisioning and relays as on every target."""
        if plan.vpn is not None:
            profile = write_client_profile(
                endpoint_dns=outputs["network"]["vpn_dns_name"], stack=plan.stack,
                bundle=load_or_create_bundle(plan.stack, stack_dir(plan.stack) / "certs"))
            announce(f"VPN profile: {profile} (connect with: sudo fogiac vpn up; the relays retry until it is up)")
        announce("waiting for each instance to print its SSH host keys on its console (pinned, never trusted on sight)")
        access, connect = access_from_outputs(
            plan, outputs, fingerprints=lambda iid: api.host_fingerprints(iid, region=plan.region))
        return provision_and_connect(plan, access=access, connect=connect, master=master)

    # -- down -------------------------------------------------------------------------------------

    def down(self, plan: Plan, opts: DownOptions) -> DownResult:
        engine.pulumi_cli()
        api.identity(region=plan.region)  # missing credentials: one line, before anything is destroyed
        with untouched_on_failure(plan.stack), stack_lock(plan.stack, operation="down"):
            stop_edge(plan)  # the edge relays first: their peers are about to go
            layers = ("compute",) if opts.keep_network else ("compute", "network")
            errors = engine.Engine(plan, on_event=opts.on_event).destroy(layers=layers)
            result = self._sweep(plan, dry_run=False, kinds=COMPUTE_KINDS if opts.keep_network else None)
            folder = stack_dir(plan.stack)
            if not result.left:
                (folder / APPLIED_FILE).unlink(missing_ok=True)
                # The instances are gone and their public addresses go back to AWS's pool.
                (folder / KNOWN_HOSTS).unlink(missing_ok=True)
                outputs = read_json(folder / engine.OUTPUTS_FILE) or {}
                if opts.keep_network and outputs:
                    kept = {k: v for k, v in outputs.items() if k != "compute"}
                    write_json_atomic(folder / engine.OUTPUTS_FILE, kept)
                else:
                    (folder / engine.OUTPUTS_FILE).unlink(missing_ok=True)
            return DownResult(
                engine_errors=tuple(errors), left=tuple(str(f) for f in result.left),
                not_checked=result.not_checked, deleted=tuple(str(f) for f in result.deleted),
                kept_usd_per_hour=kept_network_usd_per_hour(plan) if opts.keep_network else None,
            )

    # -- status, doctor, refresh, sweep ---------------------------------------------------------------

    def status(self, plan: Plan) -> dict[str, Any]:
        rows = api.status(plan.stack, region=plan.region)
        return {"stack": plan.stack, "target": plan.target, "region": plan.region, "hosts": [
            {"host": r.name, "instance_id": r.instance_id, "state": r.state, "machine": r.machine,
             "public_ip": r.public_ip, "private_ip": r.private_ip, "launched": r.launched.isoformat(),
             "uptime_s": round(r.uptime_s), "cost_usd": r.cost_usd} for r in rows]}

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        if not doc["hosts"]:
            return [f"{doc['stack']}: no instances"]
        out = table(f"{doc['stack']} ({doc['region']})", "host", "instance", "state", "type", "public", "private",
                    "uptime", "cost so far")
        for h in doc["hosts"]:
            out.add_row(h["host"], h["instance_id"], h["state"], h["machine"], h["public_ip"] or "-",
                        h["private_ip"] or "-", f"{h['uptime_s'] / 3600:.1f} h", f"${h['cost_usd']:.2f}")
        return [out]

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """Every check ``up`` would make, each as (what, ok, detail); nothing is created."""
        checks: list[Check] = []
        try:
            checks.append(Check("Pulumi CLI", True, str(engine.pulumi_cli())))
        except CloudError as err:
            checks.append(Check("Pulumi CLI", False, str(err)))
        known = engine.known_ids(plan.stack) if stack_dir(plan.stack, create=False).exists() else frozenset()
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
        ]

    def refresh(self, plan: Plan) -> list[Refreshed]:
        with stack_lock(plan.stack, operation="refresh"):
            return [Refreshed(r.layer, r.ok, r.summary) for r in engine.Engine(plan).refresh()]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        # Deleting takes the stack's lock, so a sweep cannot delete what a running up is creating;
        # a dry run only lists.
        with contextlib.nullcontext() if dry_run else stack_lock(plan.stack, operation="sweep"):
            result = self._sweep(plan, dry_run=dry_run)
        return SweepOutcome(found=tuple(map(str, result.found)), deleted=tuple(map(str, result.deleted)),
                            left=tuple(map(str, result.left)), errors=result.errors, not_checked=result.not_checked)

    def _sweep(self, plan: Plan, *, dry_run: bool, kinds: tuple[str, ...] | None = None) -> sweeping.SweepResult:
        return sweeping.sweep(plan.stack, ec2=api.client("ec2", region=plan.region),
                              acm=api.client("acm", region=plan.region), dry_run=dry_run, kinds=kinds)


def kept_network_usd_per_hour(plan: Plan) -> float:
    """A kept network costs its Client VPN association (VPC, subnets and gateways are free)."""
    return catalog().vpn_association_usd_per_hour if plan.vpn is not None else 0.0


def access_from_outputs(plan: Plan, outputs: Mapping[str, Any], *, fingerprints: Callable[[str], tuple[str, ...]]
                        ) -> tuple[dict[str, SshAccess], dict[str, str]]:
    """SSH access (host keys pinned from each console) and relay addresses from the stack outputs.

    In vpn mode the edge reaches a host's private address through the Client VPN; in proxy mode
    its public address, which the security group opens to ``ssh_from`` only.
    """
    key = stack_dir(plan.stack) / "ssh" / SSH_KEY
    hosts = outputs.get("compute", {}).get("hosts", {})
    access: dict[str, SshAccess] = {}
    connect: dict[str, str] = {}
    for spec in plan.hosts:
        out = hosts.get(spec.name)
        if not out or not out.get("public_ip"):
            raise ProvisionError(f"host {spec.name}: the compute stack reported no public address")
        access[spec.name] = SshAccess(address=out["public_ip"], user=SSH_USER, key=key,
                                      fingerprints=fingerprints(out["instance_id"]))
        route = next(r for r in plan.relay if r.host == spec.name)
        via = out["private_ip"] if route.connect_via == "private" else out["public_ip"]
        connect[spec.name] = f"{via}:{route.port}"
    return access, connect


AWS = AwsTarget()
