"""``HOST:PORT`` as one value type, parsed and checked once (``[v6]:PORT`` too)."""

from __future__ import annotations

from dataclasses import dataclass

from fogiac.errors import FogiacError


@dataclass(frozen=True)
class Endpoint:
    host: str
    port: int

    @classmethod
    def parse(cls, text: str, *, default_port: int | None = None) -> Endpoint:
        """``"10.0.0.5:11411"``, ``"[fd00::1]:7447"``, or a bare host when ``default_port`` is given."""
        host, sep, port = text.strip().rpartition(":")
        if not sep or (host.count(":") and not host.startswith("[")):  # no port, or a bare IPv6 address
            if default_port is None:
                raise FogiacError(f"{text!r} is not HOST:PORT")
            host, port = text.strip(), str(default_port)
        host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
        if not host or not port.isdigit() or not 0 <= int(port) < 65536:  # 0: any free port, to listen on
            raise FogiacError(f"{text!r} is not HOST:PORT (a port from 0 to 65535)")
        return cls(host, int(port))

    def __str__(self) -> str:
        return f"[{self.host}]:{self.port}" if ":" in self.host else f"{self.host}:{self.port}"
