"""Robot-side client: send plan requests to the node and time each answer.

``request_paths`` is what an end-to-end demo calls from its own rospy node; ``main`` (behind
``python -m workloads.motion_planning client``) makes an anonymous node and prints one line per
problem (``--json``: the whole timings, for programs).
"""

from __future__ import annotations

import json
import operator
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import rospy
from geometry_msgs.msg import PoseArray
from std_msgs.msg import Float64

from fogiac.errors import WorkloadError
from fogiac.procs import poll
from workloads.motion_planning.node import pose_from_msg, pose_to_msg, request_name
from workloads.motion_planning.problem import PROBLEMS_DIR, Pose

REQUEST_TOPIC = "/motion_planning/request"
PATH_TOPIC = "/motion_planning/path"
COMPUTE_TIME_TOPIC = "/motion_planning/compute_time"


@dataclass(frozen=True)
class Timing:
    """One request's outcome: round trip as the robot saw it, and the node's compute time."""

    name: str
    solved: bool
    round_trip_s: float
    compute_time_s: float
    path: tuple[Pose, ...]

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "solved": self.solved, "round_trip_s": self.round_trip_s,
                "compute_time_s": self.compute_time_s, "path": [p.as_dict() for p in self.path]}


def shipped_problems() -> list[str]:
    return sorted(p.stem for p in PROBLEMS_DIR.glob("*.cfg"))


def request_paths(names: Sequence[str], *, timeout: float = 120.0,
                  endpoints: dict[str, tuple[Pose, Pose]] | None = None, connect_timeout: float = 30.0,
                  seeds: dict[str, int] | None = None) -> list[Timing]:
    """Send one request per problem name, in turn, and wait for each path. Needs rospy.init_node done.

    ``seeds`` names a problem's seed, for a repeatable search (``node.request_name``).
    """
    cond = threading.Condition()
    paths: dict[tuple[str, int], Any] = {}
    # The node publishes a request's compute time, then its path, on two topics: two connections,
    # so either may arrive first. Each request gets one of each; times are matched by arrival after sending.
    compute_times: list[tuple[float, float]] = []  # (received, seconds)

    def on_time(msg: Float64) -> None:
        with cond:
            compute_times.append((time.perf_counter(), msg.data))
            cond.notify_all()

    def on_path(msg: PoseArray) -> None:
        with cond:
            paths[(msg.header.frame_id, msg.header.stamp.to_nsec())] = (time.perf_counter(), msg)
            cond.notify_all()

    def compute_since(sent: float) -> float | None:
        fresh = [seconds for received, seconds in compute_times if received >= sent]
        return fresh[0] if fresh else None

    def has_compute_since(sent: float) -> bool:
        return compute_since(sent) is not None

    subs = [rospy.Subscriber(COMPUTE_TIME_TOPIC, Float64, on_time, queue_size=10),
            rospy.Subscriber(PATH_TOPIC, PoseArray, on_path, queue_size=10)]
    pub = rospy.Publisher(REQUEST_TOPIC, PoseArray, queue_size=10)
    try:
        _wait_connected(pub, subs, connect_timeout)
        timings = []
        for name in names:
            request = PoseArray()
            request.header.frame_id = request_name(name, (seeds or {}).get(name))
            request.header.stamp = rospy.Time.now()
            if endpoints and name in endpoints:
                request.poses = [pose_to_msg(p) for p in endpoints[name]]
            key = (request.header.frame_id, request.header.stamp.to_nsec())
            sent = time.perf_counter()
            pub.publish(request)
            with cond:
                if not cond.wait_for(partial(operator.contains, paths, key), timeout=timeout):
                    raise WorkloadError(f"no path for {name!r} on {PATH_TOPIC} within {timeout:g} s")
                if not cond.wait_for(partial(has_compute_since, sent), timeout=timeout):
                    raise WorkloadError(f"no compute time for {name!r} on {COMPUTE_TIME_TOPIC} within {timeout:g} s")
                received, msg = paths.pop(key)
                compute = compute_since(sent) or 0.0
                compute_times.clear()
            path = tuple(pose_from_msg(p) for p in msg.poses)
            timings.append(Timing(name, bool(path), received - sent, compute, path))
        return timings
    finally:
        for sub in subs:
            sub.unregister()
        pub.unregister()


def _wait_connected(pub: Any, subs: Sequence[Any], timeout: float) -> None:
    def connected() -> bool | None:
        return True if pub.get_num_connections() and all(s.get_num_connections() for s in subs) else None

    if poll(connected, timeout=timeout, interval=0.05, backoff=1.0) is None:
        raise WorkloadError(f"no motion_planning node answered on {REQUEST_TOPIC} within {timeout:g} s")


def main(names: Sequence[str], *, timeout: float, as_json: bool = False) -> int:
    """One line per problem for a person; with ``as_json`` every timing and pose, for a program."""
    rospy.init_node("motion_planning_client", anonymous=True, disable_signals=True)
    timings = request_paths(list(names) or shipped_problems(), timeout=timeout)
    if as_json:
        print(json.dumps([t.as_dict() for t in timings]))
    else:
        for t in timings:
            state = f"solved, {len(t.path)} poses" if t.solved else "not solved"
            print(f"{t.name}: {state}; {t.round_trip_s:.3f} s round trip, {t.compute_time_s:.3f} s planning")
    return 0 if all(t.solved for t in timings) else 1
