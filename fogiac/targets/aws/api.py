"""Everything fogiac asks AWS directly (the only module that imports boto3).

Pulumi creates and deletes; this module checks before (``preflight``), reports during
(``status``) and proves after (``sweep`` in :mod:`fogiac.targets.aws.sweep`, which gets its clients here).
Clients are parameters so tests pass LocalStack's; by default they come from a boto3 session
that honours the standard ``AWS_*`` variables, ``AWS_ENDPOINT_URL`` included.
"""

from __future__ import annotations

import datetime as _dt
import ipaddress
import os
import re
import time
import urllib.request
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from fogiac.errors import CloudError, CredentialsError, PreflightError
from fogiac.manifest.schema import ssh_from_problem
from fogiac.plan.model import OPERATOR, Plan
from fogiac.targets.aws.catalog import on_demand, spot_price
from fogiac.targets.aws.model import ImageQuery, image_of
from fogiac.targets.aws.sdk import need
from stacks.aws import HOST_KEYS_BEGIN, HOST_KEYS_END

STACK_TAG = "fogiac:stack"
NODE_TAG = "fogiac:node"
HOST_TAG = "fogiac:host"  # on a replica's instance (its host is <node>-rN); every other host is its node's name


def host_of(tags: Mapping[str, str], default: str = "") -> str:
    """The plan's host an instance is: its fogiac:host tag (a replica), else its fogiac:node tag."""
    return tags.get(HOST_TAG) or tags.get(NODE_TAG) or default
OPERATOR_ENV = "FOGIAC_OPERATOR_CIDR"
CHECKIP_URL = "https://checkip.amazonaws.com"
_NO_CREDENTIALS = (
    "no AWS credentials found: set AWS_PROFILE, or AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY, "
    "or run `aws configure`"
)


def client(service: str, *, region: str) -> Any:
    """A boto3 client for ``service`` in ``region``; short timeouts so a dead endpoint fails fast."""
    boto3 = need("boto3")
    config = need("botocore.config").Config(connect_timeout=5, read_timeout=30,
                                             retries={"max_attempts": 3, "mode": "standard"})
    return boto3.session.Session(region_name=region).client(service, config=config)


def known_regions() -> frozenset[str]:
    """Regions botocore knows for EC2 (offline: from its bundled endpoint data)."""
    session = need("boto3").session.Session()
    names: set[str] = set()
    for partition in session.get_available_partitions():
        names.update(session.get_available_regions("ec2", partition_name=partition))
    return frozenset(names)


def error_code(err: BaseException) -> str:
    """The AWS error code of a botocore ClientError (``""`` for anything else)."""
    response = getattr(err, "response", None)
    if isinstance(response, dict):
        return str(response.get("Error", {}).get("Code", ""))
    return ""


def _call(fn: Any, /, **kwargs: Any) -> Any:
    """Call an AWS API, turning credential failures into one CredentialsError line."""
    errors = need("botocore.exceptions")
    try:
        return fn(**kwargs)
    except (errors.NoCredentialsError, errors.PartialCredentialsError):
        raise CredentialsError(_NO_CREDENTIALS) from None
    except errors.ClientError as err:
        code = error_code(err)
        if code in {"InvalidClientTokenId", "SignatureDoesNotMatch", "UnrecognizedClientException",
                    "AuthFailure", "ExpiredToken", "ExpiredTokenException"}:
            raise CredentialsError(f"AWS rejected the credentials ({code}): {err}") from None
        raise
    except errors.EndpointConnectionError as err:
        raise CloudError(f"cannot reach AWS: {err}") from None
    except errors.BotoCoreError as err:
        raise CloudError(f"AWS call failed: {err}") from None


def paginate(api: Any, operation: str, key: str, **kwargs: Any) -> list[Any]:
    """Every item under ``key`` across all pages of ``operation`` (one call if it has no pages)."""
    if not api.can_paginate(operation):
        return list(_call(getattr(api, operation), **kwargs).get(key, []))

    def every_page() -> list[Any]:  # pages are fetched while iterating: errors surface here
        return [item for page in api.get_paginator(operation).paginate(**kwargs) for item in page.get(key, [])]

    return list(_call(every_page))


def tag_filter(stack: str) -> list[dict[str, Any]]:
    return [{"Name": f"tag:{STACK_TAG}", "Values": [stack]}]


def tags_of(item: dict[str, Any]) -> dict[str, str]:
    return {t["Key"]: t["Value"] for t in item.get("Tags", []) or []}


@dataclass(frozen=True)
class PreflightReport:
    """What preflight found: where to deploy and with what, plus warnings that do not block."""

    account: str
    region: str
    zone: str
    images: tuple[tuple[str, str], ...]  # (host name, AMI id)
    operator_cidrs: tuple[str, ...]  # ssh_from with the operator's address filled in
    warnings: tuple[str, ...] = ()

    def image(self, host: str) -> str:
        return dict(self.images)[host]


def operator_cidrs(plan: Plan, *, override: str | None = None, fetch: bool = True) -> tuple[str, ...]:
    """``plan.ssh_from`` with the OPERATOR placeholder replaced by the operator's /32.

    The override (``--ssh-from``, else ``$FOGIAC_OPERATOR_CIDR``) wins; otherwise one short
    HTTPS GET to checkip asks what address AWS sees. Tests always pass an override.
    """
    if OPERATOR not in plan.ssh_from:
        return plan.ssh_from
    given = override or os.environ.get(OPERATOR_ENV)
    if given:
        try:
            mine = str(ipaddress.IPv4Network(given.strip(), strict=False))
        except ValueError:
            raise PreflightError(f"--ssh-from {given!r} is not an address or CIDR") from None
    elif not fetch:
        raise PreflightError(f"ssh_from: auto needs your address: pass --ssh-from CIDR or set {OPERATOR_ENV}")
    else:
        try:
            with urllib.request.urlopen(CHECKIP_URL, timeout=5) as response:  # noqa: S310 (fixed https URL)
                address = response.read().decode().strip()
            mine = str(ipaddress.ip_network(f"{address}/32"))
        except (OSError, ValueError) as err:
            raise PreflightError(
                f"ssh_from: auto could not learn your public address from {CHECKIP_URL} ({err}); "
                f"pass --ssh-from CIDR or set {OPERATOR_ENV}"
            ) from None
    cidrs = tuple(mine if cidr == OPERATOR else cidr for cidr in plan.ssh_from)
    problem = ssh_from_problem(ipaddress.IPv4Network(c) for c in cidrs)  # --ssh-from may be as wide as any
    if problem:
        raise PreflightError(f"ssh_from: {problem}")
    return cidrs


def _zones(ec2: Any, types: Sequence[str]) -> dict[str, set[str]]:
    """zone -> the requested types it offers."""
    zones: dict[str, set[str]] = {
        z["ZoneName"]: set()
        for z in _call(ec2.describe_availability_zones, Filters=[{"Name": "state", "Values": ["available"]}])[
            "AvailabilityZones"
        ]
        if z.get("ZoneType", "availability-zone") == "availability-zone"
    }
    offers = paginate(ec2, "describe_instance_type_offerings", "InstanceTypeOfferings",
                      LocationType="availability-zone",
                      Filters=[{"Name": "instance-type", "Values": list(types)}])
    for offer in offers:
        if offer["Location"] in zones and offer["InstanceType"] in types:
            zones[offer["Location"]].add(offer["InstanceType"])
    return zones


def choose_zone(plan: Plan, offered: dict[str, set[str]], problems: list[str]) -> str:
    """The manifest's zone if it offers every type, else the first zone (sorted) that does. A replica's
    host has a zone of its own (checked here too); the plan's zone is chosen for the others."""
    for host in plan.hosts:
        if host.zone is not None and host.machine not in offered.get(host.zone, set()):
            where = "is not an available zone of " + plan.region if host.zone not in offered else \
                f"does not offer {host.machine}"
            problems.append(f"{host.name}: zone {host.zone} {where} (replicas go to zones of their own; "
                            "`fogiac catalog update` refreshes which zones offer what)")
    wanted = sorted({h.machine for h in plan.hosts if h.zone is None})
    if not wanted:
        return plan.zone  # every host a replica in its own zone: the plan's zone holds only the VPN's subnet
    if plan.zone_chosen:
        missing = [t for t in wanted if t not in offered.get(plan.zone, set())]
        if plan.zone not in offered:
            problems.append(f"zone {plan.zone} is not an available zone of {plan.region}")
        elif missing:
            elsewhere = sorted(z for z, types in offered.items() if set(wanted) <= types)
            hint = f" (zones that do: {', '.join(elsewhere)})" if elsewhere else ""
            problems.append(f"zone {plan.zone} does not offer {', '.join(missing)}{hint}")
        return plan.zone
    for zone in sorted(offered):
        if set(wanted) <= offered[zone]:
            return zone
    anywhere = set().union(*offered.values()) if offered else set()
    absent = [t for t in wanted if t not in anywhere]
    if absent:
        problems.append(f"machine type {', '.join(absent)} is not offered in {plan.region}")
    else:
        problems.append(f"no zone of {plan.region} offers {', '.join(wanted)} together; "
                        "split the nodes across manifests")
    return plan.zone


def _check_gpus(ec2: Any, plan: Plan, problems: list[str]) -> None:
    types = sorted({h.machine for h in plan.hosts})
    try:
        found = {t["InstanceType"]: t for t in paginate(ec2, "describe_instance_types", "InstanceTypes",
                                                        InstanceTypes=types)}
    except Exception as err:  # an unknown type fails the whole call; offerings already named it
        if error_code(err).startswith("InvalidInstanceType"):
            return
        raise
    for host in plan.hosts:
        info = found.get(host.machine)
        if info is None:
            continue
        gpus = sum(g.get("Count", 0) for g in info.get("GpuInfo", {}).get("Gpus", []))
        if gpus != host.gpus:
            problems.append(f"host {host.name}: {host.machine} has {gpus} GPU(s) in {plan.region}, "
                            f"the plan expects {host.gpus}")


def resolve_image(ec2: Any, query: ImageQuery) -> str | None:
    """The newest available AMI matching ``query`` (owners and name pattern), or None."""
    images = paginate(ec2, "describe_images", "Images", Owners=list(query.owners),
                      Filters=[{"Name": "name", "Values": [query.name_pattern]},
                               {"Name": "state", "Values": ["available"]}])
    if not images:
        return None
    return str(max(images, key=lambda i: (i.get("CreationDate", ""), i["ImageId"]))["ImageId"])


def conflicts(ec2: Any, stack: str, *, known_ids: Collection[str]) -> list[str]:
    """VPCs and live instances tagged with ``stack`` whose ids fogiac's state does not know."""
    vpcs = [v["VpcId"] for v in paginate(ec2, "describe_vpcs", "Vpcs", Filters=tag_filter(stack))]
    instances = [
        i["InstanceId"]
        for r in paginate(ec2, "describe_instances", "Reservations",
                          Filters=tag_filter(stack) + [{"Name": "instance-state-name",
                                                        "Values": ["pending", "running", "stopping", "stopped"]}])
        for i in r["Instances"]
    ]
    return [rid for rid in vpcs + instances if rid not in known_ids]


def preflight(plan: Plan, *, ec2: Any = None, sts: Any = None, operator_cidr: str | None = None,
              known_ids: Collection[str] = (), fetch_address: bool = True) -> PreflightReport:
    """Check everything that can fail before money is spent; raise one PreflightError listing all."""
    if plan.region not in known_regions():
        raise PreflightError(f"unknown AWS region {plan.region!r}")
    sts = sts or client("sts", region=plan.region)
    ec2 = ec2 or client("ec2", region=plan.region)
    identity = _call(sts.get_caller_identity)
    problems: list[str] = []
    enabled = {r["RegionName"]: r.get("OptInStatus", "opt-in-not-required")
               for r in _call(ec2.describe_regions, AllRegions=True)["Regions"]}
    if plan.region not in enabled:
        raise PreflightError(f"unknown AWS region {plan.region!r} (not in this account's region list)")
    if enabled[plan.region] == "not-opted-in":
        raise PreflightError(f"region {plan.region} is not enabled for account {identity['Account']}")
    zone = plan.zone
    images: list[tuple[str, str]] = []
    if plan.hosts:
        zone = choose_zone(plan, _zones(ec2, sorted({h.machine for h in plan.hosts})), problems)
        _check_gpus(ec2, plan, problems)
        resolved: dict[ImageQuery, str | None] = {}
        for host in plan.hosts:
            image = image_of(host)
            if image is None:
                continue
            if image not in resolved:
                resolved[image] = resolve_image(ec2, image)
                if resolved[image] is None:
                    problems.append(f"no AMI matches {image.description} ({image.name_pattern!r}, "
                                    f"owners {', '.join(image.owners)}) in {plan.region}")
            if ami := resolved[image]:
                images.append((host.name, ami))
    strangers = conflicts(ec2, plan.stack, known_ids=known_ids)
    if strangers:
        problems.append(f"stack {plan.stack} already has resources outside fogiac's state "
                        f"({', '.join(strangers[:5])}{' ...' if len(strangers) > 5 else ''}); "
                        f"run `fogiac sweep` on this manifest or use another --env")
    try:
        cidrs = operator_cidrs(plan, override=operator_cidr, fetch=fetch_address)
    except PreflightError as err:
        problems.append(str(err))
        cidrs = plan.ssh_from
    if problems:
        raise PreflightError("\n".join(problems))
    return PreflightReport(account=str(identity["Account"]), region=plan.region, zone=zone,
                           images=tuple(images), operator_cidrs=cidrs)


@dataclass(frozen=True)
class InstanceStatus:
    name: str
    instance_id: str
    state: str
    machine: str
    public_ip: str | None
    private_ip: str | None
    launched: _dt.datetime  # AWS moves it on every start: the running stretch's beginning
    uptime_s: float
    cost_usd: float | None  # None: the price is unknown (the catalogue has none in the region)
    usd_per_hour: float | None = 0.0  # what it costs now (0 while stopped, disk not counted); None: unknown
    stopped_at: _dt.datetime | None = None
    stopped_by: str = ""  # "the instance" (autostop's poweroff), "a user", or "" while running
    spot: bool = False  # bought on the spot market, as EC2 reports it (after any fallback to on-demand)
    spot_estimate: bool = False  # usd_per_hour and cost_usd are the catalogue's spot estimate, not a list price


_STOPPED_AT = re.compile(r"\((\d{4}-\d\d-\d\d \d\d:\d\d:\d\d) (?:GMT|UTC)\)")  # AWS says GMT, moto UTC
_STOPPED_BY = {"Client.InstanceInitiatedShutdown": "the instance", "Client.UserInitiatedShutdown": "a user"}


def stop_time(inst: dict[str, Any]) -> tuple[_dt.datetime | None, str]:
    """When and by whom a stopped instance stopped, from AWS's ``StateTransitionReason`` and ``StateReason``.

    AWS writes ``User initiated (2026-11-23 12:03:10 GMT)`` for every stop; the state reason's
    code tells a poweroff from inside (autostop) from a console click or API call.
    """
    if inst["State"]["Name"] not in {"stopping", "stopped"}:
        return None, ""
    found = _STOPPED_AT.search(inst.get("StateTransitionReason") or "")
    when = (_dt.datetime.strptime(found.group(1), "%Y-%m-%d %H:%M:%S").replace(tzinfo=_dt.timezone.utc)
            if found else None)
    return when, _STOPPED_BY.get((inst.get("StateReason") or {}).get("Code", ""), "")


def status(stack: str, *, region: str, ec2: Any = None,
           now: _dt.datetime | None = None) -> list[InstanceStatus]:
    """The stack's instances (not terminated), with uptime and cost so far at catalogue prices: a spot
    instance (EC2's ``InstanceLifecycle``, so one that fell back to on-demand is not) at the spot
    estimate, any other, or a spot type without an estimate, at on-demand."""
    ec2 = ec2 or client("ec2", region=region)
    now = now or _dt.datetime.now(_dt.timezone.utc)
    rows = []
    for reservation in paginate(ec2, "describe_instances", "Reservations", Filters=tag_filter(stack)):
        for inst in reservation["Instances"]:
            state = inst["State"]["Name"]
            if state == "terminated":
                continue
            launched = inst["LaunchTime"]
            running = state in {"pending", "running", "stopping"}
            uptime = max(0.0, (now - launched).total_seconds()) if running else 0.0
            spot = inst.get("InstanceLifecycle") == "spot"
            estimate = spot_price(inst["InstanceType"], region) if spot else None
            price = on_demand(inst["InstanceType"], region) if estimate is None else estimate
            tags = tags_of(inst)
            stopped_at, stopped_by = stop_time(inst)
            rows.append(InstanceStatus(
                name=host_of(tags, tags.get("Name", inst["InstanceId"])), instance_id=inst["InstanceId"],
                state=state, machine=inst["InstanceType"], public_ip=inst.get("PublicIpAddress"),
                private_ip=inst.get("PrivateIpAddress"), launched=launched, uptime_s=uptime,
                cost_usd=round(uptime / 3600 * price, 4) if price is not None else None,
                usd_per_hour=price if running else 0.0,
                stopped_at=stopped_at, stopped_by=stopped_by, spot=spot, spot_estimate=estimate is not None))
    return sorted(rows, key=lambda r: (r.name, r.instance_id))


def start_stopped(stack: str, *, region: str, known_ids: Collection[str], ec2: Any = None,
                  delay_s: int = 5, attempts: int = 120) -> list[str]:
    """Start the stack's stopped instances (autostop's poweroff) that fogiac's state knows; wait until running.

    Started, not recreated: the same instance, disk and private address come back, so the
    engine's refresh finds nothing to replace and provisioning redoes only what changed.
    Instances still stopping are waited for first (AWS refuses to start them).
    """
    ec2 = ec2 or client("ec2", region=region)
    found = [i for r in paginate(ec2, "describe_instances", "Reservations", Filters=tag_filter(stack) + [
        {"Name": "instance-state-name", "Values": ["stopping", "stopped"]}]) for i in r["Instances"]]
    ids = sorted(i["InstanceId"] for i in found if i["InstanceId"] in known_ids)
    if not ids:
        return []
    config = {"Delay": delay_s, "MaxAttempts": attempts}
    waiters = need("botocore.exceptions")
    try:
        ec2.get_waiter("instance_stopped").wait(InstanceIds=ids, WaiterConfig=config)
        _call(ec2.start_instances, InstanceIds=ids)
        ec2.get_waiter("instance_running").wait(InstanceIds=ids, WaiterConfig=config)
    except waiters.WaiterError as err:
        raise CloudError(f"starting the stopped instances {', '.join(ids)} failed: {err}") from None
    return ids


def identity(*, region: str, sts: Any = None) -> str:
    """The account the credentials belong to; CredentialsError (one line) when there are none."""
    sts = sts or client("sts", region=region)
    return str(_call(sts.get_caller_identity)["Account"])


def parse_host_fingerprints(console: str) -> tuple[str, ...]:
    """The ``SHA256:`` fingerprints the instance printed between fogiac's markers (cloud-init)."""
    start, end = console.rfind(HOST_KEYS_BEGIN), console.rfind(HOST_KEYS_END)
    if start < 0 or end < start:
        return ()
    block = console[start + len(HOST_KEYS_BEGIN):end]
    return tuple(dict.fromkeys(word for word in block.split() if word.startswith("SHA256:")))


def host_fingerprints(instance_id: str, *, region: str, ec2: Any = None, timeout: float = 900.0,
                      poll: float = 15.0, sleep: Any = None) -> tuple[str, ...]:
    """Wait until the instance's console shows its SSH host keys; pin those, never trust on sight."""
    ec2 = ec2 or client("ec2", region=region)
    sleep = sleep or time.sleep
    deadline = time.monotonic() + timeout
    while True:
        out = _call(ec2.get_console_output, InstanceId=instance_id, Latest=True).get("Output") or ""
        found = parse_host_fingerprints(out)
        if found:
            return found
        if time.monotonic() >= deadline:
            raise CloudError(f"{instance_id}: no SSH host keys on its console after {timeout:.0f} s; "
                             "refusing to connect without pinning them (is cloud-init running?)")
        sleep(poll)


def import_revocations(endpoint_id: str, crl_pem: bytes, *, region: str, ec2: Any = None) -> None:
    """Hand the Client VPN endpoint the stack's certificate revocation list (it replaces the one before);
    the endpoint refuses new connections of the certificates listed and ends theirs that are connected."""
    ec2 = ec2 or client("ec2", region=region)
    errors = need("botocore.exceptions")
    try:
        _call(ec2.import_client_vpn_client_certificate_revocation_list, ClientVpnEndpointId=endpoint_id,
              CertificateRevocationList=crl_pem.decode("ascii"))
    except errors.ClientError as err:
        raise CloudError(f"the Client VPN endpoint {endpoint_id} did not take the revocation list "
                         f"({error_code(err) or 'error'}): {err}") from None
