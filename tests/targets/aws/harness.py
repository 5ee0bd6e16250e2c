"""Apply the compiled stacks to LocalStack without the Pulumi engine (which cannot run here).

The stack programs run under Pulumi's mock runtime (:func:`fogiac.pulumi_engine.offline.run_program`); this
``Mocks`` creates each resource it is told about through boto3 and answers with the real id,
so dependants receive real ids as Pulumi would give them. Like Pulumi, it keeps a state (ids
by layer, type and logical name, in creation order) and a re-apply reuses what the state names
and still exists: nothing new is created. ``destroy`` deletes in reverse, past errors.
Client VPN, which LocalStack lacks, is only recorded, with its inputs, for assertions. The VPC's
default security group is adopted (its rules revoked), never deleted: AWS deletes it with the VPC.
"""

from __future__ import annotations

import json
import threading
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pulumi
from botocore.exceptions import ClientError

from fogiac.targets.aws.api import error_code
from fogiac.certs import Bundle
from fogiac.pulumi_engine.offline import run_program
from fogiac.plan.model import Plan
from stacks.aws import PROJECT

_SECRET_SIG = "4dabf18193072939515e22adb298388d"
CLIENT_VPN = ("aws:ec2clientvpn/endpoint:Endpoint", "aws:ec2clientvpn/networkAssociation:NetworkAssociation",
              "aws:ec2clientvpn/authorizationRule:AuthorizationRule")


def plain(value: Any) -> Any:
    """Inputs with secrets unwrapped and whole floats as ints (the mock wire has only floats)."""
    if isinstance(value, Mapping):
        if _SECRET_SIG in value:
            return plain(value.get("value"))
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def _tag_spec(kind: str, tags: Mapping[str, str] | None) -> list[dict[str, Any]]:
    return [{"ResourceType": kind, "Tags": [{"Key": k, "Value": v} for k, v in (tags or {}).items()]}] if tags else []


class InjectedFailure(RuntimeError):
    pass


@dataclass
class Harness:
    """Creates, reuses and deletes one stack's resources in LocalStack; ``state`` mirrors Pulumi's."""

    ec2: Any
    acm: Any
    logs: Any = None  # CloudWatch Logs and IAM clients; made for the ec2 client's endpoint when not given
    iam: Any = None
    path: Path | None = None
    fail_at: int | None = None  # raise instead of creating the Nth resource of an apply
    spot_capacity: bool = True  # False: refuse spot launches as AWS does when it has none (InsufficientInstanceCapacity)
    state: dict[str, dict[str, Any]] = field(default_factory=dict)
    created: list[str] = field(default_factory=list)  # keys created by the last apply
    reused: list[str] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        from fogiac.targets.aws.api import client

        region = self.ec2.meta.region_name
        self.logs = self.logs if self.logs is not None else client("logs", region=region)
        self.iam = self.iam if self.iam is not None else client("iam", region=region)
        if self.path is not None and self.path.exists():
            self.state = json.loads(self.path.read_text())

    # ---- apply -------------------------------------------------------------------------------

    def apply(self, plan: Plan, *, certs: Bundle, operator_cidrs: tuple[str, ...],
              public_key_openssh: str) -> dict[str, dict[str, Any]]:
        """Run the network program, then compute with network's outputs; return both outputs."""
        from stacks.aws.program import compute_program, network_program

        self.created, self.reused = [], []
        outputs: dict[str, dict[str, Any]] = {}
        outputs["network"] = self._run(plan, "network", lambda: network_program(
            plan, certs=certs, operator_cidrs=operator_cidrs))
        outputs["compute"] = self._run(plan, "compute", lambda: compute_program(
            plan, network=outputs["network"], public_key_openssh=public_key_openssh))
        return outputs

    def run_layer(self, plan: Plan, layer: str, program: Callable[[], None]) -> dict[str, Any]:
        """Run one layer's program (as built by fogiac's Engine); its resources go to LocalStack."""
        self.created, self.reused = ([], []) if layer == "network" else (self.created, self.reused)
        return self._run(plan, layer, program)

    def _run(self, plan: Plan, layer: str, program: Callable[[], None]) -> dict[str, Any]:
        return run_program(program, mocks=_Mocks(self, layer), project=PROJECT, stack=f"{plan.stack}-{layer}",
                           preview=False)

    def new_resource(self, layer: str, args: pulumi.runtime.MockResourceArgs) -> tuple[str, dict[str, Any]]:
        inputs = plain(dict(args.inputs))
        if not args.custom:
            return f"{args.name}-component", {}
        key = f"{layer}/{args.typ}/{args.name}"
        with self._lock:
            known = self.state.get(key)
            if known is not None and self._exists(args.typ, known["id"], known["state"]):
                self.reused.append(key)
                return known["id"], {**inputs, **known["state"]}
            if self.fail_at is not None and len(self.created) + 1 == self.fail_at:
                raise InjectedFailure(f"injected failure at resource {self.fail_at}: {args.typ} {args.name}")
            rid, extra = _CREATE[args.typ](self, inputs)
            self.state[key] = {"type": args.typ, "id": rid, "state": extra, "inputs": _keep(args.typ, inputs)}
            self.created.append(key)
            self._save()
            return rid, {**inputs, **extra}

    def call(self, args: pulumi.runtime.MockCallArgs) -> dict[str, Any]:
        if args.token != "aws:ec2/getAmi:getAmi":
            return {}
        filters = [{"Name": f["name"], "Values": f["values"]} for f in plain(args.args).get("filters", [])]
        images = self.ec2.describe_images(Owners=list(args.args.get("owners", [])), Filters=filters)["Images"]
        if not images:
            raise RuntimeError(f"no AMI matches {filters}")
        newest = max(images, key=lambda i: i.get("CreationDate", ""))
        return {"id": newest["ImageId"], "imageId": newest["ImageId"], "name": newest["Name"],
                "architecture": newest.get("Architecture", "x86_64")}

    # ---- destroy -----------------------------------------------------------------------------

    def destroy(self, *, layers: tuple[str, ...] = ("compute", "network")) -> list[str]:
        """Delete ``layers`` in that order, each newest first, continuing past errors; return the errors."""
        errors = []
        keys = [k for layer in layers for k in reversed(list(self.state)) if k.startswith(f"{layer}/")]
        for key in keys:
            entry = self.state[key]
            try:
                _DELETE[entry["type"]](self, entry)
            except Exception as err:  # noqa: BLE001 (like pulumi destroy --continue-on-error)
                if not error_code(err).endswith(("NotFound", "NotFoundException", "NoSuchEntity")):
                    errors.append(f"{key}: {err}")
                    continue
            del self.state[key]
            self._save()
        return errors

    def client_vpn(self) -> dict[str, dict[str, Any]]:
        """The recorded Client VPN resources by type token (LocalStack has none to describe)."""
        return {e["type"]: {"id": e["id"], **e["inputs"]} for e in self.state.values() if e["type"] in CLIENT_VPN}

    def _save(self) -> None:
        if self.path is not None:
            self.path.write_text(json.dumps(self.state, indent=1))  # keeps creation order

    def _exists(self, typ: str, rid: str, state: Mapping[str, Any]) -> bool:
        check = _EXISTS.get(typ)
        if check is None:
            return True
        try:
            return bool(check(self, rid, state))
        except Exception as err:  # noqa: BLE001
            if error_code(err).endswith(("NotFound", "NotFoundException", "NoSuchEntity", "Malformed")):
                return False
            raise


def _keep(typ: str, inputs: Mapping[str, Any]) -> dict[str, Any]:
    """What the state keeps of a resource's inputs: everything but private keys and user data."""
    return {k: v for k, v in inputs.items() if k not in {"privateKey", "userData", "publicKey"}}


class _Mocks(pulumi.runtime.Mocks):
    def __init__(self, harness: Harness, layer: str) -> None:
        self.harness, self.layer = harness, layer

    def new_resource(self, args: pulumi.runtime.MockResourceArgs) -> tuple[str, dict[str, Any]]:
        return self.harness.new_resource(self.layer, args)

    def call(self, args: pulumi.runtime.MockCallArgs) -> dict[str, Any]:  # type: ignore[override]
        return self.harness.call(args)


# ---- per-type create / delete / exists -----------------------------------------------------------

def _vpc(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    vpc = h.ec2.create_vpc(CidrBlock=i["cidrBlock"], TagSpecifications=_tag_spec("vpc", i.get("tags")))["Vpc"]["VpcId"]
    for attr in ("enableDnsSupport", "enableDnsHostnames"):
        if attr in i:
            h.ec2.modify_vpc_attribute(VpcId=vpc, **{attr[0].upper() + attr[1:]: {"Value": bool(i[attr])}})
    return vpc, {}


def _igw(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    igw = h.ec2.create_internet_gateway(TagSpecifications=_tag_spec("internet-gateway", i.get("tags")))[
        "InternetGateway"]["InternetGatewayId"]
    h.ec2.attach_internet_gateway(InternetGatewayId=igw, VpcId=i["vpcId"])
    return igw, {}


def _subnet(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    sid = h.ec2.create_subnet(VpcId=i["vpcId"], CidrBlock=i["cidrBlock"], AvailabilityZone=i["availabilityZone"],
                              TagSpecifications=_tag_spec("subnet", i.get("tags")))["Subnet"]["SubnetId"]
    if i.get("mapPublicIpOnLaunch"):
        h.ec2.modify_subnet_attribute(SubnetId=sid, MapPublicIpOnLaunch={"Value": True})
    return sid, {}


def _route_table(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    rt = h.ec2.create_route_table(VpcId=i["vpcId"], TagSpecifications=_tag_spec("route-table", i.get("tags")))[
        "RouteTable"]["RouteTableId"]
    for route in i.get("routes") or []:
        h.ec2.create_route(RouteTableId=rt, DestinationCidrBlock=route["cidrBlock"], GatewayId=route["gatewayId"])
    return rt, {}


def _association(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    return h.ec2.associate_route_table(RouteTableId=i["routeTableId"], SubnetId=i["subnetId"])["AssociationId"], {}


def _group(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    gid = h.ec2.create_security_group(GroupName=i["name"], Description=i["description"], VpcId=i["vpcId"],
                                      TagSpecifications=_tag_spec("security-group", i.get("tags")))["GroupId"]
    # As the AWS provider does: drop the allow-all egress AWS adds, so only the plan's rules remain.
    h.ec2.revoke_security_group_egress(GroupId=gid, IpPermissions=[
        {"IpProtocol": "-1", "IpRanges": [{"CidrIp": "0.0.0.0/0"}]}])
    return gid, {"arn": f"arn:aws:ec2:::security-group/{gid}"}


def _permission(i: dict[str, Any]) -> dict[str, Any]:
    perm: dict[str, Any] = {"IpProtocol": i["ipProtocol"]}
    if i["ipProtocol"] != "-1":
        perm.update(FromPort=i["fromPort"], ToPort=i["toPort"])
    if "cidrIpv4" in i:
        perm["IpRanges"] = [{"CidrIp": i["cidrIpv4"], "Description": i.get("description", "")}]
    else:
        perm["Ipv6Ranges"] = [{"CidrIpv6": i["cidrIpv6"], "Description": i.get("description", "")}]
    return perm


def _rule(egress: bool) -> Callable[[Harness, dict[str, Any]], tuple[str, dict[str, Any]]]:
    def create(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
        call = h.ec2.authorize_security_group_egress if egress else h.ec2.authorize_security_group_ingress
        out = call(GroupId=i["securityGroupId"], IpPermissions=[_permission(i)],
                   TagSpecifications=_tag_spec("security-group-rule", i.get("tags")))
        return out["SecurityGroupRules"][0]["SecurityGroupRuleId"], {"securityGroupId": i["securityGroupId"]}

    return create


def _key_pair(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    out = h.ec2.import_key_pair(KeyName=i["keyName"], PublicKeyMaterial=i["publicKey"].encode(),
                                TagSpecifications=_tag_spec("key-pair", i.get("tags")))
    return out["KeyPairId"], {"keyName": i["keyName"]}


def _instance(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    root = i.get("rootBlockDevice") or {}
    meta = i.get("metadataOptions") or {}
    args: dict[str, Any] = dict(
        ImageId=i["ami"], InstanceType=i["instanceType"], MinCount=1, MaxCount=1, KeyName=i["keyName"],
        UserData=i.get("userData", ""),
        NetworkInterfaces=[{"DeviceIndex": 0, "SubnetId": i["subnetId"], "Groups": i["vpcSecurityGroupIds"],
                            "AssociatePublicIpAddress": bool(i.get("associatePublicIpAddress"))}],
        MetadataOptions={"HttpTokens": meta.get("httpTokens", "optional"),
                         "HttpEndpoint": meta.get("httpEndpoint", "enabled"),
                         "HttpPutResponseHopLimit": meta.get("httpPutResponseHopLimit", 1)},
        BlockDeviceMappings=[{"DeviceName": "/dev/sda1", "Ebs": {
            "VolumeSize": root.get("volumeSize", 8), "VolumeType": root.get("volumeType", "gp3"),
            "Encrypted": bool(root.get("encrypted")), "DeleteOnTermination": root.get("deleteOnTermination", True)}}],
        TagSpecifications=_tag_spec("instance", i.get("tags")) + _tag_spec("volume", i.get("volumeTags")),
    )
    if i.get("ebsOptimized"):
        args["EbsOptimized"] = True
    if i.get("instanceInitiatedShutdownBehavior"):  # what the watchdog's poweroff does: stop or terminate
        args["InstanceInitiatedShutdownBehavior"] = i["instanceInitiatedShutdownBehavior"]
    if i.get("instanceMarketOptions"):
        if not h.spot_capacity:
            raise ClientError({"Error": {"Code": "InsufficientInstanceCapacity", "Message": (
                f"There is no Spot capacity available that matches your request ({i['instanceType']}).")}},
                "RunInstances")
        args["InstanceMarketOptions"] = {"MarketType": "spot"}
    inst = h.ec2.run_instances(**args)["Instances"][0]
    return inst["InstanceId"], {"publicIp": inst.get("PublicIpAddress", ""), "privateIp": inst["PrivateIpAddress"]}


def _certificate(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    arn = h.acm.import_certificate(
        Certificate=i["certificateBody"].encode(), PrivateKey=i["privateKey"].encode(),
        CertificateChain=i["certificateChain"].encode(),
        Tags=[{"Key": k, "Value": v} for k, v in (i.get("tags") or {}).items()])["CertificateArn"]
    return arn, {"arn": arn}


def _default_group(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """Adopt the VPC's default group as the AWS provider does: tag it and remove every rule."""
    group = h.ec2.describe_security_groups(Filters=[{"Name": "vpc-id", "Values": [i["vpcId"]]},
                                                    {"Name": "group-name", "Values": ["default"]}])["SecurityGroups"][0]
    if group.get("IpPermissions"):
        h.ec2.revoke_security_group_ingress(GroupId=group["GroupId"], IpPermissions=group["IpPermissions"])
    if group.get("IpPermissionsEgress"):
        h.ec2.revoke_security_group_egress(GroupId=group["GroupId"], IpPermissions=group["IpPermissionsEgress"])
    if i.get("tags"):
        h.ec2.create_tags(Resources=[group["GroupId"]], Tags=[{"Key": k, "Value": v} for k, v in i["tags"].items()])
    return group["GroupId"], {}


def _log_group(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    h.logs.create_log_group(logGroupName=i["name"], tags=i.get("tags") or {})
    if i.get("retentionInDays"):
        h.logs.put_retention_policy(logGroupName=i["name"], retentionInDays=i["retentionInDays"])
    (group,) = h.logs.describe_log_groups(logGroupNamePrefix=i["name"])["logGroups"]
    return i["name"], {"arn": group["arn"].removesuffix(":*")}  # Terraform's arn has no ":*"


def _role(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    role = h.iam.create_role(RoleName=i["name"], Path=i.get("path", "/"), AssumeRolePolicyDocument=i["assumeRolePolicy"],
                             Tags=[{"Key": k, "Value": v} for k, v in (i.get("tags") or {}).items()])["Role"]
    return role["RoleName"], {"arn": role["Arn"]}


def _role_policy(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    name = i.get("name") or "policy"
    h.iam.put_role_policy(RoleName=i["role"], PolicyName=name, PolicyDocument=i["policy"])
    return f"{i['role']}:{name}", {}


def _flow_log(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    out = h.ec2.create_flow_logs(ResourceIds=[i["vpcId"]], ResourceType="VPC", TrafficType=i["trafficType"],
                                 LogDestinationType=i["logDestinationType"], LogDestination=i["logDestination"],
                                 DeliverLogsPermissionArn=i["iamRoleArn"],
                                 TagSpecifications=_tag_spec("vpc-flow-log", i.get("tags")))
    if out.get("Unsuccessful"):
        raise RuntimeError(f"create_flow_logs: {out['Unsuccessful']}")
    return out["FlowLogIds"][0], {}


def _delete_role_policy(h: Harness, e: dict[str, Any]) -> None:
    role, name = e["id"].split(":", 1)
    h.iam.delete_role_policy(RoleName=role, PolicyName=name)


def _recorded(prefix: str) -> Callable[[Harness, dict[str, Any]], tuple[str, dict[str, Any]]]:
    def create(h: Harness, i: dict[str, Any]) -> tuple[str, dict[str, Any]]:
        rid = f"{prefix}-{uuid.uuid4().hex[:17]}"
        extra = {"dnsName": f"*.{rid}.prod.clientvpn.us-west-2.amazonaws.com"} if prefix == "cvpn-endpoint" else {}
        return rid, extra

    return create


def _terminate(h: Harness, e: dict[str, Any]) -> None:
    found = [i for r in h.ec2.describe_instances(InstanceIds=[e["id"]])["Reservations"] for i in r["Instances"]]
    enis = [n["NetworkInterfaceId"] for i in found for n in i.get("NetworkInterfaces", [])]
    h.ec2.terminate_instances(InstanceIds=[e["id"]])
    h.ec2.get_waiter("instance_terminated").wait(InstanceIds=[e["id"]], WaiterConfig={"Delay": 1, "MaxAttempts": 60})
    # AWS deletes a terminated instance's primary interface itself; LocalStack keeps it.
    for eni in enis:
        try:
            h.ec2.delete_network_interface(NetworkInterfaceId=eni)
        except Exception as err:  # noqa: BLE001
            if not error_code(err).endswith("NotFound"):
                raise


def _detach_delete_igw(h: Harness, e: dict[str, Any]) -> None:
    gw = h.ec2.describe_internet_gateways(InternetGatewayIds=[e["id"]])["InternetGateways"][0]
    for attachment in gw.get("Attachments", []):
        h.ec2.detach_internet_gateway(InternetGatewayId=e["id"], VpcId=attachment["VpcId"])
    h.ec2.delete_internet_gateway(InternetGatewayId=e["id"])


def _revoke(egress: bool) -> Callable[[Harness, dict[str, Any]], None]:
    def delete(h: Harness, e: dict[str, Any]) -> None:
        call = h.ec2.revoke_security_group_egress if egress else h.ec2.revoke_security_group_ingress
        call(GroupId=e["state"]["securityGroupId"], SecurityGroupRuleIds=[e["id"]])

    return delete


_CREATE: dict[str, Callable[[Harness, dict[str, Any]], tuple[str, dict[str, Any]]]] = {
    "aws:ec2/vpc:Vpc": _vpc,
    "aws:ec2/internetGateway:InternetGateway": _igw,
    "aws:ec2/subnet:Subnet": _subnet,
    "aws:ec2/routeTable:RouteTable": _route_table,
    "aws:ec2/routeTableAssociation:RouteTableAssociation": _association,
    "aws:ec2/securityGroup:SecurityGroup": _group,
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": _rule(egress=False),
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": _rule(egress=True),
    "aws:ec2/keyPair:KeyPair": _key_pair,
    "aws:ec2/instance:Instance": _instance,
    "aws:acm/certificate:Certificate": _certificate,
    "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup": _default_group,
    "aws:cloudwatch/logGroup:LogGroup": _log_group,
    "aws:iam/role:Role": _role,
    "aws:iam/rolePolicy:RolePolicy": _role_policy,
    "aws:ec2/flowLog:FlowLog": _flow_log,
    CLIENT_VPN[0]: _recorded("cvpn-endpoint"),
    CLIENT_VPN[1]: _recorded("cvpn-assoc"),
    CLIENT_VPN[2]: _recorded("cvpn-auth"),
}

_DELETE: dict[str, Callable[[Harness, dict[str, Any]], None]] = {
    "aws:ec2/vpc:Vpc": lambda h, e: h.ec2.delete_vpc(VpcId=e["id"]),
    "aws:ec2/internetGateway:InternetGateway": _detach_delete_igw,
    "aws:ec2/subnet:Subnet": lambda h, e: h.ec2.delete_subnet(SubnetId=e["id"]),
    "aws:ec2/routeTable:RouteTable": lambda h, e: h.ec2.delete_route_table(RouteTableId=e["id"]),
    "aws:ec2/routeTableAssociation:RouteTableAssociation": lambda h, e: h.ec2.disassociate_route_table(
        AssociationId=e["id"]),
    "aws:ec2/securityGroup:SecurityGroup": lambda h, e: h.ec2.delete_security_group(GroupId=e["id"]),
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": _revoke(egress=False),
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": _revoke(egress=True),
    "aws:ec2/keyPair:KeyPair": lambda h, e: h.ec2.delete_key_pair(KeyName=e["state"]["keyName"]),
    "aws:ec2/instance:Instance": _terminate,
    "aws:acm/certificate:Certificate": lambda h, e: h.acm.delete_certificate(CertificateArn=e["id"]),
    "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup": lambda h, e: None,  # AWS keeps it until the VPC goes
    "aws:cloudwatch/logGroup:LogGroup": lambda h, e: h.logs.delete_log_group(logGroupName=e["id"]),
    "aws:iam/role:Role": lambda h, e: h.iam.delete_role(RoleName=e["id"]),
    "aws:iam/rolePolicy:RolePolicy": _delete_role_policy,
    "aws:ec2/flowLog:FlowLog": lambda h, e: h.ec2.delete_flow_logs(FlowLogIds=[e["id"]]),
    CLIENT_VPN[0]: lambda h, e: None,
    CLIENT_VPN[1]: lambda h, e: None,
    CLIENT_VPN[2]: lambda h, e: None,
}


def _instance_alive(h: Harness, rid: str, state: Mapping[str, Any]) -> bool:
    found = [i for r in h.ec2.describe_instances(InstanceIds=[rid])["Reservations"] for i in r["Instances"]]
    return any(i["State"]["Name"] not in {"shutting-down", "terminated"} for i in found)


def _rule_exists(h: Harness, rid: str, state: Mapping[str, Any]) -> bool:
    return bool(h.ec2.describe_security_group_rules(SecurityGroupRuleIds=[rid])["SecurityGroupRules"])


_EXISTS: dict[str, Callable[[Harness, str, Mapping[str, Any]], bool]] = {
    "aws:ec2/vpc:Vpc": lambda h, rid, s: h.ec2.describe_vpcs(VpcIds=[rid])["Vpcs"],
    "aws:ec2/internetGateway:InternetGateway": lambda h, rid, s: h.ec2.describe_internet_gateways(
        InternetGatewayIds=[rid])["InternetGateways"],
    "aws:ec2/subnet:Subnet": lambda h, rid, s: h.ec2.describe_subnets(SubnetIds=[rid])["Subnets"],
    "aws:ec2/routeTable:RouteTable": lambda h, rid, s: h.ec2.describe_route_tables(RouteTableIds=[rid])["RouteTables"],
    "aws:ec2/routeTableAssociation:RouteTableAssociation": lambda h, rid, s: h.ec2.describe_route_tables(
        Filters=[{"Name": "association.route-table-association-id", "Values": [rid]}])["RouteTables"],
    "aws:ec2/securityGroup:SecurityGroup": lambda h, rid, s: h.ec2.describe_security_groups(
        GroupIds=[rid])["SecurityGroups"],
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": _rule_exists,
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": _rule_exists,
    "aws:ec2/keyPair:KeyPair": lambda h, rid, s: h.ec2.describe_key_pairs(KeyNames=[s["keyName"]])["KeyPairs"],
    "aws:ec2/instance:Instance": _instance_alive,
    "aws:acm/certificate:Certificate": lambda h, rid, s: h.acm.describe_certificate(CertificateArn=rid),
    "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup": lambda h, rid, s: h.ec2.describe_security_groups(
        GroupIds=[rid])["SecurityGroups"],
    "aws:cloudwatch/logGroup:LogGroup": lambda h, rid, s: [
        g for g in h.logs.describe_log_groups(logGroupNamePrefix=rid)["logGroups"] if g["logGroupName"] == rid],
    "aws:iam/role:Role": lambda h, rid, s: h.iam.get_role(RoleName=rid),
    "aws:iam/rolePolicy:RolePolicy": lambda h, rid, s: h.iam.get_role_policy(
        RoleName=rid.split(":", 1)[0], PolicyName=rid.split(":", 1)[1]),
    "aws:ec2/flowLog:FlowLog": lambda h, rid, s: h.ec2.describe_flow_logs(FlowLogIds=[rid])["FlowLogs"],
}
