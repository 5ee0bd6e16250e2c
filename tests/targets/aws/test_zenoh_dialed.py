"""The Zenoh router's certificate on an AWS host names the address the edge dials.

The real stack programs run under Pulumi's mock runtime (no LocalStack: only the instances'
addresses matter), the aws target turns their outputs into SSH access and the addresses the
edge dials, and provisioning's own :class:`HostRun` makes the router's key in a sandbox folder
standing in for the instance. Over the VPN the edge dials the private VPC address (SSH still
goes to the public one); in proxy mode the public address.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pulumi
import pytest
from cryptography import x509

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.net.zenoh import tls
from fogiac.lifecycle.edge import dialed_addresses
from fogiac.plan.compile import compile_plan
from fogiac.provision.local import LocalAccess
from fogiac.provision.steps import HostRun, Options
from fogiac.targets.aws.offline import declare
from fogiac.targets.aws.target import access_from_outputs
from tests.conftest import EXAMPLES

PUBLIC, PRIVATE = "203.0.113.10", "10.10.1.10"


class AddressMocks(pulumi.runtime.Mocks):
    """Every instance gets the same public and private address; other resources echo their inputs."""

    def new_resource(self, args: pulumi.runtime.MockResourceArgs) -> tuple[str, dict[str, Any]]:
        state = dict(args.inputs, arn=f"arn:{args.name}", dnsName=f"{args.name}.example")
        if args.typ == "aws:ec2/instance:Instance":
            state |= {"publicIp": PUBLIC, "privateIp": PRIVATE}
        return f"{args.name}-id", state

    def call(self, args: pulumi.runtime.MockCallArgs) -> dict[str, Any]:
        return {"id": "ami-1", "imageId": "ami-1", "name": "ami", "architecture": "x86_64"}


@pytest.mark.parametrize("mode, dialed", [("vpn", PRIVATE), ("proxy", PUBLIC)])
def test_the_router_certificate_names_what_the_edge_dials(tmp_path: Path, mode: str, dialed: str) -> None:
    manifest = load_manifest(EXAMPLES / "ros2-zenoh.yaml")
    network = manifest.network.model_copy(update={"mode": mode, "ssh_from": "auto" if mode == "vpn" else
                                                  manifest.network.ssh_from})
    plan = compile_plan(manifest.model_copy(update={"network": network}))
    outputs = declare(plan, mocks=AddressMocks()).outputs
    access, connect = access_from_outputs(plan, outputs, fingerprints=lambda _: ("SHA256:pinned",))
    (spec,) = plan.hosts
    assert access[spec.name].address == PUBLIC  # provisioning always reaches the instance over SSH here
    assert dialed_addresses(connect) == {spec.name: dialed}

    load_or_create_bundle(plan.stack, tmp_path / "certs")
    sandbox = LocalAccess(sandbox=tmp_path / "instance")
    run = HostRun(plan=plan, spec=spec, access=dataclasses.replace(sandbox, ros_address=PUBLIC),
                  host=sandbox.open(name=spec.name, known_hosts=tmp_path / "known_hosts", stack=plan.stack),
                  options=Options(certs_dir=tmp_path / "certs", dialed=dialed_addresses(connect)))
    run.host.connect()
    assert run.credentials()
    cert = x509.load_pem_x509_certificate((tmp_path / "instance" / "certs" / "zenoh" / "server.pem").read_bytes())
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert [str(a) for a in san.get_values_for_type(x509.IPAddress)] == [dialed]
    assert san.get_values_for_type(x509.DNSName) == [tls.host_name(plan.stack, spec.name)]
