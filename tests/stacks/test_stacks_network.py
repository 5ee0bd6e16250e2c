"""The network stack's resource graph, from real pulumi_aws programs under Pulumi mocks."""

from __future__ import annotations

from collections import Counter

from fogiac.targets.aws.offline import OfflinePlan

VPC = "aws:ec2/vpc:Vpc"
SUBNET = "aws:ec2/subnet:Subnet"
IGW = "aws:ec2/internetGateway:InternetGateway"
ROUTES = "aws:ec2/routeTable:RouteTable"
ASSOC = "aws:ec2/routeTableAssociation:RouteTableAssociation"
SG = "aws:ec2/securityGroup:SecurityGroup"
INGRESS = "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule"
EGRESS = "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule"
CERT = "aws:acm/certificate:Certificate"
ENDPOINT = "aws:ec2clientvpn/endpoint:Endpoint"
VPN_ASSOC = "aws:ec2clientvpn/networkAssociation:NetworkAssociation"
AUTHZ = "aws:ec2clientvpn/authorizationRule:AuthorizationRule"
KEY = "aws:ec2/keyPair:KeyPair"
INSTANCE = "aws:ec2/instance:Instance"
DEFAULT_SG = "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup"
LOGS = "aws:cloudwatch/logGroup:LogGroup"
ROLE = "aws:iam/role:Role"
POLICY = "aws:iam/rolePolicy:RolePolicy"
FLOW_LOG = "aws:ec2/flowLog:FlowLog"
UNTAGGABLE = {ASSOC, VPN_ASSOC, AUTHZ, POLICY}


def counts(offline: OfflinePlan, layer: str) -> Counter[str]:
    return Counter(r.type for r in offline.layer(layer))


def test_minimal_counts_per_stack(offline: dict[str, OfflinePlan]) -> None:
    assert counts(offline["minimal"], "network") == {
        VPC: 1, DEFAULT_SG: 1, SUBNET: 2, IGW: 1, ROUTES: 2, ASSOC: 2, SG: 2, INGRESS: 7, EGRESS: 5,
        CERT: 2, LOGS: 1, ENDPOINT: 1, VPN_ASSOC: 1, AUTHZ: 1,
    }
    assert counts(offline["minimal"], "compute") == {KEY: 1, INSTANCE: 1}


def test_proxy_mode_has_no_vpn(offline: dict[str, OfflinePlan]) -> None:
    network = counts(offline["proxy"], "network")
    assert network == {VPC: 1, DEFAULT_SG: 1, SUBNET: 2, IGW: 1, ROUTES: 2, ASSOC: 2, SG: 1, INGRESS: 7, EGRESS: 3}
    assert "vpn_endpoint_id" not in offline["proxy"].outputs["network"]


def test_components_parent_their_resources(offline: dict[str, OfflinePlan]) -> None:
    components = [(r.stack, r.type) for r in offline["minimal"].resources if not r.custom]
    assert components == [
        ("network", "fogiac:aws:Network"),
        ("network", "fogiac:aws:Firewall"),
        ("network", "fogiac:aws:ClientVpn"),
        ("compute", "fogiac:aws:Compute"),
    ]
    assert all(r.name.startswith("minimal-dev") for r in offline["minimal"].resources)


def test_vpc_and_subnet_cidrs(offline: dict[str, OfflinePlan]) -> None:
    (vpc,) = offline["proxy"].of_type(VPC)
    assert vpc.inputs["cidrBlock"] == "10.20.0.0/20"
    assert vpc.inputs["enableDnsHostnames"] is True
    subnets = {r.name: r.inputs for r in offline["proxy"].of_type(SUBNET)}
    assert subnets["proxied-dev-subnet-hosts"]["cidrBlock"] == "10.20.0.0/24"
    assert subnets["proxied-dev-subnet-hosts"]["mapPublicIpOnLaunch"] is False  # each instance asks for one
    assert subnets["proxied-dev-subnet-vpn"]["cidrBlock"] == "10.20.1.0/24"
    assert subnets["proxied-dev-subnet-vpn"]["mapPublicIpOnLaunch"] is False
    assert {s["availabilityZone"] for s in subnets.values()} == {"us-east-1b"}
    assert {s["vpcId"] for s in subnets.values()} == {"<proxied-dev-vpc.id>"}


def test_only_the_public_subnet_routes_to_the_internet(offline: dict[str, OfflinePlan]) -> None:
    tables = {r.name: r.inputs for r in offline["minimal"].of_type(ROUTES)}
    assert tables["minimal-dev-rt-public"]["routes"] == (
        {"cidrBlock": "0.0.0.0/0", "gatewayId": "<minimal-dev-igw.id>"},
    )
    assert "routes" not in tables["minimal-dev-rt-private"] or not tables["minimal-dev-rt-private"]["routes"]
    associations = {r.inputs["subnetId"]: r.inputs["routeTableId"] for r in offline["minimal"].of_type(ASSOC)}
    assert associations == {
        "<minimal-dev-subnet-hosts.id>": "<minimal-dev-rt-public.id>",
        "<minimal-dev-subnet-vpn.id>": "<minimal-dev-rt-private.id>",
    }


def test_every_taggable_resource_carries_the_stack_tag(offline: dict[str, OfflinePlan]) -> None:
    for key, plan in offline.items():
        stack = plan.plan.stack
        for r in plan.resources:
            if r.custom and r.type not in UNTAGGABLE:
                assert r.inputs["tags"]["fogiac:stack"] == stack, (key, r.name)
                assert r.inputs["tags"]["fogiac:manifest"] == plan.plan.manifest_name
    (instance, *_) = offline["gpu"].of_type(INSTANCE)
    assert instance.inputs["tags"]["team"] == "robots"
    assert instance.inputs["tags"]["fogiac:node"] == "dexnet"


def test_network_exports(offline: dict[str, OfflinePlan]) -> None:
    outputs = offline["minimal"].outputs["network"]
    assert outputs["vpc_id"] == "<minimal-dev-vpc.id>"
    assert dict(outputs["subnet_ids"]) == {
        "hosts": "<minimal-dev-subnet-hosts.id>", "vpn": "<minimal-dev-subnet-vpn.id>"
    }
    assert dict(outputs["security_group_ids"]) == {
        "hosts": "<minimal-dev-sg-hosts.id>", "vpn": "<minimal-dev-sg-vpn.id>"
    }
    assert outputs["vpn_endpoint_id"] == "<minimal-dev-endpoint.id>"
    assert outputs["vpn_dns_name"] == "<minimal-dev-endpoint.dnsName>"


def test_default_security_group_is_adopted_without_rules(offline: dict[str, OfflinePlan]) -> None:
    for plan in offline.values():
        (group,) = plan.of_type(DEFAULT_SG)
        assert group.inputs["vpcId"] == f"<{plan.plan.stack}-vpc.id>"
        assert not group.inputs.get("ingress") and not group.inputs.get("egress")


def test_hosts_egress_is_web_and_the_vpc_only(offline: dict[str, OfflinePlan]) -> None:
    def world(plan: OfflinePlan) -> set[tuple[str, int]]:
        return {(r.inputs["ipProtocol"], r.inputs["fromPort"]) for r in plan.of_type(EGRESS)
                if r.inputs.get("cidrIpv4") == "0.0.0.0/0"}

    assert world(offline["proxy"]) == {("tcp", 80), ("tcp", 443)}
    assert world(offline["flows"]) == {("tcp", 80), ("tcp", 443), ("tcp", 8883)}
    inside = [r for r in offline["proxy"].of_type(EGRESS) if r.inputs["ipProtocol"] == "-1"]
    assert [r.inputs["cidrIpv4"] for r in inside] == ["10.20.0.0/20"]


def test_flow_logs_are_opt_in(offline: dict[str, OfflinePlan]) -> None:
    assert not offline["proxy"].of_type(FLOW_LOG) and not offline["proxy"].of_type(ROLE)
    (flow,) = offline["flows"].of_type(FLOW_LOG)
    (group,) = offline["flows"].of_type(LOGS)
    (role,) = offline["flows"].of_type(ROLE)
    (policy,) = offline["flows"].of_type(POLICY)
    assert group.inputs["name"] == "/fogiac/flows-dev/flow-logs" and group.inputs["retentionInDays"] == 365
    assert flow.inputs["vpcId"] == "<flows-dev-vpc.id>"
    assert (flow.inputs["trafficType"], flow.inputs["logDestinationType"]) == ("ALL", "cloud-watch-logs")
    assert flow.inputs["logDestination"] == "<flows-dev-flow-logs.arn>"
    assert flow.inputs["iamRoleArn"] == "<flows-dev-flow-logs-role.arn>"
    assert role.inputs["path"] == "/fogiac/flows-dev/"
    # Issue 35 item 4: the shipped IAM policy creates a role only with the account's fogiac-boundary on it
    assert role.inputs["permissionsBoundary"] == "arn:aws:iam::<account>:policy/fogiac-boundary"
    assert "vpc-flow-logs.amazonaws.com" in role.inputs["assumeRolePolicy"]
    assert '"Resource": ["<flows-dev-flow-logs.arn>", "<flows-dev-flow-logs.arn>:*"]' in policy.inputs["policy"]
