"""Issue 34 on aws in vpn mode: each robot of a fleet dials the Client VPN with a certificate of its own, and a
robot revoked (``fogiac robot revoke``) or dropped from ``robots:`` is refused by the endpoint through a CRL
signed by the stack's CA; ``restore`` hands the endpoint a CRL without it.

Before, every robot used the stack's one client certificate, so a revoked robot, cut at the relay's cloud ends,
kept its way into the VPC. The CRL is checked as real files (its signature against the CA, the serials it
lists, its mode) and by ``openssl verify -crl_check``, as OpenVPN checks a client against a CRL. LocalStack
does not implement Client VPN (``create_client_vpn_endpoint`` is "not implemented", see TESTING.md), so the
import into the endpoint (``ImportClientVpnClientCertificateRevocationList``) is checked with botocore's
Stubber: the sanctioned stand-in for an API LocalStack lacks; it checks the request against EC2's own model.
"""

from __future__ import annotations

import dataclasses
import shutil
import socket
import stat
import subprocess
from pathlib import Path
from typing import Any

import boto3
import pytest
from botocore.stub import ANY, Stubber
from cryptography import x509
from cryptography.x509.oid import NameOID
from typer.testing import CliRunner

from fogiac import certs
from fogiac.cli import app
from fogiac.errors import CloudError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision import SshAccess
from fogiac.state import StackState
from fogiac.targets.aws import api, engine, robotvpn
from fogiac.targets.aws.errors import VpnError
from fogiac.targets.aws.target import AWS, HOST_KEYS_FILE
from fogiac.targets.aws.vpn import default_profile_path, write_client_profile
from fogiac.targets.base import Created
from tests.plugins.install import installed

STACK = "lab-dev"
ENDPOINT = "cvpn-endpoint-0123456789abcdef0"
DNS = "*.cvpn-endpoint-0123456789abcdef0.prod.clientvpn.us-west-2.amazonaws.com"
ROBOT = '  - {{name: {name}, ros_master: "http://127.0.0.1:{port}"}}\n'
NODES = """nodes:
  - name: planner
    machine: t3.small
    image: ros:noetic-ros-core
    topics: {in: [/plan/request], out: [/plan/path]}
"""


def _plan(tmp_path: Path, robots: tuple[str, ...] = ("arm1", "arm2", "arm3")) -> Plan:
    head = "name: lab\ncloud: {provider: aws, region: us-west-2}\nnetwork: {mode: vpn}\n"
    listed = "robots:\n" + "".join(ROBOT.format(name=r, port=11312 + i) for i, r in enumerate(robots))
    path = tmp_path / "fogiac.yaml"
    path.write_text(head + listed + NODES)
    return compile_plan(load_manifest(path))


def _cert(pem: bytes) -> x509.Certificate:
    return x509.load_pem_x509_certificate(pem)


def _inline(profile: Path, tag: str) -> bytes:
    text = profile.read_text()
    return text.split(f"<{tag}>")[1].split(f"</{tag}>")[0].strip().encode() + b"\n"


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def _revoke(*robots: str) -> None:
    """What ``fogiac robot revoke``/``restore`` leave in the record of a deployed stack (which has sections)."""
    def change(document: dict[str, Any]) -> None:
        document.setdefault(StackState.DEPLOYMENT, {"target": "aws"})
        if robots:
            document[StackState.REVOKED] = sorted(robots)
        else:
            document.pop(StackState.REVOKED, None)
    StackState(STACK).update(change)


def _crl(path: Path) -> x509.CertificateRevocationList:
    return x509.load_pem_x509_crl(path.read_bytes())


def _serials(crl: x509.CertificateRevocationList) -> set[int]:
    return {entry.serial_number for entry in crl}


def _robot_serial(robot: str) -> int:
    return _cert((StackState(STACK).certs / robotvpn.FOLDER / f"{robot}.pem").read_bytes()).serial_number


@pytest.fixture
def ec2(monkeypatch: pytest.MonkeyPatch) -> Any:
    """A real botocore EC2 client whose answers the Stubber gives (no request leaves the machine); the aws
    target's api module hands it out as it would a client of the operator's session."""
    client = boto3.session.Session(aws_access_key_id="test", aws_secret_access_key="test",
                                   region_name="us-west-2").client("ec2")
    monkeypatch.setattr(api, "client", lambda service, *, region: client)
    return client


def test_each_robot_gets_its_own_certificate_and_profile(tmp_path: Path, _state_dir: Path) -> None:
    plan = _plan(tmp_path)
    bundle = certs.load_or_create_bundle(STACK, StackState(STACK).certs)
    shared = write_client_profile(endpoint_dns=DNS, stack=STACK, bundle=bundle)  # a one-robot past's profile
    profiles = robotvpn.write_profiles(plan, endpoint_dns=DNS)
    assert sorted(profiles) == ["arm1", "arm2", "arm3"]
    assert not shared.exists()  # its certificate is refused in a fleet: the profile goes with it
    seen: set[int] = set()
    for robot, profile in profiles.items():
        assert profile == default_profile_path(STACK, robot=robot, create=False)
        assert _mode(profile) == 0o600 and _mode(profile.parent) == 0o700
        cert = _cert(_inline(profile, "cert"))
        assert cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == f"{robot}.vpn.{STACK}.fogiac"
        cert.verify_directly_issued_by(_cert(bundle.ca.cert_pem))  # the stack's CA, which the endpoint trusts
        assert cert.serial_number != _cert(bundle.client.cert_pem).serial_number
        seen.add(cert.serial_number)
        key = StackState(STACK).certs / robotvpn.FOLDER / f"{robot}.key"
        assert _mode(key) == 0o600 and _inline(profile, "key") == key.read_bytes()
    assert len(seen) == 3
    again = robotvpn.write_profiles(plan, endpoint_dns=DNS)  # kept: a second up reissues nothing
    assert {_cert(_inline(p, "cert")).serial_number for p in again.values()} == seen


def test_a_one_robot_stack_keeps_its_one_profile_and_imports_nothing(tmp_path: Path, _state_dir: Path,
                                                                       ec2: Any) -> None:
    manifest = tmp_path / "one.yaml"
    manifest.write_text("name: lab\ncloud: {provider: aws, region: us-west-2}\nnetwork: {mode: vpn}\n"
                        'edge: {ros_master: "http://127.0.0.1:11312"}\n' + NODES)
    plan = compile_plan(load_manifest(manifest))
    assert not plan.fleet
    StackState(STACK).write(engine.OUTPUTS_FILE, {"network": {"vpn_endpoint_id": ENDPOINT, "vpn_dns_name": DNS}})
    with Stubber(ec2) as stub:  # no response queued: any call would fail the test
        assert AWS.refuse_revoked(plan) == "no Client VPN endpoint: nothing to refuse there"
        stub.assert_no_pending_responses()
    assert not (StackState(STACK).certs / robotvpn.FOLDER).exists()


def test_the_crl_lists_exactly_the_revoked_and_removed_robots(tmp_path: Path, _state_dir: Path) -> None:
    plan = _plan(tmp_path)
    robotvpn.write_profiles(plan, endpoint_dns=DNS)
    bundle = certs.load_or_create_bundle(STACK, StackState(STACK).certs)
    ca = _cert(bundle.ca.cert_pem)
    shared = _cert(bundle.client.cert_pem).serial_number

    made = robotvpn.write_crl(plan, revoked=("arm3",))
    crl = _crl(made.path)
    assert crl.is_signature_valid(ca.public_key())  # type: ignore[arg-type]
    assert crl.issuer == ca.subject and crl.next_update_utc == ca.not_valid_after_utc  # never expires before the CA
    assert _serials(crl) == {_robot_serial("arm3"), shared} and made.robots == ("arm3",)
    assert _mode(made.path) == 0o644 and b"PRIVATE" not in made.path.read_bytes()  # public: no key in it

    arm2 = _robot_serial("arm2")
    smaller = _plan(tmp_path, robots=("arm1", "arm3"))
    assert robotvpn.retire_dropped(STACK, [e.name for e in smaller.edges]) == ("arm2",)
    assert not (StackState(STACK).certs / robotvpn.FOLDER / "arm2.key").exists()
    crl = _crl(robotvpn.write_crl(smaller, revoked=()).path)
    assert _serials(crl) == {arm2, shared}  # removed for good; arm3 no longer revoked

    back = _plan(tmp_path)  # arm2 added again: a new certificate, not the refused one
    robotvpn.write_profiles(back, endpoint_dns=DNS)
    assert _robot_serial("arm2") != arm2
    assert _serials(_crl(robotvpn.write_crl(back, revoked=()).path)) == {arm2, shared}


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl command")
def test_openssl_refuses_a_revoked_robot_and_accepts_the_others(tmp_path: Path, _state_dir: Path) -> None:
    """What OpenVPN does with a CRL (``crl-verify``), done by OpenSSL itself on the files fogiac wrote."""
    plan = _plan(tmp_path)
    profiles = robotvpn.write_profiles(plan, endpoint_dns=DNS)
    crl = robotvpn.write_crl(plan, revoked=("arm3",)).path
    ca = StackState(STACK).certs / "ca.pem"

    def verify(pem: bytes) -> subprocess.CompletedProcess[str]:
        leaf = tmp_path / "leaf.pem"
        leaf.write_bytes(pem)
        return subprocess.run(["openssl", "verify", "-crl_check", "-CAfile", str(ca), "-CRLfile", str(crl),
                               str(leaf)], capture_output=True, text=True)

    for robot in ("arm1", "arm2"):
        ok = verify(_inline(profiles[robot], "cert"))
        assert ok.returncode == 0, ok.stdout + ok.stderr
    refused = verify(_inline(profiles["arm3"], "cert"))
    assert refused.returncode != 0 and "revoked" in (refused.stdout + refused.stderr)
    shared = verify((StackState(STACK).certs / "client.pem").read_bytes())
    assert shared.returncode != 0 and "revoked" in (shared.stdout + shared.stderr)


def test_revoke_and_restore_hand_the_endpoint_its_crl_once(tmp_path: Path, _state_dir: Path, ec2: Any) -> None:
    plan = _plan(tmp_path)
    robotvpn.write_profiles(plan, endpoint_dns=DNS)
    StackState(STACK).write(engine.OUTPUTS_FILE, {"network": {"vpn_endpoint_id": ENDPOINT, "vpn_dns_name": DNS}})
    sent: list[str] = []
    ec2.meta.events.register("provide-client-params.ec2.ImportClientVpnClientCertificateRevocationList",
                             lambda params, **_: sent.append(params["CertificateRevocationList"]))
    expected = {"ClientVpnEndpointId": ENDPOINT, "CertificateRevocationList": ANY}
    shared = _cert((StackState(STACK).certs / "client.pem").read_bytes()).serial_number

    with Stubber(ec2) as stub:
        stub.add_response("import_client_vpn_client_certificate_revocation_list", {"Return": True}, expected)
        _revoke("arm3")
        line = AWS.refuse_revoked(plan)
        assert line.startswith(f"Client VPN {ENDPOINT} now refuses arm3"), line
        assert _serials(x509.load_pem_x509_crl(sent[-1].encode())) == {_robot_serial("arm3"), shared}

        # nothing changed: importing would reset every robot's tunnel, so no call (none is queued)
        assert AWS.refuse_revoked(plan).startswith(f"Client VPN {ENDPOINT} already refuses arm3")

        stub.add_response("import_client_vpn_client_certificate_revocation_list", {"Return": True}, expected)
        _revoke()  # restore
        assert AWS.refuse_revoked(plan).startswith(f"Client VPN {ENDPOINT} now refuses no robot")
        assert _serials(x509.load_pem_x509_crl(sent[-1].encode())) == {shared}
        stub.assert_no_pending_responses()
    assert len(sent) == 2


def test_an_endpoint_that_refuses_the_crl_is_one_line(tmp_path: Path, _state_dir: Path, ec2: Any) -> None:
    plan = _plan(tmp_path)
    StackState(STACK).write(engine.OUTPUTS_FILE, {"network": {"vpn_endpoint_id": ENDPOINT, "vpn_dns_name": DNS}})
    with Stubber(ec2) as stub:
        stub.add_client_error("import_client_vpn_client_certificate_revocation_list",
                              service_error_code="InvalidParameterValue", service_message="bad CRL")
        with pytest.raises(CloudError) as err:
            AWS.refuse_revoked(plan)
    assert str(err.value).count("\n") == 0 and ENDPOINT in str(err.value) and "InvalidParameterValue" in str(err.value)
    with Stubber(ec2) as stub:  # not remembered as imported: the next revoke or up tries again
        stub.add_response("import_client_vpn_client_certificate_revocation_list", {"Return": True})
        assert "now refuses" in AWS.refuse_revoked(plan)


def test_a_robot_name_that_is_no_label_is_one_line(_state_dir: Path) -> None:
    with pytest.raises(VpnError, match=r"robot '\.\./x': a robot's name is one DNS label"):
        default_profile_path(STACK, robot="../x", create=False)


def _reach(plan: Plan, ec2: Any) -> list[str]:
    """The aws target's step after the stacks, on the outputs a stack of one host reports (its host keys pinned
    already, so no console is read)."""
    outputs = {"network": {"vpn_endpoint_id": ENDPOINT, "vpn_dns_name": DNS},
               "compute": {"hosts": {"planner": {"instance_id": "i-0abc", "public_ip": "198.51.100.7",
                                                  "private_ip": "10.10.1.7"}}}}
    StackState(STACK).write(engine.OUTPUTS_FILE, outputs)
    StackState(STACK).write(HOST_KEYS_FILE, {"i-0abc": ["SHA256:pinned"]})
    said: list[str] = []
    AWS.reach(plan, Created(plan=plan, outputs=outputs), announce=said.append)
    return said


def test_up_writes_each_robots_profile_and_hands_the_endpoint_the_crl(tmp_path: Path, _state_dir: Path,
                                                                        ec2: Any) -> None:
    plan = _plan(tmp_path)
    with Stubber(ec2) as stub:
        stub.add_response("import_client_vpn_client_certificate_revocation_list", {"Return": True},
                          {"ClientVpnEndpointId": ENDPOINT, "CertificateRevocationList": ANY})
        said = _reach(plan, ec2)
        stub.assert_no_pending_responses()
        assert [line for line in said if line.startswith("VPN profile of robot")] == [
            f"VPN profile of robot {r}: {default_profile_path(STACK, robot=r, create=False)} (connect with: sudo "
            f"fogiac vpn up --robot {r}, or on the robot itself: sudo fogiac vpn up --profile PATH)"
            for r in ("arm1", "arm2", "arm3")]
        assert f"Client VPN {ENDPOINT} now refuses no robot (the stack's shared certificate too); the other " \
               "robots' tunnels redial" in said
        assert not default_profile_path(STACK, create=False).exists()
        again = _reach(plan, ec2)  # nothing new to refuse: no import (none queued), no tunnel reset
        assert f"Client VPN {ENDPOINT} already refuses no robot (the stack's shared certificate too)" in again

        stub.add_response("import_client_vpn_client_certificate_revocation_list", {"Return": True})
        arm2 = _robot_serial("arm2")
        said = _reach(_plan(tmp_path, robots=("arm1", "arm3")), ec2)  # arm2 dropped from robots:
        assert "robot arm2 left robots:, so its VPN certificate is revoked for good" in said
        assert any(line.startswith(f"Client VPN {ENDPOINT} now refuses arm2") for line in said), said
        assert arm2 in _serials(_crl(StackState(STACK).certs / robotvpn.FOLDER / robotvpn.CRL))
        stub.assert_no_pending_responses()


def test_up_of_a_one_robot_stack_is_as_before(tmp_path: Path, _state_dir: Path, ec2: Any) -> None:
    manifest = tmp_path / "one.yaml"
    manifest.write_text("name: lab\ncloud: {provider: aws, region: us-west-2}\nnetwork: {mode: vpn}\n"
                        'edge: {ros_master: "http://127.0.0.1:11312"}\n' + NODES)
    with Stubber(ec2) as stub:  # nothing queued: any AWS call fails the test
        said = _reach(compile_plan(load_manifest(manifest)), ec2)
        stub.assert_no_pending_responses()
    profile = default_profile_path(STACK, create=False)
    assert said[0] == (f"VPN profile: {profile} (connect with: sudo fogiac vpn up; the relays retry until it is "
                       "up)")
    assert _inline(profile, "cert") == (StackState(STACK).certs / "client.pem").read_bytes()
    assert not (StackState(STACK).certs / robotvpn.FOLDER).exists()


def _vpn_facing(plan: Plan) -> dict[str, set[int]]:
    """Each source of the hosts group's ingress rules -> the ports it opens (SSH's aside)."""
    (hosts,) = [g for g in plan.security_groups if g.name == "hosts"]
    opened: dict[str, set[int]] = {}
    for rule in hosts.ingress:
        if rule.from_port != 22:
            opened.setdefault(rule.cidr, set()).add(rule.from_port)
    return opened


def test_a_fleets_robots_reach_the_relays_port_only(tmp_path: Path) -> None:
    """The endpoint source-NATs its clients into the VPC (its subnet ``vpn``): a fleet opens the master's and the
    nodes' ports to the hosts' subnet only, so a robot cannot reach the master every robot's topics pass through
    past the relay's per-robot access; a one-robot stack's rules are as before."""
    fleet = _plan(tmp_path)
    subnets = {s.role: s.cidr for s in fleet.network.subnets}  # type: ignore[union-attr]
    assert _vpn_facing(fleet) == {subnets["instances"]: {11311, 32768}, "10.10.0.0/16": {11411},
                                  "10.200.0.0/22": {11411}}
    manifest = tmp_path / "one.yaml"
    manifest.write_text("name: lab\ncloud: {provider: aws, region: us-west-2}\nnetwork: {mode: vpn}\n"
                        'edge: {ros_master: "http://127.0.0.1:11312"}\n' + NODES)
    one = compile_plan(load_manifest(manifest))
    assert _vpn_facing(one) == {"10.10.0.0/16": {11311, 32768, 11411}, "10.200.0.0/22": {11311, 32768, 11411}}


def test_robot_revoke_has_the_endpoint_refuse_the_robot_too(tmp_path: Path, _state_dir: Path, ec2: Any,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """``fogiac robot revoke`` on aws: besides every host's ``fleet.json``, the Client VPN endpoint gets the CRL
    listing the robot. The one host recorded here cannot be reached (a closed local port), so its rewrite fails
    and is named; the endpoint still refuses the robot, and the exit status says something failed."""
    plan = _plan(tmp_path)
    robotvpn.write_profiles(plan, endpoint_dns=DNS)
    StackState(STACK).write(engine.OUTPUTS_FILE, {"network": {"vpn_endpoint_id": ENDPOINT, "vpn_dns_name": DNS}})
    closed = socket.socket()
    closed.bind(("127.0.0.1", 0))  # bound, never listening: a connection is refused at once
    access = {"kind": "ssh", "address": "127.0.0.1", "user": "ubuntu", "port": closed.getsockname()[1],
              "key": str(tmp_path / "id"), "base_dir": "/opt/fogiac", "python": "python3"}
    StackState(STACK).set(StackState.HOSTS, {"planner": {**access, "base": "/opt/fogiac", "nodes": ["planner"]}})
    # an instance's patience is a minute (a booting one answers within it); a closed port needs a second
    monkeypatch.setattr(AWS, "access_from", lambda d: dataclasses.replace(SshAccess.from_description(d),
                                                                          connect_timeout=1.0))
    sent: list[str] = []
    ec2.meta.events.register("provide-client-params.ec2.ImportClientVpnClientCertificateRevocationList",
                             lambda params, **_: sent.append(params["CertificateRevocationList"]))
    try:
        with installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}), \
                Stubber(ec2) as stub:
            stub.add_response("import_client_vpn_client_certificate_revocation_list", {"Return": True},
                              {"ClientVpnEndpointId": ENDPOINT, "CertificateRevocationList": ANY})
            result = CliRunner().invoke(app, ["robot", "revoke", "arm3", str(tmp_path / "fogiac.yaml"),
                                              "--target", "aws"])
            stub.assert_no_pending_responses()
    finally:
        closed.close()
    assert result.exit_code == 1, result.output
    assert f"Client VPN {ENDPOINT} now refuses arm3 (the stack's shared certificate too)" in result.output
    assert "robot arm3 revoked" in result.output and "(0 of 1 hosts)" in result.output
    assert StackState(STACK).get(StackState.REVOKED) == ["arm3"]
    assert _serials(x509.load_pem_x509_crl(sent[0].encode())) == {
        _robot_serial("arm3"), _cert((StackState(STACK).certs / "client.pem").read_bytes()).serial_number}
