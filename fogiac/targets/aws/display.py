"""How ``fogiac plan`` shows the aws stacks' resources: the inputs worth a glance, per Pulumi type.

The CLI finds this table through the plug-in registry (group ``fogiac.key_inputs``, by the type
token's package, ``aws``), so it names no AWS resource itself.
"""

from __future__ import annotations

from collections.abc import Mapping

_RULE = ("ipProtocol", "fromPort", "toPort", "cidrIpv4", "cidrIpv6")
# The inputs worth a glance in `fogiac plan`'s table, per resource type (the JSON has all of them).
KEY_INPUTS: Mapping[str, tuple[str, ...]] = {
    "aws:ec2/vpc:Vpc": ("cidrBlock",),
    "aws:ec2/subnet:Subnet": ("cidrBlock", "availabilityZone", "mapPublicIpOnLaunch"),
    "aws:ec2/routeTable:RouteTable": ("routes",),
    "aws:ec2/routeTableAssociation:RouteTableAssociation": ("subnetId", "routeTableId"),
    "aws:ec2/securityGroup:SecurityGroup": ("name",),
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": _RULE,
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": _RULE,
    "aws:acm/certificate:Certificate": ("certificateBody", "privateKey"),
    "aws:ec2clientvpn/endpoint:Endpoint": ("clientCidrBlock", "splitTunnel", "transportProtocol", "vpnPort",
                                           "authenticationOptions"),
    "aws:ec2clientvpn/networkAssociation:NetworkAssociation": ("subnetId",),
    "aws:ec2clientvpn/authorizationRule:AuthorizationRule": ("targetNetworkCidr",),
    "aws:ec2/keyPair:KeyPair": ("keyName",),
    "aws:ec2/instance:Instance": ("instanceType", "ami", "rootBlockDevice", "metadataOptions", "instanceMarketOptions"),
}
