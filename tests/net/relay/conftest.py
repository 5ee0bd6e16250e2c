"""Real ROS for the relay tests: two roscores on free loopback ports (edge and cloud), rospy
nodes in subprocesses, relay ends in-process or as ``fogiac relay`` processes. Every process
runs in its own session and its whole group is killed at teardown, pass or fail."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.net.relay.tls import write_relay_lab
from tests.net.relay.relay_support import Master, Procs, ros_missing


@pytest.fixture(scope="session")
def ros_ready() -> None:
    reason = ros_missing()
    if reason:
        pytest.skip(reason)


@pytest.fixture(scope="session")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("certs")
    write_relay_lab("relaytest", directory)
    return directory


@pytest.fixture(scope="module")
def masters(ros_ready: None, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Master, Master]]:
    """Edge and cloud masters, shared by a module's tests (each test uses its own topics)."""
    procs = Procs(tmp_path_factory.mktemp("roshome"))
    try:
        yield procs.roscore(), procs.roscore()
    finally:
        procs.close()


@pytest.fixture
def procs(tmp_path: Path) -> Iterator[Procs]:
    p = Procs(tmp_path)
    try:
        yield p
    finally:
        p.close()
