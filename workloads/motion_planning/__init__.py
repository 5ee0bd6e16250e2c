"""Multi-core SE(3) rigid-body motion planning: OMPL planners racing in processes, fcl collisions.

Pure core: :func:`load_problem` reads an OMPL.app-style ``.cfg``; :func:`solve` plans;
:func:`path_is_collision_free` re-checks a path on its own. The ROS node (``node.py``) and the
robot-side client (``client.py``) are thin shells around these.
"""

from __future__ import annotations

from workloads.motion_planning.geometry import path_is_collision_free
from workloads.motion_planning.planner import PLANNERS, Solution, solve, warm_up
from workloads.motion_planning.problem import Pose, Problem, load_problem

__all__ = ["PLANNERS", "Pose", "Problem", "Solution", "load_problem", "path_is_collision_free", "solve", "warm_up"]
