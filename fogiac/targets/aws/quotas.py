"""Can the account run the plan: EC2 vCPU quotas per instance family, read before anything is created.

EC2 limits running vCPUs per region and per *quota family* (standard A/C/D/H/I/M/R/T/Z, G and VT,
P, X, ...), separately for on-demand and spot; a new account often allows 0 G or P vCPUs, so a
plan with one ``g5.xlarge`` fails at create time with ``VcpuLimitExceeded`` after the network is
up. :func:`check` groups a plan's machines by quota family, reads each family's quota from Service
Quotas (``GetServiceQuota``, falling back to ``GetAWSDefaultServiceQuota`` when the account has no
applied value) and, optionally, the vCPUs already running (``DescribeInstances``), and returns one
:class:`Shortfall` per machine that would not fit, each saying how to ask for more in one line.

The quota codes are AWS's (Service Quotas, service code ``ec2``), the same in every region; checked
2026-11-26 against public uses. (L-7212CCBC is the *P spot* quota; the X family's are L-7295265B
and L-E3A00192.) LocalStack has no Service Quotas: tests use botocore's Stubber.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from fogiac.errors import CloudError
from fogiac.extras import need
from fogiac.plan.model import Plan
from fogiac.targets.aws import api
from fogiac.targets.base import Check

SERVICE = "ec2"


class QuotaUnavailable(CloudError):
    """Service Quotas could not be read (no permission, or not reachable)."""


@dataclass(frozen=True)
class QuotaFamily:
    name: str
    label: str  # as the Service Quotas console names it
    on_demand: str  # quota code for running on-demand vCPUs
    spot: str | None  # quota code for spot vCPUs (None where EC2 offers no spot)

    def code(self, *, spot: bool) -> str | None:
        return self.spot if spot else self.on_demand


FAMILIES: Mapping[str, QuotaFamily] = {f.name: f for f in (
    QuotaFamily("standard", "Standard (A, C, D, H, I, M, R, T, Z)", "L-1216C47A", "L-34B43A08"),
    QuotaFamily("g", "G and VT", "L-DB2E81BA", "L-3819A6DF"),
    QuotaFamily("p", "P", "L-417A185B", "L-7212CCBC"),
    QuotaFamily("x", "X", "L-7295265B", "L-E3A00192"),
    QuotaFamily("f", "F", "L-74FC7D96", "L-88CF9481"),
    QuotaFamily("inf", "Inf", "L-1945791B", "L-B5D1601B"),
    QuotaFamily("trn", "Trn", "L-2C3B7624", "L-5480EFD2"),
    QuotaFamily("dl", "DL", "L-6E869C2A", "L-85EED4F7"),
    QuotaFamily("highmem", "High Memory", "L-43DA4232", None),
)}
_BY_PREFIX = {"g": "g", "vt": "g", "p": "p", "x": "x", "f": "f", "inf": "inf", "trn": "trn", "dl": "dl",
              "u": "highmem"}
_PREFIX = re.compile(r"^[a-z]+")


def family_of(instance_type: str) -> QuotaFamily:
    """The quota family that meters ``instance_type``: by its leading letters (``dl1`` is DL, not D)."""
    match = _PREFIX.match(instance_type.strip().lower())
    return FAMILIES[_BY_PREFIX.get(match.group(0) if match else "", "standard")]


@dataclass(frozen=True)
class Machine:
    """One machine the plan would create."""

    name: str  # the node or host name, as the plan shows it
    instance_type: str
    vcpus: int
    spot: bool = False


@dataclass(frozen=True)
class Quota:
    family: QuotaFamily
    spot: bool
    code: str
    limit: float | None  # None: unknown (lookup failed); never read as 0
    in_use: float = 0.0
    default: bool = False  # the AWS default, not a value applied to this account


@dataclass(frozen=True)
class Shortfall:
    """A machine that would push its family past the quota."""

    machine: Machine
    quota: Quota
    needed: float  # vCPUs of this family the plan reaches with this machine, plus those in use
    region: str

    def line(self) -> str:
        q, kind = self.quota, "spot" if self.quota.spot else "on-demand"
        desired = int(self.needed)
        return (f"{self.machine.name} ({self.machine.instance_type}, {self.machine.vcpus} vCPU) would exceed the "
                f"{kind} {q.family.label} vCPU quota in {self.region}: {q.code} allows {q.limit:g}"
                f"{f', {q.in_use:g} in use' if q.in_use else ''}, the plan needs {desired}; ask for more: "
                f"aws service-quotas request-service-quota-increase --region {self.region} --service-code ec2 "
                f"--quota-code {q.code} --desired-value {desired}")


def demand(machines: Iterable[Machine]) -> dict[tuple[str, bool], list[Machine]]:
    """The plan's machines grouped by (quota family, spot), in plan order."""
    groups: dict[tuple[str, bool], list[Machine]] = {}
    for m in machines:
        groups.setdefault((family_of(m.instance_type).name, m.spot), []).append(m)
    return groups


def _code(err: Any) -> str:
    return str(getattr(err, "response", {}).get("Error", {}).get("Code", ""))


def read_quota(client: Any, family: QuotaFamily, *, spot: bool, region: str) -> Quota | None:
    """The family's vCPU quota; the AWS default where the account has none applied; None if EC2 has
    no such quota (no spot for High Memory)."""
    code = family.code(spot=spot)
    if code is None:
        return None
    errors = need("botocore.exceptions")
    try:
        value = client.get_service_quota(ServiceCode=SERVICE, QuotaCode=code)["Quota"]["Value"]
        return Quota(family, spot, code, float(value))
    except errors.ClientError as err:
        if _code(err) != "NoSuchResourceException":
            raise _unavailable(err, region) from None
    except errors.BotoCoreError as err:
        raise QuotaUnavailable(f"cannot read EC2 vCPU quotas in {region}: {err}") from None
    try:
        value = client.get_aws_default_service_quota(ServiceCode=SERVICE, QuotaCode=code)["Quota"]["Value"]
        return Quota(family, spot, code, float(value), default=True)
    except errors.ClientError as err:
        if _code(err) == "NoSuchResourceException":
            return Quota(family, spot, code, None)
        raise _unavailable(err, region) from None


def _unavailable(err: Any, region: str) -> QuotaUnavailable:
    code = _code(err)
    if code in {"AccessDeniedException", "AccessDenied", "UnauthorizedOperation"}:
        return QuotaUnavailable(f"cannot read EC2 vCPU quotas in {region}: the credentials lack "
                                "servicequotas:GetServiceQuota (add it, or skip the check)")
    return QuotaUnavailable(f"cannot read EC2 vCPU quotas in {region}: {code or err}")


def in_use(ec2: Any) -> dict[tuple[str, bool], float]:
    """vCPUs already running or pending, per (quota family, spot): they count against the same quota."""
    used: dict[tuple[str, bool], float] = {}
    pages = ec2.get_paginator("describe_instances").paginate(
        Filters=[{"Name": "instance-state-name", "Values": ["pending", "running"]}])
    for page in pages:
        for reservation in page.get("Reservations", []):
            for inst in reservation.get("Instances", []):
                cpu = inst.get("CpuOptions", {})
                vcpus = cpu.get("CoreCount", 0) * cpu.get("ThreadsPerCore", 1)
                key = (family_of(inst["InstanceType"]).name, inst.get("InstanceLifecycle") == "spot")
                used[key] = used.get(key, 0.0) + vcpus
    return used


def check(machines: Sequence[Machine], *, region: str, quotas: Any, ec2: Any = None) -> list[Shortfall]:
    """Every machine that would not fit its family's vCPU quota in ``region``, in plan order.

    ``quotas`` is a Service Quotas client for ``region``; with ``ec2``, vCPUs already running count
    too. A quota that cannot be known is not read as 0: its machines pass.
    """
    running = in_use(ec2) if ec2 is not None else {}
    short: list[Shortfall] = []
    for (name, spot), group in demand(machines).items():
        quota = read_quota(quotas, FAMILIES[name], spot=spot, region=region)
        if quota is None or quota.limit is None:
            continue
        used = running.get((name, spot), 0.0)
        limit = quota.limit
        quota = Quota(quota.family, spot, quota.code, limit, used, quota.default)
        total = used
        for m in group:
            total += m.vcpus
            if total > limit:
                short.append(Shortfall(m, quota, total, region))
    return short


def report(shortfalls: Iterable[Shortfall]) -> list[str]:
    return [s.line() for s in shortfalls]


def for_plan(plan: Plan, *, quotas: Any = None, ec2: Any = None) -> list[Shortfall]:
    """:func:`check` over the plan's hosts, in the plan's region (``quotas``: a Service Quotas client,
    made from the user's credentials when not given)."""
    if quotas is None:
        quotas = api.client("service-quotas", region=plan.region)
    machines = [Machine(h.name, h.machine, h.vcpus, spot=h.spot) for h in plan.hosts]
    return check(machines, region=plan.region, quotas=quotas, ec2=ec2)


def doctor_checks(plan: Plan, *, quotas: Any = None, ec2: Any = None) -> list[Check]:
    """``fogiac doctor``'s lines: each machine that would exceed its quota, or that all fit; a quota
    that cannot be read is said, not failed (the create would still tell)."""
    try:
        short = for_plan(plan, quotas=quotas, ec2=ec2)
    except QuotaUnavailable as err:
        return [Check("vCPU quotas", True, f"not checked: {err}")]
    if not short:
        families = sorted({family_of(h.machine).label for h in plan.hosts})
        return [Check("vCPU quotas", True, f"the plan fits {', '.join(families)}" if families else "no machines")]
    return [Check("vCPU quotas", False, line) for line in report(short)]
