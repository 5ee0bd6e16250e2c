"""A host's server certificate: the key is made on the host, the certificate signed on this machine.

Here, in ``net/`` beside both middlewares' folders rather than in either, because the relay's cloud
end and the Zenoh router both come through it (provisioning only calls the middleware's
``host_credentials``, which calls this).

Why: one server key sent to every host meant any host (a lab machine included) could pose as
any other, and as the Client VPN endpoint. Now each host's key is born there
(:mod:`.hostkey`, run through :class:`Host`), only its CSR comes back, and the operator's CA
(whose key never leaves this machine) signs a certificate for the host's own name
(:func:`fogiac.net.relay.tls.relay_name` for the relay's cloud end, which the edge relay checks; the
Zenoh router's name plus the address the edge dials, which the edge router checks). A second
run keeps the key and certificate while the certificate is the CA's, for those names and that
key, and has more than a month left. The relay and the Zenoh router both come through here,
each with its own folder on the host.
"""

from __future__ import annotations

import json
from pathlib import Path

from fogiac.certs import KeyPair, serves, sign_csr
from fogiac.errors import CertError, ProvisionError
from fogiac.provision.host import Host, command_failed, q

_SCRIPT = Path(__file__).with_name("hostkey.py")


def _hostkey(host: Host, python: str, what: str, *args: str) -> str:
    result = host.run(f"{q(python)} -c {q(_SCRIPT.read_text())} {' '.join(q(a) for a in args)}", check=False)
    if not result.ok:
        raise command_failed(host.name, result, what=f"the {what} key's {args[0]} on the host")
    return result.stdout


def ensure(host: Host, *, python: str, folder: str, ca: KeyPair, name: str, addresses: tuple[str, ...] = (),
           what: str = "relay") -> bool:
    """Make sure ``folder`` on ``host`` holds a key and the CA's certificate for ``name`` and ``addresses``
    (server.key, server.pem); True if it issued one. ``what`` names the key in errors."""
    try:
        shown = json.loads(_hostkey(host, python, what, "show", folder))
        cert, public = shown.get("cert"), shown.get("public")
    except (ValueError, AttributeError):
        raise ProvisionError(f"{host.name}: the {what} key's show on the host printed no JSON object") from None
    if isinstance(cert, str) and isinstance(public, str) and serves(ca, cert.encode(), name, public.encode(),
                                                                    addresses=addresses):
        return False
    csr = _hostkey(host, python, what, "new", folder, name)
    try:
        signed = sign_csr(ca, csr.encode(), name, addresses=addresses)
    except CertError as err:
        raise ProvisionError(f"{host.name}: {err}") from None
    host.put(signed, f"{folder}/server.pem", mode=0o644)
    return True
