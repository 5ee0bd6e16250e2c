"""Which ROS master a workload's robot-side client talks to, and whether it answers, asked before rospy is.

Why: the clients used ``ROS_MASTER_URI`` alone, ignoring the manifest's ``edge.ros_master`` (where fogiac
started the edge's relay), and rospy retries "Unable to register with master node" for ever when no master
answers there. The master is ``--master``, else the manifest's ``edge.ros_master`` (``./fogiac.yaml``, or
``--manifest``), else ``ROS_MASTER_URI``; one that does not answer within the timeout is one error line.
"""

from __future__ import annotations

import os
import socket
import time
import xmlrpc.client
from pathlib import Path
from typing import Any

import yaml

from fogiac.errors import WorkloadError

MANIFEST = Path("fogiac.yaml")


def choose(master: str | None, manifest: Path | None) -> tuple[str, str]:
    """(URI, where it came from)."""
    if master:
        return master, "--master"
    path = manifest or MANIFEST
    if manifest is not None or path.is_file():
        try:
            doc = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as err:
            raise WorkloadError(f"{path}: cannot read edge.ros_master ({err})") from None
        edge = doc.get("edge") if isinstance(doc, dict) else None
        found = edge.get("ros_master") if isinstance(edge, dict) else None
        if isinstance(found, str) and found:
            return found, f"{path}'s edge.ros_master"
    env = os.environ.get("ROS_MASTER_URI")
    if env:
        return env, "ROS_MASTER_URI"
    return "http://localhost:11311", "ROS's default (no --master, manifest or ROS_MASTER_URI)"


def _answers(uri: str, timeout: float) -> bool:
    previous = socket.getdefaulttimeout()
    socket.setdefaulttimeout(max(0.5, timeout))
    try:
        reply: Any = xmlrpc.client.ServerProxy(uri).getPid("/fogiac_client_probe")
        return isinstance(reply, list | tuple) and len(reply) == 3 and reply[0] == 1  # (code, status, pid)
    except (OSError, xmlrpc.client.Error, ValueError):
        return False
    finally:
        socket.setdefaulttimeout(previous)


def use(master: str | None, manifest: Path | None, *, timeout: float) -> str:
    """Pick the master, wait up to ``timeout`` s for it to answer, and point rospy at it (its environment)."""
    uri, source = choose(master, manifest)
    deadline = time.monotonic() + timeout
    while not _answers(uri, min(2.0, max(0.5, deadline - time.monotonic()))):
        if time.monotonic() >= deadline:
            raise WorkloadError(f"no ROS master answers at {uri} (from {source}) within {timeout:g} s: start the "
                                "robot's roscore (or fogiac up --start-edge-master), or pass --master URI")
        time.sleep(0.2)
    os.environ["ROS_MASTER_URI"] = uri
    return uri
