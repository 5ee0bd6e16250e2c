"""ClientVpn: ACM certificates with secret keys, mutual TLS, split tunnel, VPC authorization."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from fogiac.certs import Bundle, new_bundle, save_bundle, save_pair
from fogiac.net import hostcert
from fogiac.net.relay.tls import relay_name
from fogiac.provision.local import LocalHost
from fogiac.targets.aws.offline import OfflinePlan
from stacks.aws.program import network_program
from tests.support.tls import handshake, public_der

from .conftest import EXAMPLES, compiled
from .recorder import Recorder, is_secret


@pytest.fixture(scope="module")
def bundle() -> Bundle:
    return new_bundle("minimal-dev")


@pytest.fixture(scope="module")
def recorded(bundle: Bundle) -> tuple[Recorder, dict]:
    plan = compiled(EXAMPLES / "minimal.yaml")
    recorder = Recorder()
    exports = recorder.run(
        lambda: network_program(plan, certs=bundle, operator_cidrs=("192.0.2.7/32",)), stack=plan.stack
    )
    return recorder, exports


def test_endpoint_uses_mutual_tls_and_split_tunnel(offline: dict[str, OfflinePlan]) -> None:
    (endpoint,) = offline["minimal"].of_type("aws:ec2clientvpn/endpoint:Endpoint")
    inputs = endpoint.inputs
    assert inputs["authenticationOptions"] == (
        {"type": "certificate-authentication", "rootCertificateChainArn": "<minimal-dev-cert-client.arn>"},
    )
    assert inputs["serverCertificateArn"] == "<minimal-dev-cert-server.arn>"
    assert inputs["splitTunnel"] is True
    assert inputs["clientCidrBlock"] == "10.200.0.0/22"
    assert (inputs["transportProtocol"], inputs["vpnPort"]) == ("udp", 443)
    assert inputs["connectionLogOptions"] == {"enabled": True, "cloudwatchLogGroup": "/fogiac/minimal-dev/client-vpn"}
    assert inputs["securityGroupIds"] == ("<minimal-dev-sg-vpn.id>",)
    assert inputs["vpcId"] == "<minimal-dev-vpc.id>"


def test_association_and_authorization(offline: dict[str, OfflinePlan]) -> None:
    (association,) = offline["minimal"].of_type("aws:ec2clientvpn/networkAssociation:NetworkAssociation")
    assert association.inputs == {
        "clientVpnEndpointId": "<minimal-dev-endpoint.id>", "subnetId": "<minimal-dev-subnet-vpn.id>"
    }
    (rule,) = offline["minimal"].of_type("aws:ec2clientvpn/authorizationRule:AuthorizationRule")
    assert rule.inputs["targetNetworkCidr"] == "10.10.0.0/16"
    assert rule.inputs["authorizeAllGroups"] is True


def test_offline_plan_shows_no_key_material(offline: dict[str, OfflinePlan]) -> None:
    for cert in offline["minimal"].of_type("aws:acm/certificate:Certificate"):
        assert cert.inputs["privateKey"] == "[secret]"
        assert "made at up" in cert.inputs["certificateBody"]


def test_acm_gets_the_bundle_with_private_keys_as_secrets(recorded: tuple[Recorder, dict], bundle: Bundle) -> None:
    recorder, _ = recorded
    server = recorder.inputs["minimal-dev-cert-server"]
    client = recorder.inputs["minimal-dev-cert-client"]
    assert server["certificateBody"] == bundle.vpn.cert_pem.decode()
    assert client["certificateBody"] == bundle.client.cert_pem.decode()
    assert server["certificateChain"] == client["certificateChain"] == bundle.ca.cert_pem.decode()
    for inputs, pair in ((server, bundle.vpn), (client, bundle.client)):
        assert is_secret(inputs["privateKey"])
        assert inputs["privateKey"]["value"] == pair.key_pem.decode()
    endpoint = recorder.inputs["minimal-dev-endpoint"]
    assert endpoint["serverCertificateArn"] == "arn:aws:test:::minimal-dev-cert-server"
    assert endpoint["authenticationOptions"][0]["rootCertificateChainArn"] == "arn:aws:test:::minimal-dev-cert-client"


def test_slow_vpn_resources_wait_thirty_minutes(recorded: tuple[Recorder, dict]) -> None:
    recorder, _ = recorded
    for name in ("minimal-dev-endpoint", "minimal-dev-vpn-association"):
        timeouts = recorder.options[name].custom_timeouts
        assert (timeouts.create, timeouts.delete) == ("30m", "30m")


def test_ids_from_the_mocks_flow_into_dependants(recorded: tuple[Recorder, dict]) -> None:
    recorder, exports = recorded
    assert recorder.inputs["minimal-dev-vpn-association"] == {
        "clientVpnEndpointId": "id-minimal-dev-endpoint", "subnetId": "id-minimal-dev-subnet-vpn"
    }
    assert exports["vpn_endpoint_id"] == "id-minimal-dev-endpoint"
    assert exports["vpn_dns_name"] == "*.minimal-dev-endpoint.example"
    assert exports["subnet_ids"] == {"hosts": "id-minimal-dev-subnet-hosts", "vpn": "id-minimal-dev-subnet-vpn"}
    ssh = recorder.inputs["minimal-dev-hosts-in-tcp-22-192.0.2.7-32"]
    assert ssh["cidrIpv4"] == "192.0.2.7/32"
    assert ssh["securityGroupId"] == "id-minimal-dev-sg-hosts"



def test_acm_server_certificate_is_no_hosts(recorded: tuple[Recorder, dict], bundle: Bundle, tmp_path: Path) -> None:
    """The endpoint's certificate is its own: every host's relay certificate (made the way
    provisioning makes it, key on the host) differs from it, and the edge dialing a host refuses it."""
    recorder, _ = recorded
    acm = recorder.inputs["minimal-dev-cert-server"]["certificateBody"].encode()
    assert acm == bundle.vpn.cert_pem
    plan = compiled(EXAMPLES / "minimal.yaml")
    edge = tmp_path / "edge"
    save_bundle(bundle, edge)
    endpoint = tmp_path / "endpoint"  # a cloud end that shows the VPN endpoint's certificate
    save_pair(endpoint, "server", bundle.vpn)
    (endpoint / "ca.pem").write_bytes(bundle.ca.cert_pem)
    assert plan.hosts
    for spec in plan.hosts:
        host = LocalHost(name=spec.name, base=str(tmp_path / "hosts" / spec.name))
        host.connect()
        folder = f"{host.base}/certs"
        assert hostcert.ensure(host, python=sys.executable, folder=folder, ca=bundle.ca,
                                name=relay_name(plan.stack, spec.name))
        mine = Path(folder, "server.pem").read_bytes()
        assert mine != acm and public_der(mine) != public_der(acm)
        refused = handshake(endpoint, edge, relay_name(plan.stack, spec.name))
        assert refused is not None and "Hostname mismatch" in refused
