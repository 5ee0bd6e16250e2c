"""Placeholders copied from the documentation into a real manifest: an image at an example registry
(``registry.example.com/...``, ``ghcr.io/example/...``) or an address in the documentation ranges
(RFC 5737: 192.0.2.0/24, 198.51.100.0/24, 203.0.113.0/24; RFC 3849: 2001:db8::/32) that a security
group would open. ``validate`` and ``plan`` warn; ``up`` refuses them unless forced.

Pure: the compiled plan in, one line per placeholder out.
"""

from __future__ import annotations

import ipaddress

from fogiac.plan.model import Plan

DOCUMENTATION = tuple(ipaddress.ip_network(n) for n in
                      ("192.0.2.0/24", "198.51.100.0/24", "203.0.113.0/24", "2001:db8::/32"))
_EXAMPLE_DOMAINS = ("example.com", "example.org", "example.net")
_EXAMPLE_TLDS = (".example", ".test", ".invalid", ".localhost")
_REGISTRIES = ("ghcr.io", "docker.io", "index.docker.io", "quay.io", "registry.gitlab.com")


def placeholder_image(image: str) -> bool:
    """An image at an example registry, or under an ``example`` account of a public one."""
    first, _, rest = image.partition("/")
    if not rest or ("." not in first and ":" not in first and first != "localhost"):
        return False  # a Docker Hub name ("ros:noetic", "org/app"): the account is someone's own
    host = first.split(":", 1)[0].lower()
    if host in _EXAMPLE_DOMAINS or host.endswith(tuple("." + d for d in _EXAMPLE_DOMAINS) + _EXAMPLE_TLDS):
        return True
    return host in _REGISTRIES and rest.split("/", 1)[0].lower() == "example"


def documentation_range(cidr: str) -> bool:
    try:
        net = ipaddress.ip_network(cidr, strict=False)
    except ValueError:
        return False  # the operator placeholder of an offline plan
    return any(net.version == doc.version and net.subnet_of(doc) for doc in DOCUMENTATION)  # type: ignore[arg-type]


def found(plan: Plan) -> list[str]:
    """One line per placeholder in ``plan``: the node's image, or a source a security group would let in."""
    lines = [f"node {node.name}: image {node.image} is a documentation placeholder (an example registry); "
             "name your own image" for node in plan.nodes if node.image and placeholder_image(node.image)]
    opened = {rule.cidr for group in plan.security_groups for rule in group.ingress}
    lines += [f"network.ssh_from: {cidr} is a documentation address range (RFC 5737/3849), nobody's network; "
              "name your own" for cidr in plan.ssh_from if cidr in opened and documentation_range(cidr)]
    return lines
