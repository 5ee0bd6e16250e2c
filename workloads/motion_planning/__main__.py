"""``python -m workloads.motion_planning {solve,node,client}``: a thin command-line shell.

argparse, not typer: the container image needs nothing beyond the workload's own libraries.
Errors the user can fix print one line and exit 1; so does an unsolved problem.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from fogiac.errors import FogiacError
from workloads.motion_planning import load_problem, solve
from workloads.motion_planning.planner import DEFAULT_PLANNER, PLANNERS
from workloads.motion_planning.share import DEFAULT_MODE, MODES


def _solve(args: argparse.Namespace) -> int:
    problem = load_problem(args.problem)
    solution = solve(problem, cores=args.cores, time_limit=args.time_limit, seed=args.seed, planner=args.planner,
                     resolution=args.resolution, mode=args.mode)
    if args.json:
        print(json.dumps(solution.as_dict()))
    else:
        state = "solved" if solution.solved else f"not solved ({solution.status})"
        print(f"{problem.name}: {state} in {solution.solve_time_s:.3f} s on {solution.cores} cores, "
              f"{len(solution.path)} poses, proven free at {solution.check_resolution:.3g} "
              f"(planned at {solution.resolution:.3g})")
    return 0 if solution.solved else 1


# node and client import rospy: only they need ROS, so `solve` runs where it is not installed.
def _node(args: argparse.Namespace) -> int:
    from workloads.motion_planning.node import main  # noqa: PLC0415 (rospy, see above)

    main()
    return 0


def _client(args: argparse.Namespace) -> int:
    from workloads.master import use  # noqa: PLC0415 (before rospy reads ROS_MASTER_URI)
    from workloads.motion_planning.client import main  # noqa: PLC0415 (rospy, see above)

    use(args.master, args.manifest, timeout=args.master_timeout)
    return main(args.names, timeout=args.timeout, as_json=args.json)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m workloads.motion_planning")
    verbs = parser.add_subparsers(dest="verb", required=True)
    s = verbs.add_parser("solve", help="plan one problem file")
    s.add_argument("problem", help="OMPL.app-style .cfg file")
    s.add_argument("--cores", type=int, default=None, help="planner processes (default: all cores)")
    s.add_argument("--time-limit", type=float, default=None, help="seconds (default: the cfg's time_limit)")
    s.add_argument("--seed", type=int, default=None)
    s.add_argument("--resolution", type=float, default=None,
                   help="world units a robot point may move between checks (default: the cfg's, else fitted)")
    s.add_argument("--planner", choices=sorted(PLANNERS), default=DEFAULT_PLANNER,
                   help="the OMPL planner of the race and share modes")
    s.add_argument("--mode", choices=MODES, default=DEFAULT_MODE,
                   help="divide: one search split between the cores; race/share: one search per core")
    s.add_argument("--json", action="store_true", help="print the Solution as one JSON object")
    s.set_defaults(run=_solve)
    n = verbs.add_parser("node", help="run the ROS node (rospy args such as __name:= pass through)")
    n.set_defaults(run=_node)
    c = verbs.add_parser("client", help="send problems to a running node, print one line of timings each")
    c.add_argument("names", nargs="*", help="problem names (default: every shipped problem)")
    c.add_argument("--timeout", type=float, default=120.0, help="seconds to wait for each path")
    c.add_argument("--json", action="store_true", help="print the timings and paths as one JSON array (for machines)")
    c.add_argument("--master", default=None,
                   help="the robot's ROS master (default: ./fogiac.yaml's edge.ros_master, else ROS_MASTER_URI)")
    c.add_argument("--manifest", type=Path, default=None, help="read edge.ros_master from this manifest")
    c.add_argument("--master-timeout", type=float, default=10.0, help="seconds to wait for the master to answer")
    c.set_defaults(run=_client)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    raw = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args([a for a in raw if ":=" not in a])  # rospy reads a:=b from sys.argv
    try:
        return args.run(args)
    except FogiacError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
