"""ROS test helpers shared by every suite that starts real roscores and rospy nodes."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys


def ros_missing(*modules: str) -> str | None:
    """Why ROS tests cannot run here, or None: roscore and the given rospy modules must import."""
    if shutil.which("roscore") is None:
        return "roscore not installed (apt-get install ros-core)"
    wanted = ("rospy", "std_msgs.msg", *modules)
    if subprocess.run([sys.executable, "-c", f"import {', '.join(wanted)}"], capture_output=True).returncode:
        return f"{', '.join(wanted)} not importable (apt-get install python3-rospy python3-std-msgs ...)"
    return None


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


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
