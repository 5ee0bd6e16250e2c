"""Each robot of a fleet its own Client VPN certificate and profile, and the revocation list that refuses a
revoked or removed robot's.

Why: the Client VPN endpoint trusts every certificate the stack's CA signed (its ``client`` certificate in
ACM is there for its chain). Were every robot to dial it with the stack's one client certificate, ``fogiac
robot revoke NAME`` would cut the robot at the relay's cloud ends but leave it inside the VPC. So a fleet's
robot gets a certificate of its own (``<robot>.vpn.<stack>.fogiac``, RSA 2048 as AWS requires, key 0600 in
the stack's certs folder, never printed) and a profile of its own; the endpoint is told which ones it must
refuse by a certificate revocation list (CRL) signed by the stack's CA, which the endpoint imports
(``ImportClientVpnClientCertificateRevocationList``; the Pulumi resource has no input for it, so the target
calls the API after the stack and on ``robot revoke``/``restore``).

The CRL lists:

- the robots the record keeps revoked (``fogiac robot revoke``), until ``restore`` (which keeps their
  certificate: a restored robot dials with the same profile);
- every certificate of a robot dropped from ``robots:`` (retired: its files go, its serial stays listed),
  so a robot of that name added later gets a new certificate and the old profile stays refused;
- in a fleet, the stack's shared client certificate, which no robot of a fleet may use.

A one-robot stack (``edge:``) keeps its one ``client.ovpn`` on the stack's client certificate and imports no
CRL: nothing changes for it. The CRL is public (no key in it), written 0644; it is valid until the CA
expires, because an endpoint whose CRL has expired refuses every client.
"""

from __future__ import annotations

import datetime as _dt
import json
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa

from fogiac import certs
from fogiac.plan.model import Plan
from fogiac.state import StackState
from fogiac.store import write_atomic
from fogiac.targets.aws.vpn import default_profile_path, write_client_profile

FOLDER = "vpn-robots"  # under the stack's certs folder: ROBOT.pem (0644) and ROBOT.key (0600) of each robot
RETIRED = "retired.json"  # in FOLDER: serial (hex) -> robot, of the certificates of robots dropped from robots:
CRL = "revoked.crl.pem"  # in FOLDER: the list the endpoint imports (public, 0644)


def identity(stack: str, robot: str) -> str:
    """The name in ``robot``'s VPN certificate (what the endpoint's connection log shows); not an edge's
    relay identity (``<robot>.edge.<stack>.fogiac``), so the VPN certificate opens no relay link."""
    certs.edge_identity(stack, robot)  # the same check: one DNS label
    return f"{robot}.vpn.{stack}.fogiac"


def _folder(stack: str) -> Path:
    return StackState(stack).certs / FOLDER


def _load(folder: Path, robot: str) -> certs.KeyPair | None:
    cert, key = folder / f"{robot}.pem", folder / f"{robot}.key"
    return certs.KeyPair(cert.read_bytes(), key.read_bytes()) if cert.exists() and key.exists() else None


def serial(pair: certs.KeyPair) -> int:
    return x509.load_pem_x509_certificate(pair.cert_pem).serial_number


def robot_pairs(stack: str, robots: Iterable[str]) -> dict[str, certs.KeyPair]:
    """Each robot's VPN certificate and key, issued by the stack's CA on first use and kept."""
    bundle = certs.load_or_create_bundle(stack, StackState(stack).certs)
    folder = _folder(stack)
    pairs: dict[str, certs.KeyPair] = {}
    for robot in robots:
        pair = _load(folder, robot)
        if pair is None:
            pair = certs.issue(bundle.ca, identity(stack, robot), server=False)
            certs.save_pair(folder, robot, pair)
        pairs[robot] = pair
    return pairs


def _retired(folder: Path) -> dict[str, str]:
    path = folder / RETIRED
    found = json.loads(path.read_text()) if path.exists() else {}
    return {str(k): str(v) for k, v in found.items()} if isinstance(found, dict) else {}


def retire_dropped(stack: str, robots: Collection[str]) -> tuple[str, ...]:
    """Retire the certificate of every robot no longer in ``robots``: its serial stays in the CRL for good,
    its files go (so the name, added again, gets a new certificate). Returns the robots retired."""
    folder = _folder(stack)
    if not folder.is_dir():
        return ()
    retired = _retired(folder)
    gone = sorted(p.stem for p in folder.glob("*.pem") if p.name != CRL and p.stem not in robots)
    for robot in gone:
        pair = _load(folder, robot)
        if pair is not None:
            retired[format(serial(pair), "x")] = robot
    if gone:
        write_atomic(folder / RETIRED, json.dumps(retired, indent=2, sort_keys=True).encode(), mode=0o644)
    for robot in gone:
        (folder / f"{robot}.key").unlink(missing_ok=True)
        (folder / f"{robot}.pem").unlink(missing_ok=True)
    return tuple(gone)


def build_crl(ca: certs.KeyPair, serials: Iterable[int], *, now: _dt.datetime | None = None) -> bytes:
    """A CRL (PEM) signed by ``ca`` that lists ``serials``; valid until the CA itself expires."""
    now = now or _dt.datetime.now(_dt.timezone.utc)
    ca_cert = x509.load_pem_x509_certificate(ca.cert_pem)
    ca_key = serialization.load_pem_private_key(ca.key_pem, password=None)
    assert isinstance(ca_key, rsa.RSAPrivateKey)  # certs makes RSA keys only
    builder = (
        x509.CertificateRevocationListBuilder()
        .issuer_name(ca_cert.subject)
        .last_update(now - _dt.timedelta(minutes=5))
        .next_update(max(ca_cert.not_valid_after_utc, now + _dt.timedelta(days=1)))
        .add_extension(x509.CRLNumber(int(now.timestamp() * 1000)), critical=False)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False)
    )
    for number in sorted(set(serials)):
        builder = builder.add_revoked_certificate(
            x509.RevokedCertificateBuilder().serial_number(number).revocation_date(now).build())
    return builder.sign(ca_key, hashes.SHA256()).public_bytes(serialization.Encoding.PEM)


@dataclass(frozen=True)
class Revocations:
    """What the CRL written at ``path`` refuses: the robots by name (revoked, retired) and the shared
    certificate of a fleet's stack."""

    path: Path
    pem: bytes
    robots: tuple[str, ...]
    serials: tuple[int, ...]


def write_crl(plan: Plan, revoked: Collection[str]) -> Revocations:
    """The stack's CRL from the record's ``revoked`` robots, the retired certificates and (a fleet) the shared
    client certificate, written 0644 beside the robots' certificates."""
    bundle = certs.load_or_create_bundle(plan.stack, StackState(plan.stack).certs)
    folder = _folder(plan.stack)
    listed: dict[int, str] = {int(k, 16): v for k, v in _retired(folder).items()}
    current = [e.name for e in plan.edges if not e.shorthand]
    for robot, pair in robot_pairs(plan.stack, [r for r in current if r in revoked]).items():
        listed[serial(pair)] = robot
    if plan.fleet:
        listed[serial(bundle.client)] = "(the stack's shared client certificate)"
    pem = build_crl(bundle.ca, listed)
    path = folder / CRL
    write_atomic(path, pem, mode=0o644)
    robots = tuple(sorted({name for name in listed.values() if not name.startswith("(")}))
    return Revocations(path=path, pem=pem, robots=robots, serials=tuple(sorted(listed)))



IMPORTED = "imported.json"  # in FOLDER: the endpoint and serials of the CRL it was last handed


def needs_import(stack: str, endpoint_id: str, revocations: Revocations) -> bool:
    """Whether the endpoint must be handed this CRL: it lists other serials than the one it was last handed.
    Importing resets every connection of the endpoint (each robot's OpenVPN redials), so an ``up`` that
    revokes nothing new leaves the robots' tunnels alone."""
    path = _folder(stack) / IMPORTED
    last = json.loads(path.read_text()) if path.exists() else {}
    return not isinstance(last, dict) or last != _imported(endpoint_id, revocations)


def imported(stack: str, endpoint_id: str, revocations: Revocations) -> None:
    """Remember that the endpoint now holds this CRL (after the API call succeeded)."""
    write_atomic(_folder(stack) / IMPORTED, json.dumps(_imported(endpoint_id, revocations), indent=2).encode(),
                 mode=0o644)


def _imported(endpoint_id: str, revocations: Revocations) -> dict[str, object]:
    return {"endpoint": endpoint_id, "serials": [format(n, "x") for n in revocations.serials]}


def write_profiles(plan: Plan, *, endpoint_dns: str, port: int = 443, proto: str = "udp") -> dict[str, Path]:
    """Each robot's own profile (0600, its folder 0700) on its own certificate; the stack's shared
    ``client.ovpn`` of a one-robot past goes, since the endpoint refuses its certificate in a fleet."""
    bundle = certs.load_or_create_bundle(plan.stack, StackState(plan.stack).certs)
    robots = [e.name for e in plan.edges]
    written: dict[str, Path] = {}
    for robot, pair in robot_pairs(plan.stack, robots).items():
        written[robot] = write_client_profile(
            endpoint_dns=endpoint_dns, stack=plan.stack, ca_pem=bundle.ca.cert_pem, cert_pem=pair.cert_pem,
            key_pem=pair.key_pem, path=default_profile_path(plan.stack, robot=robot), port=port, proto=proto)
    default_profile_path(plan.stack, create=False).unlink(missing_ok=True)
    return written
