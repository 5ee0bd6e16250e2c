"""Processes and waiting, shared by the state lock, the local target, provisioning, the VPN and the tests.

Each helper exists once: :func:`poll` (wait with a deadline and backoff), :func:`stop_tree`
(TERM then KILL a process and everything it started), :func:`pid_alive` and :func:`free_port`.
``fogiac/provision/supervise.py`` keeps its own copies: it is copied to hosts and must stand alone.
"""

from __future__ import annotations

import os
import random
import signal
import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")


def poll(check: Callable[[], T | None], *, timeout: float, interval: float = 0.1, backoff: float = 1.5,
         max_interval: float = 2.0, sleep: Callable[[float], None] = time.sleep) -> T | None:
    """Call ``check`` until it returns something other than None; that value, or None after ``timeout`` s.

    ``check`` runs at once, then after pauses of ``interval`` growing by ``backoff`` up to
    ``max_interval`` (``backoff=1`` polls at a fixed rate). A pause never runs past the deadline:
    the last one is cut short so that ``check`` has a final say at the deadline itself. An
    exception from ``check`` ends the wait at once (a definite failure is not worth waiting out).
    ``sleep`` is injectable so tests need not wait.
    """
    deadline = time.monotonic() + timeout
    pause = interval
    while True:
        result = check()
        if result is not None:
            return result
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        sleep(min(pause, left))
        pause = min(pause * backoff, max_interval)


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


def start_time(pid: int) -> str | None:
    """When ``pid`` started (clock ticks since boot, field 22 of /proc/PID/stat): with the pid it names
    one process for good (a pid reused after a crash or a reboot has another), as the supervisor's pid
    files use it."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def same_process(pid: int, started: str | None) -> bool:
    """``pid`` is alive and is the process that was recorded with ``started`` (None: recorded without a start
    time, by an older fogiac: liveness alone)."""
    return pid_alive(pid) and (started is None or start_time(pid) in (started, None))


def _ppid(pid: int) -> int | None:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return None


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds a live process has used, all its threads; 0.0 when it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def descendants(root: int) -> list[int]:
    """Every live process below ``root`` (children, their children, ...), read from /proc."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            parent = _ppid(int(entry.name))
            if parent is not None:
                children.setdefault(parent, []).append(int(entry.name))
    out, todo = [], [root]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def _signal_root(pid: int, sig: signal.Signals) -> None:
    """Signal ``pid``'s process group when it leads one, else the process alone."""
    try:
        os.killpg(pid, sig)
    except ProcessLookupError:
        os.kill(pid, sig)


def _wait_gone(pids: list[int], *, timeout: float) -> None:
    poll(lambda: None if any(pid_alive(p) for p in pids) else True, timeout=timeout, interval=0.05, backoff=1.0)


def stop_tree(pid: int, *, grace: float) -> None:
    """TERM ``pid``, its process group and every descendant; KILL whatever is left after ``grace`` s.

    Why descendants too: roslaunch and daemons start children in sessions of their own, which a
    group signal misses. Returns once all are gone, or ``grace`` s after the KILL. A
    PermissionError for ``pid`` itself propagates (the caller lacks the rights to stop it);
    descendants that cannot be signalled are skipped.
    """
    tree = [pid, *descendants(pid)]
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for target in tree:
            try:
                if target == pid:
                    _signal_root(pid, sig)
                else:
                    os.kill(target, sig)
            except ProcessLookupError:
                pass
            except PermissionError:
                if target == pid:
                    raise
        _wait_gone(tree, timeout=grace)
        tree = [p for p in tree if pid_alive(p)]
        if not tree:
            return


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
