"""ROS 1 node around :func:`solve`, on standard messages only (no message build step).

Topics (node name ``motion_planning``, so ``~x`` is ``/motion_planning/x``; remap as usual):

- in  ``~request``       geometry_msgs/PoseArray: ``header.frame_id`` names a problem (a ``.cfg``
  in ``~problem_dir``, without extension), optionally followed by ``;seed=N`` for a repeatable
  search (see ``pool.py``); ``poses`` is ``[start, goal]`` or empty for the file's own endpoints.
- out ``~compute_time``  std_msgs/Float64: seconds :func:`solve` took (published first).
- out ``~path``          geometry_msgs/PoseArray: the simplified path, start to goal, with the
  request's header (frame_id and stamp; rospy renumbers ``seq`` itself, so match on stamp).
  An empty ``poses`` list means no path: unknown problem, bad request or not solved in time.

Params: ``~cores`` (0 or unset: all cores), ``~time_limit`` (0 or unset: each cfg's), ``~problem_dir``
(default: the shipped problems), ``~planner`` (default ``rrtconnect``), ``~resolution`` (0 or
unset: each problem's validity resolution), ``~mode`` (``divide``, the default: the workers share
one search, ``divided.py``, then a piece each of its path; ``share``: they race, then share the
finish; ``race``: the winner finishes alone; see ``share.py``).

The node is warm: at start it loads every problem in ``~problem_dir`` into ``~cores`` long-lived
worker processes (:class:`pool.WarmPlanner`), so a request pays for planning only. Requests are
answered one at a time; one that arrives during another waits its turn (up to the subscriber
queue of 10; rospy drops the oldest beyond that).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import rospy
from geometry_msgs.msg import Point, PoseArray, Quaternion
from geometry_msgs.msg import Pose as PoseMsg
from std_msgs.msg import Float64

from fogiac.errors import WorkloadError
from workloads.motion_planning.planner import DEFAULT_PLANNER, warm_up
from workloads.motion_planning.pool import WarmPlanner
from workloads.motion_planning.problem import PROBLEMS_DIR, Pose, load_problem
from workloads.motion_planning.share import DEFAULT_MODE

NODE_NAME = "motion_planning"
DEFAULT_PROBLEM_DIR = PROBLEMS_DIR  # ~problem_dir when the parameter is unset: the shipped problems


def pose_from_msg(msg: Any) -> Pose:
    p, q = msg.position, msg.orientation
    return Pose(p.x, p.y, p.z, q.x, q.y, q.z, q.w)


def pose_to_msg(pose: Pose) -> Any:
    return PoseMsg(Point(pose.x, pose.y, pose.z), Quaternion(pose.qx, pose.qy, pose.qz, pose.qw))


def request_name(name: str, seed: int | None = None) -> str:
    """A request's ``header.frame_id``: the problem's name, and its seed when it has one."""
    return name if seed is None else f"{name};seed={seed}"


def parse_request_name(frame_id: str) -> tuple[str, int | None]:
    """(problem name, seed or None) from a request's ``header.frame_id``; a bad seed is one line."""
    name, sep, option = frame_id.partition(";")
    if not sep:
        return name, None
    key, _, value = option.partition("=")
    if key != "seed" or not value.isdigit():
        raise WorkloadError(f"request {frame_id!r}: after ';' only 'seed=N' (N a whole number) is understood")
    return name, int(value)


class PlannerNode:
    """A warm planner over every problem in ``problem_dir``; answers each request in turn."""

    def __init__(self, *, problem_dir: Path, cores: int, time_limit: float | None, planner: str,
                 resolution: float | None = None, mode: str = DEFAULT_MODE) -> None:
        self.problem_dir, self.cores, self.time_limit, self.resolution = problem_dir, cores, time_limit, resolution
        problems = {path.stem: load_problem(path) for path in sorted(problem_dir.glob("*.cfg"))}
        if not problems:
            raise WorkloadError(f"{problem_dir}: no problem files (*.cfg)")
        self.planner = WarmPlanner(problems, workers=cores, planner=planner, mode=mode)

    def close(self) -> None:
        self.planner.close()

    def handle(self, request: Any) -> tuple[float, list[Pose]]:
        """(compute seconds, path) for one PoseArray request; an empty path on any failure."""
        name = request.header.frame_id
        try:
            name, seed = parse_request_name(name)
            if len(request.poses) not in (0, 2):
                raise WorkloadError(f"request has {len(request.poses)} poses; send [start, goal] or none")
            start, goal = (pose_from_msg(p) for p in request.poses) if request.poses else (None, None)
            solution = self.planner.solve(name, start=start, goal=goal, time_limit=self.time_limit,
                                          resolution=self.resolution, seed=seed)
        except WorkloadError as err:
            rospy.logerr(f"motion_planning: {err}")
            return 0.0, []
        except Exception as err:  # a robot waits for an answer: log the bug, answer "no path"
            rospy.logerr(f"motion_planning: {type(err).__name__}: {err}")
            return 0.0, []
        if solution.solved:
            rospy.loginfo(f"motion_planning: {name}: path of {len(solution.path)} poses, proven free at "
                          f"{solution.check_resolution:.3g} (planned at {solution.resolution:.3g})")
        else:
            rospy.logwarn(f"motion_planning: {name}: not solved ({solution.status})")
        return solution.solve_time_s, list(solution.path)


def main() -> None:
    rospy.init_node(NODE_NAME)
    time_limit = float(rospy.get_param("~time_limit", 0.0))
    cores = int(rospy.get_param("~cores", 0))
    resolution = float(rospy.get_param("~resolution", 0.0))
    warm_up()
    node = PlannerNode(
        problem_dir=Path(rospy.get_param("~problem_dir", str(DEFAULT_PROBLEM_DIR))),
        cores=cores if cores > 0 else os.cpu_count() or 1,
        time_limit=time_limit if time_limit > 0 else None,
        planner=str(rospy.get_param("~planner", DEFAULT_PLANNER)),
        resolution=resolution if resolution > 0 else None,
        mode=str(rospy.get_param("~mode", DEFAULT_MODE)),
    )
    rospy.on_shutdown(node.close)
    path_pub = rospy.Publisher("~path", PoseArray, queue_size=10)
    time_pub = rospy.Publisher("~compute_time", Float64, queue_size=10)

    def on_request(request: PoseArray) -> None:
        seconds, path = node.handle(request)
        time_pub.publish(Float64(seconds))
        path_pub.publish(PoseArray(header=request.header, poses=[pose_to_msg(p) for p in path]))

    rospy.Subscriber("~request", PoseArray, on_request, queue_size=10)
    rospy.loginfo(f"motion_planning: ready, {node.cores} cores, problems in {node.problem_dir}")
    rospy.spin()
