"""The edge's client.ovpn: AWS Client VPN's format, inline PEM, 0600, never inside a repo."""

from __future__ import annotations

import os
import re
import shutil
import stat
import subprocess
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import serialization

from fogiac import certs
from fogiac.targets.aws.errors import VpnError
from fogiac.targets.aws.vpn import parse_log, render_client_profile, write_client_profile

AWS_DNS = "*.cvpn-endpoint-0123456789abcdef0.prod.clientvpn.eu-west-1.amazonaws.com"


@pytest.fixture(scope="module")
def bundle() -> certs.Bundle:
    return certs.new_bundle("demo-dev")


@pytest.fixture(autouse=True)
def _state_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    state = tmp_path / "state"
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(state))
    return state


def _block(text: str, tag: str) -> bytes:
    match = re.search(rf"^<{tag}>\n(.*?)\n</{tag}>$", text, re.S | re.M)
    assert match, f"no <{tag}> block"
    return match.group(1).encode()


def _outside_blocks(text: str) -> list[str]:
    return re.sub(r"<(ca|cert|key)>\n.*?\n</\1>\n", "", text, flags=re.S).splitlines()


def test_profile_lines_follow_aws_client_vpn(bundle: certs.Bundle, _state_dir: Path) -> None:
    path = write_client_profile(endpoint_dns=AWS_DNS, bundle=bundle, stack="demo-dev")
    assert path == _state_dir / "demo-dev" / "client.ovpn"
    assert _outside_blocks(path.read_text()) == [
        "# fogiac: AWS Client VPN profile for stack demo-dev. Contains a private key: keep it 0600.",
        "client",
        "dev tun",
        "proto udp",
        "remote cvpn-endpoint-0123456789abcdef0.prod.clientvpn.eu-west-1.amazonaws.com 443",
        "remote-random-hostname",
        "resolv-retry infinite",
        "nobind",
        "persist-key",
        "persist-tun",
        "remote-cert-tls server",
        "verify-x509-name server.demo-dev.fogiac name",
        "cipher AES-256-GCM",
        "tls-version-min 1.2",
        "reneg-sec 0",
        "verb 3",
    ]


def test_inline_blocks_are_the_bundles_pem(bundle: certs.Bundle) -> None:
    text = render_client_profile(
        endpoint_dns=AWS_DNS, stack="demo-dev", ca_pem=bundle.ca.cert_pem,
        cert_pem=bundle.client.cert_pem, key_pem=bundle.client.key_pem,
    )
    ca = x509.load_pem_x509_certificate(_block(text, "ca"))
    cert = x509.load_pem_x509_certificate(_block(text, "cert"))
    key = serialization.load_pem_private_key(_block(text, "key"), password=None)
    assert ca == x509.load_pem_x509_certificate(bundle.ca.cert_pem)
    assert cert.issuer == ca.subject
    assert cert.public_key().public_numbers() == key.public_key().public_numbers()  # type: ignore[union-attr]
    assert _block(text, "key") == bundle.client.key_pem.strip()


def test_address_endpoint_tcp_and_port(bundle: certs.Bundle, tmp_path: Path) -> None:
    path = write_client_profile(endpoint_dns="10.231.8.1", bundle=bundle, stack="demo-dev",
                                path=tmp_path / "edge" / "lab.ovpn", port=1194, proto="tcp")
    lines = _outside_blocks(path.read_text())
    assert "remote 10.231.8.1 1194" in lines and "proto tcp" in lines
    assert "remote-random-hostname" not in lines


def test_written_0600_whatever_the_umask(bundle: certs.Bundle, tmp_path: Path) -> None:
    old = os.umask(0)
    try:
        path = write_client_profile(endpoint_dns=AWS_DNS, bundle=bundle, stack="demo-dev",
                                    path=tmp_path / "client.ovpn")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temp file left


def test_default_state_folder_is_private(bundle: certs.Bundle, _state_dir: Path) -> None:
    path = write_client_profile(endpoint_dns=AWS_DNS, bundle=bundle, stack="demo-dev")
    assert stat.S_IMODE(path.parent.stat().st_mode) == 0o700


def test_refuses_inside_a_git_work_tree(bundle: certs.Bundle, tmp_path: Path) -> None:
    repo = tmp_path / "robot"
    repo.mkdir()
    if shutil.which("git"):
        subprocess.run(["git", "init", "-q", str(repo)], check=True)
    else:
        (repo / ".git").mkdir()
    target = repo / "deploy" / "client.ovpn"
    with pytest.raises(VpnError, match=rf"^refusing to write the VPN profile {re.escape(str(target))} "
                       rf"inside the git work tree {re.escape(str(repo))}: it holds a private key; "
                       r"choose a path outside the repository$"):
        write_client_profile(endpoint_dns=AWS_DNS, bundle=bundle, stack="demo-dev", path=target)
    assert not (repo / "deploy").exists()


def test_pem_pieces_instead_of_a_bundle(bundle: certs.Bundle, tmp_path: Path) -> None:
    path = write_client_profile(
        endpoint_dns=AWS_DNS, stack="demo-dev", path=tmp_path / "c.ovpn", ca_pem=bundle.ca.cert_pem,
        cert_pem=bundle.client.cert_pem, key_pem=bundle.client.key_pem,
    )
    assert _block(path.read_text(), "cert") == bundle.client.cert_pem.strip()
    with pytest.raises(VpnError, match=r"^a client profile needs the CA certificate and the client "
                       r"certificate and key$"):
        write_client_profile(endpoint_dns=AWS_DNS, stack="demo-dev", path=tmp_path / "d.ovpn",
                             ca_pem=bundle.ca.cert_pem)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"proto": "icmp"}, r"^VPN protocol 'icmp' is not one of: udp, tcp$"),
        ({"port": 0}, r"^VPN port 0 is not between 1 and 65535$"),
        ({"endpoint_dns": "bad host!"}, r"^endpoint DNS name 'bad host!' is not a host name or address$"),
        ({"key_pem": b"not a key"}, r"^the client key is not PEM text$"),
    ],
)
def test_bad_input_is_refused_without_echoing_keys(
    bundle: certs.Bundle, kwargs: dict[str, object], message: str
) -> None:
    args: dict[str, object] = {
        "endpoint_dns": AWS_DNS, "stack": "demo-dev", "ca_pem": bundle.ca.cert_pem,
        "cert_pem": bundle.client.cert_pem, "key_pem": bundle.client.key_pem, **kwargs,
    }
    with pytest.raises(VpnError, match=message):
        render_client_profile(**args)  # type: ignore[arg-type]


def test_parse_log_finds_device_address_and_readiness() -> None:
    log = (
        "2026-11-21 08:00:00 TUN/TAP device tun3 opened\n"
        "2026-11-21 08:00:00 net_addr_v4_add: 10.200.0.2/22 dev tun3\n"
        "2026-11-21 08:00:01 Initialization Sequence Completed\n"
    )
    facts = parse_log(log)
    assert (facts.device, facts.address, facts.ready, facts.failure) == ("tun3", "10.200.0.2/22", True, None)
    failed = parse_log("2026-11-21 08:00:00 VERIFY ERROR: depth=0, error=unable to get issuer\n")
    assert failed.failure == "VERIFY ERROR: depth=0, error=unable to get issuer"
    assert not failed.ready
