"""Helpers for the relay tests: processes in their own sessions, masters, message checks."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import xmlrpc.client
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from tests.support.ros import free_port, ros_missing, stop_group, stop_groups

__all__ = ["free_port", "ros_missing", "kill_group", "wait_for"]

NODE = Path(__file__).with_name("rosnode.py")


def kill_group(proc: subprocess.Popen, sig: int = signal.SIGINT) -> None:
    stop_group(proc, sig, timeout=5)


def wait_for(predicate: Callable[[], object], timeout: float = 15.0, what: str = "condition") -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")


@dataclass
class Proc:
    """A child process whose stdout lines are collected as they come."""

    popen: subprocess.Popen
    lines: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            self.lines.append(line.rstrip("\n"))

    def data(self) -> list[bytes]:
        return [bytes.fromhex(line) for line in self.lines if line and line != "ready"]


@dataclass(frozen=True)
class Master:
    uri: str
    env: dict[str, str]
    proc: Proc | None = field(default=None, compare=False)

    def state(self) -> list:
        return xmlrpc.client.ServerProxy(self.uri).getSystemState("/test")[2]

    def publishers(self, topic: str) -> list[str]:
        return next((nodes for t, nodes in self.state()[0] if t == topic), [])

    def subscribers(self, topic: str) -> list[str]:
        return next((nodes for t, nodes in self.state()[1] if t == topic), [])


class Procs:
    """Starts processes in their own sessions and kills every group at teardown."""

    def __init__(self, home: Path) -> None:
        self.home = home
        self.started: list[subprocess.Popen] = []

    def spawn(self, argv: list[str], env: dict[str, str], *, capture: bool = True) -> Proc:
        popen = subprocess.Popen(
            argv, env=env, start_new_session=True, text=True,
            stdout=subprocess.PIPE if capture else subprocess.DEVNULL, stderr=subprocess.DEVNULL if capture else None,
        )
        self.started.append(popen)
        return Proc(popen)

    def roscore(self, port: int | None = None) -> Master:
        port = port or free_port()
        uri = f"http://127.0.0.1:{port}/"
        env = dict(os.environ, ROS_HOSTNAME="127.0.0.1", ROS_MASTER_URI=uri, ROS_HOME=str(self.home),
                   ROS_LOG_DIR=str(self.home / "log"), PYTHONUNBUFFERED="1")
        master = Master(uri, env, self.spawn(["roscore", "-p", str(port)], env))

        def up() -> bool:
            try:
                return "/rosout" in master.subscribers("/rosout")
            except OSError:
                return False

        wait_for(up, 30, f"roscore on port {port}")
        return master

    def node(self, master: Master, *args: str) -> Proc:
        proc = self.spawn([sys.executable, str(NODE), *args], master.env)
        wait_for(lambda: "ready" in proc.lines or proc.popen.poll() is not None, 30, f"rospy node {args}")
        assert proc.popen.poll() is None, f"rospy node {args} exited"
        return proc

    def kill(self, proc: Proc, sig: int = signal.SIGINT) -> None:
        kill_group(proc.popen, sig)

    def close(self) -> None:
        """Every group at once (SIGINT, 5 s for all, then SIGKILL), so teardown waits for the slowest only."""
        stop_groups(list(reversed(self.started)), timeout=5)


def string_msg(text: str) -> bytes:
    data = text.encode()
    return len(data).to_bytes(4, "little") + data


def indices(data: list[bytes]) -> list[int]:
    """The i of each "msg <i>xxx" String, checking the bytes are exactly what rospy sent."""
    out = []
    for raw in data:
        text = raw[4:].decode()
        assert raw == string_msg(text)
        out.append(int(text.split()[1].rstrip("x")))
    return out
