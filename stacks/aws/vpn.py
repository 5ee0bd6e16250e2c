"""ClientVpn: the edge's way into the VPC, authenticated by certificates on both sides.

The endpoint's own server certificate (never a host's: each host's relay key stays on the
host) and the client certificate (RSA 2048, as AWS requires) are imported into ACM; the client
one's chain is the trust root the endpoint checks clients against (mutual TLS). Split
tunnel: only VPC routes go through it, so the robot keeps its own internet path. Every connection
is logged to a CloudWatch log group of the stack. Creating the
association takes about ten minutes, hence the long timeouts.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import pulumi
import pulumi_aws as aws

from fogiac.certs import Bundle, KeyPair
from fogiac.targets.aws.model import VpnSpec
from stacks.aws.network import log_group
from stacks.aws.tags import tagged

SLOW = pulumi.CustomTimeouts(create="30m", update="30m", delete="30m")


@dataclass(frozen=True)
class ClientVpnArgs:
    spec: VpnSpec
    certs: Bundle
    vpc_id: pulumi.Input[str]
    subnet_id: pulumi.Input[str]
    security_group_id: pulumi.Input[str]
    tags: Mapping[str, str]


def _text(data: bytes) -> str:
    return data.decode("ascii")


class ClientVpn(pulumi.ComponentResource):
    """ACM certificates, the endpoint, its subnet association and the VPC authorization rule."""

    endpoint: aws.ec2clientvpn.Endpoint

    def __init__(self, name: str, args: ClientVpnArgs, opts: pulumi.ResourceOptions | None = None) -> None:
        super().__init__("fogiac:aws:ClientVpn", name, None, opts)
        child = pulumi.ResourceOptions(parent=self)

        def certificate(role: str, pair: KeyPair) -> aws.acm.Certificate:
            return aws.acm.Certificate(
                f"{name}-cert-{role}",
                certificate_body=_text(pair.cert_pem),
                private_key=pulumi.Output.secret(_text(pair.key_pem)),
                certificate_chain=_text(args.certs.ca.cert_pem),
                tags=tagged(args.tags, f"{name}-{role}"),
                opts=child,
            )

        self.server_certificate = certificate("server", args.certs.vpn)
        self.client_certificate = certificate("client", args.certs.client)
        spec = args.spec
        self.log_group = log_group(name, "vpn-logs", "client-vpn", tags=args.tags, opts=child)
        self.endpoint = aws.ec2clientvpn.Endpoint(
            f"{name}-endpoint",
            description=f"fogiac {name}",
            server_certificate_arn=self.server_certificate.arn,
            client_cidr_block=spec.client_cidr,
            authentication_options=[
                aws.ec2clientvpn.EndpointAuthenticationOptionArgs(
                    type="certificate-authentication",
                    root_certificate_chain_arn=self.client_certificate.arn,
                )
            ],
            connection_log_options=aws.ec2clientvpn.EndpointConnectionLogOptionsArgs(
                enabled=True, cloudwatch_log_group=self.log_group.name
            ),
            split_tunnel=spec.split_tunnel,
            transport_protocol=spec.transport,
            vpn_port=spec.port,
            vpc_id=args.vpc_id,
            security_group_ids=[args.security_group_id],
            tags=tagged(args.tags, f"{name}-vpn"),
            opts=pulumi.ResourceOptions(parent=self, custom_timeouts=SLOW),
        )
        self.association = aws.ec2clientvpn.NetworkAssociation(
            f"{name}-vpn-association",
            client_vpn_endpoint_id=self.endpoint.id,
            subnet_id=args.subnet_id,
            opts=pulumi.ResourceOptions(parent=self, custom_timeouts=SLOW),
        )
        self.authorization = aws.ec2clientvpn.AuthorizationRule(
            f"{name}-vpn-authorize",
            client_vpn_endpoint_id=self.endpoint.id,
            target_network_cidr=spec.authorize_cidr,
            authorize_all_groups=True,
            description="the edge reaches the VPC",
            opts=child,
        )
        self.register_outputs({"vpn_endpoint_id": self.endpoint.id, "vpn_dns_name": self.endpoint.dns_name})
