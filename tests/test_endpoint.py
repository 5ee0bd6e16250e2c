"""``HOST:PORT`` parsed once: IPv4, names, bracketed IPv6, a default port, and one line for anything else."""

from __future__ import annotations

import pytest

from fogiac.endpoint import Endpoint
from fogiac.errors import FogiacError


@pytest.mark.parametrize(("text", "host", "port"), [
    ("10.0.0.5:11411", "10.0.0.5", 11411), ("relay.lab:7447", "relay.lab", 7447), ("[fd00::1]:7447", "fd00::1", 7447),
    (" 127.0.0.1:0 ", "127.0.0.1", 0), ("tcp/127.0.0.1:7447", "tcp/127.0.0.1", 7447),
])
def test_parses(text: str, host: str, port: int) -> None:
    found = Endpoint.parse(text)
    assert (found.host, found.port) == (host, port)


def test_a_default_port_for_a_bare_host_and_ipv6_round_trips() -> None:
    assert Endpoint.parse("10.0.0.5", default_port=11411) == Endpoint("10.0.0.5", 11411)
    assert Endpoint.parse("fd00::1", default_port=9) == Endpoint("fd00::1", 9)
    assert str(Endpoint("fd00::1", 9)) == "[fd00::1]:9" and str(Endpoint("h", 1)) == "h:1"


@pytest.mark.parametrize("text", ["h:x", "h:70000", ":5", "10.0.0.5", "fd00::1"])
def test_refuses_in_one_line(text: str) -> None:
    with pytest.raises(FogiacError, match=r"is not HOST:PORT"):
        Endpoint.parse(text)
