"""ROS test helpers shared by every suite that starts real roscores and rospy nodes."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import xmlrpc.client
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path

from fogiac.procs import free_port

__all__ = ["free_port", "ros_missing", "roscore", "stop_group", "stop_groups"]


@cache
def ros_missing(*modules: str) -> str | None:
    """Why ROS tests cannot run here, or None: roscore and the given rospy modules must import.

    Cached: each probe starts a Python that imports rospy (about a second), and many test modules ask
    at collection, in every pytest-xdist worker; the answer does not change within a run.
    """
    if shutil.which("roscore") is None:
        return "roscore not installed (apt-get install ros-core)"
    wanted = ("rospy", "std_msgs.msg", *modules)
    if subprocess.run([sys.executable, "-c", f"import {', '.join(wanted)}"], capture_output=True).returncode:
        return f"{', '.join(wanted)} not importable (apt-get install python3-rospy python3-std-msgs ...)"
    return None


def stop_group(proc: subprocess.Popen, sig: int = signal.SIGINT, *, timeout: float = 10.0) -> None:
    """Signal the process group, then SIGKILL whatever is left of it, and reap the leader."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, sig)
            proc.wait(timeout=timeout)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=timeout)


def stop_groups(procs: list[subprocess.Popen], sig: int = signal.SIGINT, *, timeout: float = 10.0) -> None:
    """``stop_group`` for many at once: signal every group, wait for all under one deadline, SIGKILL the rest.

    A test that started a dozen nodes and relay ends waits as long as its slowest one takes to stop,
    not the sum of them (rospy nodes take seconds to unregister, and teardowns took 10-13 s).
    """
    for proc in procs:
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                pass
    deadline = time.monotonic() + timeout
    for proc in procs:
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            pass
    for proc in procs:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    for proc in procs:
        proc.wait(timeout=timeout)


@contextmanager
def roscore(home: Path, *, pythonpath: str = "") -> Iterator[dict[str, str]]:
    """A roscore on a free loopback port; yields the environment for nodes and clients of it.

    Logs go under ``home``; the roscore's whole process group is stopped on the way out.
    """
    port = free_port()
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1",
           "ROS_HOME": str(home / "ros"), "ROS_LOG_DIR": str(home / "ros" / "log"),
           "PYTHONPATH": os.pathsep.join(p for p in (pythonpath, os.environ.get("PYTHONPATH", "")) if p)}
    core = subprocess.Popen(["roscore", "-p", str(port)], env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        master = xmlrpc.client.ServerProxy(env["ROS_MASTER_URI"])
        deadline = time.monotonic() + 30
        while True:
            try:
                master.getSystemState("/test")
                break
            except OSError:
                if time.monotonic() > deadline or core.poll() is not None:
                    raise RuntimeError("roscore did not come up within 30 s") from None
                time.sleep(0.1)
        yield env
    finally:
        stop_group(core)
