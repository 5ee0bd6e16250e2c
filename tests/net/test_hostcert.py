"""Each host's relay key is made on the host; only a CSR comes back, signed by the operator's CA.

Hosts here are real sandbox folders run through :class:`LocalHost` (bash, the host's python),
the handshakes real TLS 1.3 between the relay's own contexts.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import NameOID

from fogiac.certs import Bundle, KeyPair, issue, load_or_create_bundle, new_ca, serves, sign_csr
from fogiac.errors import CertError, ProvisionError
from fogiac.net import hostcert
from fogiac.net.relay.tls import relay_name
from fogiac.provision.local import LocalHost
from tests.support.tls import handshake, private_keys_under, public_der

STACK = "rc-dev"


class Fleet:
    def __init__(self, root: Path) -> None:
        self.state = root / "state"
        self.bundle: Bundle = load_or_create_bundle(STACK, self.state / "certs")
        self.hosts = {n: LocalHost(name=n, base=str(root / "hosts" / n)) for n in ("a", "b")}
        for host in self.hosts.values():
            host.connect()
            host.put(self.bundle.ca.cert_pem, f"{self.folder(host.name)}/ca.pem")

    def folder(self, name: str) -> str:
        return f"{self.hosts[name].base}/certs"

    def ensure(self, name: str, *, ca: KeyPair | None = None) -> bool:
        return hostcert.ensure(self.hosts[name], python=sys.executable, folder=self.folder(name),
                                ca=ca or self.bundle.ca, name=relay_name(STACK, name))

    def cert(self, name: str) -> bytes:
        return Path(self.folder(name), "server.pem").read_bytes()

    def key(self, name: str) -> bytes:
        return Path(self.folder(name), "server.key").read_bytes()


@pytest.fixture
def fleet(tmp_path: Path) -> Fleet:
    return Fleet(tmp_path)


def test_each_host_makes_its_own_key_and_the_operator_keeps_none(fleet: Fleet) -> None:
    assert fleet.ensure("a") and fleet.ensure("b")
    for name in ("a", "b"):
        assert Path(fleet.folder(name), "server.key").stat().st_mode & 0o777 == 0o600
        cert = x509.load_pem_x509_certificate(fleet.cert(name))
        names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        assert names.get_values_for_type(x509.DNSName) == [relay_name(STACK, name)]
    assert fleet.cert("a") != fleet.cert("b") and public_der(fleet.cert("a")) != public_der(fleet.cert("b"))
    operator = [k for keys in private_keys_under(fleet.state).values() for k in keys]
    assert len(operator) == 3  # ca, vpn, client: nothing of a host
    assert not {public_der(fleet.cert("a")), public_der(fleet.cert("b"))} & set(operator)
    assert sorted(p.name for p in (fleet.state / "certs").iterdir()) == [
        "ca.key", "ca.pem", "client.key", "client.pem", "vpn.key", "vpn.pem"]


def test_the_edge_refuses_host_a_when_dialing_host_b(fleet: Fleet) -> None:
    fleet.ensure("a")
    fleet.ensure("b")
    edge = fleet.state / "certs"
    assert handshake(Path(fleet.folder("a")), edge, relay_name(STACK, "a")) is None
    assert handshake(Path(fleet.folder("b")), edge, relay_name(STACK, "b")) is None
    refused = handshake(Path(fleet.folder("a")), edge, relay_name(STACK, "b"))
    assert refused is not None and "Hostname mismatch" in refused


def test_a_second_run_keeps_the_key_and_the_certificate(fleet: Fleet) -> None:
    fleet.ensure("a")
    key, cert = fleet.key("a"), fleet.cert("a")
    assert fleet.ensure("a") is False
    assert (fleet.key("a"), fleet.cert("a")) == (key, cert)


def test_another_hosts_or_cas_certificate_is_replaced_with_a_fresh_key(fleet: Fleet) -> None:
    fleet.ensure("a")
    fleet.ensure("b")
    old_key = fleet.key("a")
    shutil.copy(Path(fleet.folder("b"), "server.pem"), Path(fleet.folder("a"), "server.pem"))
    assert fleet.ensure("a") is True
    assert fleet.key("a") != old_key
    assert serves(fleet.bundle.ca, fleet.cert("a"), relay_name(STACK, "a"), _public(fleet.key("a")))
    stranger = new_ca("stranger")
    assert fleet.ensure("a", ca=stranger) is True  # the stranger's CA did not sign what is there
    assert serves(stranger, fleet.cert("a"), relay_name(STACK, "a"), _public(fleet.key("a")))
    assert not serves(fleet.bundle.ca, fleet.cert("a"), relay_name(STACK, "a"), _public(fleet.key("a")))


def test_a_certificate_about_to_expire_is_not_kept(fleet: Fleet) -> None:
    fleet.ensure("a")
    public = _public(fleet.key("a"))
    assert serves(fleet.bundle.ca, fleet.cert("a"), relay_name(STACK, "a"), public)
    assert not serves(fleet.bundle.ca, fleet.cert("a"), relay_name(STACK, "a"), public, days=10_000)


def _public(key_pem: bytes) -> bytes:
    key = serialization.load_pem_private_key(key_pem, password=None)
    return key.public_key().public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)


def _csr(key: rsa.RSAPrivateKey, name: str) -> bytes:
    builder = x509.CertificateSigningRequestBuilder().subject_name(
        x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
    return builder.sign(key, hashes.SHA256()).public_bytes(serialization.Encoding.PEM)


def test_the_name_is_fogiacs_whatever_the_request_asks(fleet: Fleet) -> None:
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    cert = x509.load_pem_x509_certificate(sign_csr(fleet.bundle.ca, _csr(key, "vpn.evil"), "a.relay.rc-dev.fogiac"))
    names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert names.get_values_for_type(x509.DNSName) == ["a.relay.rc-dev.fogiac"]


@pytest.mark.parametrize("csr, message", [
    (b"garbage", "the certificate request for h is not a PEM CSR"),
    (None, "the certificate request for h does not carry an RSA key of 2048 bits or more"),
])
def test_hostile_requests_are_refused_in_one_line(fleet: Fleet, csr: bytes | None, message: str) -> None:
    request = csr or _csr(rsa.generate_private_key(public_exponent=65537, key_size=1024), "h")
    with pytest.raises(CertError) as err:
        sign_csr(fleet.bundle.ca, request, "h")
    assert str(err.value) == message


def test_a_host_that_answers_garbage_fails_in_one_line(fleet: Fleet) -> None:
    with pytest.raises(ProvisionError, match=r"^a: the relay key's show on the host printed no JSON object$"):
        hostcert.ensure(fleet.hosts["a"], python="/bin/echo", folder=fleet.folder("a"), ca=fleet.bundle.ca,
                         name=relay_name(STACK, "a"))
    assert not Path(fleet.folder("a"), "server.key").exists()


def test_a_folder_from_before_keeps_its_ca_and_drops_the_shared_server_key(tmp_path: Path) -> None:
    folder = tmp_path / "certs"
    bundle = load_or_create_bundle(STACK, folder)
    shared = issue(bundle.ca, "server.rc-dev.fogiac", server=True, dns_names=("server.rc-dev.fogiac",))
    for suffix, data in (("pem", shared.cert_pem), ("key", shared.key_pem)):
        (folder / f"server.{suffix}").write_bytes(data)
    (folder / "vpn.pem").unlink()
    again = load_or_create_bundle(STACK, folder)
    assert again.ca == bundle.ca and again.client == bundle.client
    assert again.vpn.key_pem not in (bundle.vpn.key_pem, shared.key_pem)
    assert not (folder / "server.key").exists() and not (folder / "server.pem").exists()
