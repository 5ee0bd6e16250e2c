"""Process liveness and port choice, shared by the state lock, the local target, the planner and the tests.

(``fogiac/provision/supervise.py`` keeps its own copy: it is copied to hosts and must stand alone.)
"""

from __future__ import annotations

import os
import random
import socket
from pathlib import Path


def pid_alive(pid: int) -> bool:
    """The process exists and is neither a zombie nor dead (states Z and X)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return True


def _ephemeral_low() -> int:
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port nothing listens on, chosen below the kernel's ephemeral range.

    Why below: a port picked by binding to 0 comes from the ephemeral range, where every ROS
    node's own port-0 bind can take it before the service it was picked for starts (seen in
    CI: an edge relay dialled a rospy XML-RPC server). Ports below that range are never handed
    out by the kernel, so only another explicit choice can collide, and the start is random.
    """
    low = _ephemeral_low()
    start = 20000 if low > 21000 else 1024
    span = max(1, low - start)
    offset = random.randrange(span)
    for i in range(span):
        port = start + (offset + i) % span
        with socket.socket() as sock:
            try:
                sock.bind((host, port))
            except OSError:
                continue
            return port
    raise OSError(f"no free TCP port on {host} between {start} and {low}")
