"""Which input changes make the provider replace a resource instead of updating it in place.

pulumi-aws is bridged from terraform-provider-aws: an argument marked ``ForceNew: true`` (or, in
the provider's plugin-framework resources, ``RequiresReplace``) is a replacement in Pulumi's
diff too. The table holds the arguments fogiac's stack programs set, per resource type, with
the provider source file it was read from. Paths are Pulumi's camelCase input names; a nested
argument is ``parent.child`` and also covers anything below it.

Arguments that are absent here are updated in place (``instanceType`` and ``userData``: the
instance is stopped and started; ``tags``; security-group rule ports and CIDRs through
ModifySecurityGroupRules; the imported certificate's body through a re-import).
"""

from __future__ import annotations

from dataclasses import dataclass

PROVIDER = "hashicorp/terraform-provider-aws"


@dataclass(frozen=True)
class ReplaceRule:
    type: str  # Pulumi type token
    forces: tuple[str, ...]  # input paths whose change replaces the resource
    source: str  # the provider file whose schema says so (under PROVIDER)


RULES: tuple[ReplaceRule, ...] = (
    ReplaceRule("aws:ec2/vpc:Vpc", ("cidrBlock",), "internal/service/ec2/vpc_.go: cidr_block ForceNew"),
    ReplaceRule("aws:ec2/subnet:Subnet", ("cidrBlock", "vpcId", "availabilityZone", "availabilityZoneId"),
                "internal/service/ec2/vpc_subnet.go: cidr_block, vpc_id, availability_zone(_id) ForceNew"),
    ReplaceRule("aws:ec2/internetGateway:InternetGateway", (),
                "internal/service/ec2/vpc_internet_gateway.go: vpc_id is attached/detached in place"),
    ReplaceRule("aws:ec2/routeTable:RouteTable", ("vpcId",),
                "internal/service/ec2/vpc_route_table.go: vpc_id ForceNew; routes updated in place"),
    ReplaceRule("aws:ec2/routeTableAssociation:RouteTableAssociation", ("subnetId", "gatewayId"),
                "internal/service/ec2/vpc_route_table_association.go: subnet_id, gateway_id ForceNew; "
                "route_table_id replaced in place (ReplaceRouteTableAssociation)"),
    ReplaceRule("aws:ec2/securityGroup:SecurityGroup", ("name", "namePrefix", "description", "vpcId"),
                "internal/service/ec2/vpc_security_group.go: name, name_prefix, description, vpc_id ForceNew"),
    ReplaceRule("aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule", ("securityGroupId",),
                "internal/service/ec2/vpc_security_group_ingress_rule.go: security_group_id RequiresReplace; "
                "ports, protocol, CIDR, description through ModifySecurityGroupRules"),
    ReplaceRule("aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule", ("securityGroupId",),
                "internal/service/ec2/vpc_security_group_egress_rule.go: security_group_id RequiresReplace; "
                "ports, protocol, CIDR, description through ModifySecurityGroupRules"),
    ReplaceRule("aws:acm/certificate:Certificate", (),
                "internal/service/acm/certificate.go: an imported certificate's body, chain and key are "
                "re-imported in place"),
    ReplaceRule("aws:ec2clientvpn/endpoint:Endpoint", ("clientCidrBlock", "authenticationOptions", "transportProtocol"),
                "internal/service/ec2/client_vpn_endpoint.go: client_cidr_block, authentication_options, "
                "transport_protocol ForceNew; the rest through ModifyClientVpnEndpoint"),
    ReplaceRule("aws:ec2clientvpn/networkAssociation:NetworkAssociation", ("clientVpnEndpointId", "subnetId"),
                "internal/service/ec2/client_vpn_network_association.go: client_vpn_endpoint_id, subnet_id ForceNew"),
    ReplaceRule("aws:ec2clientvpn/authorizationRule:AuthorizationRule",
                ("clientVpnEndpointId", "targetNetworkCidr", "accessGroupId", "authorizeAllGroups", "description"),
                "internal/service/ec2/client_vpn_authorization_rule.go: every argument ForceNew (no Update)"),
    ReplaceRule("aws:ec2/keyPair:KeyPair", ("keyName", "keyNamePrefix", "publicKey"),
                "internal/service/ec2/ec2_key_pair.go: key_name, key_name_prefix, public_key ForceNew"),
    ReplaceRule("aws:ec2/instance:Instance",
                ("ami", "subnetId", "availabilityZone", "associatePublicIpAddress", "keyName", "privateIp",
                 "instanceMarketOptions", "rootBlockDevice.encrypted", "rootBlockDevice.kmsKeyId", "tenancy"),
                "internal/service/ec2/ec2_instance.go: ami, subnet_id, availability_zone, "
                "associate_public_ip_address, key_name, private_ip, instance_market_options, "
                "root_block_device.encrypted/kms_key_id, tenancy ForceNew; instance_type, user_data "
                "(user_data_replace_on_change unset), volume size, metadata options in place"),
    ReplaceRule("aws:ec2/defaultSecurityGroup:DefaultSecurityGroup", ("vpcId",),
                "internal/service/ec2/vpc_default_security_group.go: vpc_id ForceNew; rules revoked in place"),
    ReplaceRule("aws:cloudwatch/logGroup:LogGroup", ("name", "namePrefix", "logGroupClass"),
                "internal/service/logs/group.go: name, name_prefix, log_group_class ForceNew; retention, "
                "kms_key_id in place"),
    ReplaceRule("aws:iam/role:Role", ("name", "namePrefix", "path"),
                "internal/service/iam/role.go: name, name_prefix, path ForceNew; assume_role_policy in place"),
    ReplaceRule("aws:iam/rolePolicy:RolePolicy", ("name", "namePrefix", "role"),
                "internal/service/iam/role_policy.go: name, name_prefix, role ForceNew; policy in place"),
    ReplaceRule("aws:ec2/flowLog:FlowLog",
                ("vpcId", "trafficType", "logDestination", "logDestinationType", "iamRoleArn", "logFormat",
                 "maxAggregationInterval", "destinationOptions"),
                "internal/service/ec2/vpc_flow_log.go: every argument but tags ForceNew (no Update)"),
)

_BY_TYPE: dict[str, ReplaceRule] = {rule.type: rule for rule in RULES}


def forces_replacement(type_: str, path: str) -> bool:
    """True when changing input ``path`` (dotted) of a ``type_`` resource replaces it.

    A type fogiac does not know is assumed to update in place: the diff then under-reports, and
    the engine's own preview (``pulumi preview`` in CI) has the last word.
    """
    rule = _BY_TYPE.get(type_)
    if rule is None:
        return False
    return any(path == force or path.startswith(force + ".") or path.startswith(force + "[")
               for force in rule.forces)


def known_types() -> tuple[str, ...]:
    return tuple(_BY_TYPE)
