"""Find and delete everything a stack left in AWS, so ``down`` can prove nothing remains.

Every resource fogiac makes carries ``fogiac:stack=<stack>``; a VPC with that tag is ours
whole, so untagged things inside it (the default security group aside: AWS deletes it with the VPC
and nothing else can) count too. Log groups and IAM roles are found by where fogiac puts them:
log groups under ``/fogiac/<stack>/``, roles under the IAM path ``/fogiac/<stack>/``. Deletion
goes in dependency order and repeats with growing pauses while AWS answers "still in use";
then everything is listed again and what is left is returned, not hidden.
Clients come from :mod:`fogiac.targets.aws.api` (this module imports no AWS SDK itself).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any

from fogiac.errors import CloudError
from fogiac.targets.aws.api import STACK_TAG, error_code, paginate, tag_filter, tags_of

MANIFEST_TAG = "fogiac:manifest"  # the manifest name, on every resource compile tags

# Kinds in the order they can be deleted: users before what they use.
ORDER = (
    "client-vpn-endpoint", "flow-log", "instance", "elastic-ip", "network-interface", "security-group",
    "key-pair", "subnet", "route-table", "internet-gateway", "vpc", "acm-certificate", "log-group",
    "iam-role",
)
MAX_DELAY_S = 60.0  # 8 rounds wait about 3 minutes in all: ENIs of a deleted Client VPN take minutes to go
_GONE = {"InvalidVpcID.NotFound", "InvalidSubnetID.NotFound", "InvalidGroup.NotFound",
         "InvalidRouteTableID.NotFound", "InvalidInternetGatewayID.NotFound", "InvalidKeyPair.NotFound",
         "InvalidNetworkInterfaceID.NotFound", "InvalidAllocationID.NotFound", "InvalidInstanceID.NotFound",
         "ResourceNotFoundException", "InvalidClientVpnEndpointId.NotFound", "InvalidFlowLogId.NotFound",
         "NoSuchEntity"}
_UNSUPPORTED = {"NotImplemented", "UnsupportedOperation", "InvalidAction", "UnknownOperationException"}


def _unsupported(err: BaseException) -> bool:
    """The endpoint lacks the API (HTTP 501, or a code saying so): not an error in the resources."""
    status = getattr(err, "response", {}).get("ResponseMetadata", {}).get("HTTPStatusCode")
    return status == 501 or error_code(err) in _UNSUPPORTED


@dataclass(frozen=True, order=True)
class Found:
    kind: str
    id: str
    detail: str = ""  # what deleting needs besides the id: attached VPCs, a key pair's name

    def __str__(self) -> str:
        return f"{self.kind} {self.id}"


@dataclass(frozen=True)
class SweepResult:
    found: tuple[Found, ...]  # what the first listing saw
    deleted: tuple[Found, ...]
    left: tuple[Found, ...]  # what the final listing still sees
    not_checked: tuple[str, ...]  # kinds the endpoint cannot list (LocalStack: Client VPN)
    errors: tuple[str, ...]  # the last error per resource that stayed

    @property
    def clean(self) -> bool:
        return not self.left


def prefix(stack: str) -> str:
    """Where ``stacks/aws/`` puts a stack's log groups (by name) and IAM roles (by path)."""
    return f"/fogiac/{stack}/"


def _logs_and_roles(stack: str, *, logs: Any, iam: Any) -> tuple[list[Found], list[str]]:
    found: list[Found] = []
    skipped: list[str] = []
    if logs is None:
        skipped.append("log-group (no CloudWatch Logs client given)")
    else:
        for group in paginate(logs, "describe_log_groups", "logGroups", logGroupNamePrefix=prefix(stack)):
            found.append(Found("log-group", group["logGroupName"]))
    if iam is None:
        skipped.append("iam-role (no IAM client given)")
    else:
        for role in paginate(iam, "list_roles", "Roles", PathPrefix=prefix(stack)):
            found.append(Found("iam-role", role["RoleName"]))
    return found, skipped


def inventory(stack: str, *, ec2: Any, acm: Any, logs: Any = None, iam: Any = None) -> tuple[list[Found], list[str]]:
    """Everything of ``stack`` that exists now, and the kinds that could not be checked."""
    found: list[Found] = []
    skipped: list[str] = []
    tags = tag_filter(stack)
    vpcs = [v["VpcId"] for v in paginate(ec2, "describe_vpcs", "Vpcs", Filters=tags)]
    inside = [{"Name": "vpc-id", "Values": vpcs}] if vpcs else None

    def both(op: str, key: str, ident: Callable[[dict[str, Any]], str], extra: list[dict[str, Any]] | None = None,
             keep: Callable[[dict[str, Any]], bool] = lambda _: True) -> list[tuple[str, dict[str, Any]]]:
        seen: dict[str, dict[str, Any]] = {}
        for filters in ([tags + (extra or [])] + ([inside + (extra or [])] if inside else [])):
            for item in paginate(ec2, op, key, Filters=filters):
                if keep(item):
                    seen[ident(item)] = item
        return sorted(seen.items())

    try:
        for e in paginate(ec2, "describe_client_vpn_endpoints", "ClientVpnEndpoints", Filters=tags):
            if e.get("Status", {}).get("Code") != "deleted":
                found.append(Found("client-vpn-endpoint", e["ClientVpnEndpointId"], e.get("VpcId", "")))
    except Exception as err:  # noqa: BLE001 (LocalStack answers Client VPN calls with 501)
        if not _unsupported(err):
            raise
        skipped.append(f"client-vpn-endpoint (not supported by this endpoint: {error_code(err)})")
    live = [{"Name": "instance-state-name", "Values": ["pending", "running", "shutting-down", "stopping", "stopped"]}]
    for _, r in both("describe_instances", "Reservations", lambda r: r["Instances"][0]["InstanceId"], live):
        for inst in r["Instances"]:
            found.append(Found("instance", inst["InstanceId"], inst.get("VpcId", "")))
    for a in paginate(ec2, "describe_addresses", "Addresses", Filters=tags):
        found.append(Found("elastic-ip", a.get("AllocationId") or a["PublicIp"]))
    for rid, _ in both("describe_network_interfaces", "NetworkInterfaces", lambda n: n["NetworkInterfaceId"],
                       keep=lambda n: n.get("Attachment", {}).get("InstanceOwnerId") != "amazon-elb"):
        found.append(Found("network-interface", rid))
    for rid, g in both("describe_security_groups", "SecurityGroups", lambda g: g["GroupId"],
                       keep=lambda g: g["GroupName"] != "default"):
        found.append(Found("security-group", rid, g.get("VpcId", "")))
    for k in paginate(ec2, "describe_key_pairs", "KeyPairs", Filters=tags):
        found.append(Found("key-pair", k["KeyPairId"], k["KeyName"]))
    for rid, s in both("describe_subnets", "Subnets", lambda s: s["SubnetId"]):
        found.append(Found("subnet", rid, s["VpcId"]))
    for rid, t in both("describe_route_tables", "RouteTables", lambda t: t["RouteTableId"],
                       keep=lambda t: not any(a.get("Main") for a in t.get("Associations", []))):
        found.append(Found("route-table", rid, t["VpcId"]))
    gw_filters = [tags] + ([[{"Name": "attachment.vpc-id", "Values": vpcs}]] if vpcs else [])
    gateways: dict[str, dict[str, Any]] = {}
    for filters in gw_filters:
        for g in paginate(ec2, "describe_internet_gateways", "InternetGateways", Filters=filters):
            gateways[g["InternetGatewayId"]] = g
    for rid, g in sorted(gateways.items()):
        found.append(Found("internet-gateway", rid, ",".join(a["VpcId"] for a in g.get("Attachments", []))))
    flows: dict[str, dict[str, Any]] = {}
    for filters in [tags] + ([[{"Name": "resource-id", "Values": vpcs}]] if vpcs else []):
        for flow in paginate(ec2, "describe_flow_logs", "FlowLogs", Filter=filters):
            flows[flow["FlowLogId"]] = flow
    found.extend(Found("flow-log", rid) for rid in sorted(flows))
    found.extend(Found("vpc", v) for v in sorted(vpcs))
    for cert in paginate(acm, "list_certificates", "CertificateSummaryList"):
        arn = cert["CertificateArn"]
        tag_list = acm.list_tags_for_certificate(CertificateArn=arn).get("Tags", [])
        if tags_of({"Tags": tag_list}).get(STACK_TAG) == stack:
            found.append(Found("acm-certificate", arn))
    more, unchecked = _logs_and_roles(stack, logs=logs, iam=iam)
    found += more
    skipped += unchecked
    rank = {kind: i for i, kind in enumerate(ORDER)}
    return sorted(found, key=lambda f: (rank[f.kind], f.id)), skipped


def _delete(item: Found, *, ec2: Any, acm: Any, logs: Any = None, iam: Any = None) -> None:
    """One deletion attempt; raises the AWS error if it did not work."""
    kind, rid = item.kind, item.id
    if kind == "client-vpn-endpoint":
        for net in paginate(ec2, "describe_client_vpn_target_networks", "ClientVpnTargetNetworks",
                            ClientVpnEndpointId=rid):
            if net.get("Status", {}).get("Code") not in {"disassociating", "disassociated"}:
                ec2.disassociate_client_vpn_target_network(ClientVpnEndpointId=rid, AssociationId=net["AssociationId"])
        ec2.delete_client_vpn_endpoint(ClientVpnEndpointId=rid)
    elif kind == "flow-log":
        refused = ec2.delete_flow_logs(FlowLogIds=[rid]).get("Unsuccessful") or []
        if refused:
            raise RuntimeError(f"flow log {rid}: {refused[0].get('Error', {}).get('Message', refused[0])}")
    elif kind == "log-group":
        logs.delete_log_group(logGroupName=rid)
    elif kind == "iam-role":
        for name in paginate(iam, "list_role_policies", "PolicyNames", RoleName=rid):
            iam.delete_role_policy(RoleName=rid, PolicyName=name)
        for policy in paginate(iam, "list_attached_role_policies", "AttachedPolicies", RoleName=rid):
            iam.detach_role_policy(RoleName=rid, PolicyArn=policy["PolicyArn"])
        iam.delete_role(RoleName=rid)
    elif kind == "elastic-ip":
        addr = ec2.describe_addresses(AllocationIds=[rid])["Addresses"][0]
        if addr.get("AssociationId"):
            ec2.disassociate_address(AssociationId=addr["AssociationId"])
        ec2.release_address(AllocationId=rid)
    elif kind == "network-interface":
        eni = ec2.describe_network_interfaces(NetworkInterfaceIds=[rid])["NetworkInterfaces"][0]
        attachment = eni.get("Attachment") or {}
        if attachment.get("AttachmentId") and attachment.get("DeviceIndex", 0) != 0:
            ec2.detach_network_interface(AttachmentId=attachment["AttachmentId"], Force=True)
        ec2.delete_network_interface(NetworkInterfaceId=rid)
    elif kind == "security-group":
        ec2.delete_security_group(GroupId=rid)
    elif kind == "key-pair":
        ec2.delete_key_pair(KeyName=item.detail)
    elif kind == "subnet":
        ec2.delete_subnet(SubnetId=rid)
    elif kind == "route-table":
        table = ec2.describe_route_tables(RouteTableIds=[rid])["RouteTables"][0]
        for assoc in table.get("Associations", []):
            if not assoc.get("Main") and assoc.get("RouteTableAssociationId"):
                ec2.disassociate_route_table(AssociationId=assoc["RouteTableAssociationId"])
        ec2.delete_route_table(RouteTableId=rid)
    elif kind == "internet-gateway":
        for vpc in filter(None, item.detail.split(",")):
            ec2.detach_internet_gateway(InternetGatewayId=rid, VpcId=vpc)
        ec2.delete_internet_gateway(InternetGatewayId=rid)
    elif kind == "vpc":
        ec2.delete_vpc(VpcId=rid)
    elif kind == "acm-certificate":
        acm.delete_certificate(CertificateArn=rid)
    else:  # pragma: no cover
        raise ValueError(kind)


def _terminate(instances: list[Found], *, ec2: Any) -> dict[Found, str]:
    """Terminate all at once (one protected instance must not hold up the others), then wait."""
    if not instances:
        return {}
    failed: dict[Found, str] = {}
    try:
        ec2.terminate_instances(InstanceIds=[f.id for f in instances])
    except Exception:  # noqa: BLE001 (one at a time, to learn which ones refuse)
        for item in instances:
            try:
                ec2.terminate_instances(InstanceIds=[item.id])
            except Exception as err:  # noqa: BLE001
                if error_code(err) not in _GONE:
                    failed[item] = f"{item}: {err}"
    going = [f.id for f in instances if f not in failed]
    if going:
        try:
            ec2.get_waiter("instance_terminated").wait(InstanceIds=going, WaiterConfig={"Delay": 5, "MaxAttempts": 60})
        except Exception as err:  # noqa: BLE001 (reported through the next listing)
            failed.update({f: f"{f}: not terminated yet ({err})" for f in instances if f.id in going})
    return failed


def _revoke_group_rules(groups: list[Found], *, ec2: Any) -> None:
    """Drop every rule of the groups about to go, so groups that name each other can be deleted."""
    if not groups:
        return
    for g in ec2.describe_security_groups(GroupIds=[f.id for f in groups])["SecurityGroups"]:
        if g.get("IpPermissions"):
            ec2.revoke_security_group_ingress(GroupId=g["GroupId"], IpPermissions=g["IpPermissions"])
        if g.get("IpPermissionsEgress"):
            ec2.revoke_security_group_egress(GroupId=g["GroupId"], IpPermissions=g["IpPermissionsEgress"])


def owners(stack: str, *, ec2: Any) -> set[str]:
    """The manifest names (tag ``fogiac:manifest``) on the stack's VPCs, instances and security groups."""
    found: set[str] = set()
    for op, key in (("describe_vpcs", "Vpcs"), ("describe_security_groups", "SecurityGroups")):
        found.update(tags_of(item).get(MANIFEST_TAG, "") for item in paginate(ec2, op, key, Filters=tag_filter(stack)))
    for reservation in paginate(ec2, "describe_instances", "Reservations", Filters=tag_filter(stack)):
        found.update(tags_of(inst).get(MANIFEST_TAG, "") for inst in reservation["Instances"])
    return found - {""}  # made by hand, or by a fogiac that did not tag the manifest: nobody's in particular


def sweep(stack: str, *, ec2: Any, acm: Any, dry_run: bool, kinds: Collection[str] | None = None,
          logs: Any = None, iam: Any = None, owner: str | None = None,
          rounds: int = 8, first_delay_s: float = 1.0, sleep: Callable[[float], None] | None = None) -> SweepResult:
    """Delete all of ``stack`` (or only ``kinds`` of it) in dependency order, retrying "in use"
    with bounded backoff. ``owner``: the manifest name the stack must belong to; resources another
    manifest tagged with the same stack name are never deleted (the sweep is refused in one line)."""
    others = sorted(owners(stack, ec2=ec2) - {owner}) if owner is not None else []
    if others:
        raise CloudError(f"stack {stack!r} in the cloud was made by manifest {', '.join(map(repr, others))}, not "
                         f"{owner!r}: not deleting another manifest's resources; give this one another name: "
                         "or --env")

    def listing() -> tuple[list[Found], list[str]]:
        found, skipped = inventory(stack, ec2=ec2, acm=acm, logs=logs, iam=iam)
        return [f for f in found if kinds is None or f.kind in kinds], skipped

    first, skipped = listing()
    if dry_run:
        return SweepResult(found=tuple(first), deleted=(), left=tuple(first), not_checked=tuple(skipped), errors=())
    deleted: list[Found] = []
    errors: dict[Found, str] = {}
    current = first
    for attempt in range(rounds):
        if not current:
            break
        try:
            _revoke_group_rules([f for f in current if f.kind == "security-group"], ec2=ec2)
        except Exception as err:  # noqa: BLE001 (a group already gone: the deletions below will say)
            errors[Found("security-group", "*")] = f"revoking rules: {err}"
        instances = [f for f in current if f.kind == "instance"]
        stuck = _terminate(instances, ec2=ec2)
        errors.update(stuck)
        deleted.extend(f for f in instances if f not in stuck)
        for item in current:
            if item.kind == "instance":
                continue
            try:
                _delete(item, ec2=ec2, acm=acm, logs=logs, iam=iam)
            except Exception as err:  # noqa: BLE001 (retried next round, reported if it stays)
                if error_code(err) in _GONE:
                    deleted.append(item)
                else:
                    errors[item] = f"{item}: {err}"
                continue
            deleted.append(item)
            errors.pop(item, None)
        current, skipped = listing()
        if current and attempt + 1 < rounds:
            (sleep or time.sleep)(min(MAX_DELAY_S, first_delay_s * 2**attempt))
    left = tuple(current)
    return SweepResult(
        found=tuple(first), deleted=tuple(dict.fromkeys(d for d in deleted if d not in left)), left=left,
        not_checked=tuple(skipped),
        errors=tuple(errors.get(item, f"{item}: still listed after deleting it") for item in left),
    )
