"""What the ROS 1 fleet tests share: the lab stack's robots, their access file, a cloud end and a robot's edge end."""

from __future__ import annotations

import contextlib
import shutil
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from fogiac.certs import edge_identity, edge_role, load_or_create_edges
from fogiac.net.relay import CloudConfig, CloudRelay, EdgeConfig, EdgeRelay, TopicPolicy
from fogiac.net.relay.fleet import ACCESS_FILE, FleetAccess, Robot, SharedPair, write_access
from tests.net.relay.relay_support import Master

STACK = "relaytest"  # the lab certificates' stack (the relay conftest's ``certs``)
ROBOTS = ("arm1", "arm2", "arm3")
SHARED = ("/plan/request", "/plan/reply")  # a shared node's request/reply topics: every robot may use them


def access(revoked: tuple[str, ...] = (), shared: tuple[SharedPair, ...] = (),
           topics: tuple[str, ...] = SHARED) -> FleetAccess:
    robots = {edge_identity(STACK, r): Robot(r, edge_identity(STACK, r), frozenset(topics)) for r in ROBOTS}
    return FleetAccess(robots, frozenset(revoked), shared)


def fleet_folder(certs: Path, folder: Path) -> Path:
    """The lab folder with each robot's own pair (issued the way ``up`` issues every edge's) and the access file."""
    shutil.copytree(certs, folder)
    load_or_create_edges(STACK, folder, list(ROBOTS))
    for name in ("server.pem", "server.key"):  # the lab's cloud end pair, which a stack's folder never keeps
        shutil.copy(certs / name, folder / name)
    write_access(folder / ACCESS_FILE, access())
    return folder


@contextlib.contextmanager
def cloud_end(master: Master, certs: Path, policy: TopicPolicy = TopicPolicy(auto=True),
              **options: float) -> Iterator[CloudRelay]:
    cloud = CloudRelay(CloudConfig(master_uri=master.uri, certs=certs, ros_host="127.0.0.1",
                                   listen=("127.0.0.1", 0), poll_interval=0.1, policy=policy, **options))
    cloud.start()
    try:
        yield cloud
    finally:
        cloud.stop()


def edge_end(robot: str, master: Master, certs: Path, cloud: CloudRelay, n: int, **options: object) -> EdgeRelay:
    """``robot``'s edge end on its own master, started (the caller stops it); it dials at a test's pace, refused
    or not (``options``: more of its config)."""
    settings: dict[str, object] = {"backoff_initial": 0.1, "backoff_max": 0.5, "refused_backoff_max": 2.0, **options}
    end = EdgeRelay(EdgeConfig(master_uri=master.uri, certs=certs, client=edge_role(STACK, robot),
                               ros_host="127.0.0.1", connect=cloud.address, poll_interval=0.1,
                               caller_id=f"/fogiac_relay_edge_{n}", **settings))  # type: ignore[arg-type]
    end.start()
    return end


def pids(folder: Path) -> dict[str, int]:
    """service -> its supervisor's pid, for every supervised process under ``folder``."""
    return {str(p.relative_to(folder)): int(p.read_text().split()[0]) for p in folder.rglob("*.pid")}


def wait(what: str, check: Callable[[], object], timeout: float) -> float:
    """Poll ``check`` until it holds (``what``: what failed, if not within ``timeout`` s); the seconds it took."""
    started = time.monotonic()
    while not check():
        assert time.monotonic() - started < timeout, what
        time.sleep(0.1)
    return time.monotonic() - started
