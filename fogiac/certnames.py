"""Names that certificates carry, kept apart from :mod:`fogiac.certs` so that naming one needs no cryptography.

``fogiac validate`` and ``fogiac plan`` name the VPN endpoint's certificate without making or reading one;
importing :mod:`fogiac.certs` (and ``cryptography`` with it) for a string would slow every validate
(``tests/test_startup.py`` holds that line).
"""

from __future__ import annotations


def server_name(stack: str) -> str:
    """The DNS-style name the stack's VPN endpoint certificate carries (ACM needs a domain)."""
    return f"server.{stack}.fogiac"
