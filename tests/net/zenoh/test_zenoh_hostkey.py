"""Each cloud router's key is made on its host, as the relay's is; the certificate names the dialed address.

Hosts are real sandbox folders run through :class:`LocalHost`; provisioning's own
:class:`HostRun` makes the credentials, with the address the target says the edge dials.
"""

from __future__ import annotations

import ipaddress
import sys
from pathlib import Path

from cryptography import x509

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.net.zenoh import tls
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision.local import LocalAccess
from fogiac.provision.steps import HostRun, Options
from tests.conftest import EXAMPLES
from tests.support.tls import private_keys_under, public_der


def _run(tmp_path: Path, plan: Plan, *, dialed: dict[str, str]) -> HostRun:
    spec = plan.hosts[0]
    access = LocalAccess(sandbox=tmp_path / "host")
    host = access.open(name=spec.name, known_hosts=tmp_path / "known_hosts", stack=plan.stack)
    host.connect()
    return HostRun(plan=plan, spec=spec, access=access, host=host,
                   options=Options(certs_dir=tmp_path / "operator" / "certs", dialed=dialed))


def _names(cert: Path) -> tuple[list[str], list[str]]:
    san = x509.load_pem_x509_certificate(cert.read_bytes()).extensions.get_extension_for_class(
        x509.SubjectAlternativeName).value
    return san.get_values_for_type(x509.DNSName), [str(a) for a in san.get_values_for_type(x509.IPAddress)]


def test_the_router_key_is_made_on_the_host_for_the_address_the_edge_dials(tmp_path: Path) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "ros2-zenoh.yaml"))
    operator = tmp_path / "operator" / "certs"
    load_or_create_bundle(plan.stack, operator)
    spec = plan.hosts[0]
    (operator / "zenoh").mkdir()
    stale = operator / "zenoh" / f"{spec.name}@203.0.113.9.key"  # where an earlier version kept the host's key
    stale.write_text("old")
    run = _run(tmp_path, plan, dialed={spec.name: "10.10.1.5"})
    assert run.dialed == "10.10.1.5"  # the target's word, not the address provisioning reached it at
    assert run.credentials() is True
    folder = tmp_path / "host" / "certs" / "zenoh"
    assert (folder / "server.key").stat().st_mode & 0o777 == 0o600
    assert _names(folder / "server.pem") == ([tls.host_name(plan.stack, spec.name)], ["10.10.1.5"])
    operator_keys = [k for keys in private_keys_under(tmp_path / "operator").values() for k in keys]
    assert public_der((folder / "server.pem").read_bytes()) not in operator_keys
    assert not stale.exists()
    key = (folder / "server.key").read_bytes()
    assert run.credentials() is False and (folder / "server.key").read_bytes() == key  # kept on a second run

    moved = _run(tmp_path, plan, dialed={spec.name: "10.10.1.6"})  # the edge dials another address now
    assert moved.credentials() is True
    assert _names(folder / "server.pem")[1] == ["10.10.1.6"]


def test_without_the_targets_word_the_host_is_dialed_where_provisioning_reaches_it(tmp_path: Path) -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "ros2-zenoh.yaml"))
    load_or_create_bundle(plan.stack, tmp_path / "operator" / "certs")
    run = _run(tmp_path, plan, dialed={})
    assert run.dialed == "127.0.0.1" and run.credentials()
    assert ipaddress.ip_address(_names(tmp_path / "host" / "certs" / "zenoh" / "server.pem")[1][0]).is_loopback
    assert sys.executable == run.where().python  # the interpreter that runs the router made its key
