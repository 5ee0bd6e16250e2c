"""Sharing a request's work between warm workers: race to a first path, then finish it in pieces.

Measured on the shipped problems (README, "How the cores are used"), a request's time on one
core is the search plus simplifying and proving the path, and the second part is as long as the
first on cubicles and the maze. A race only shortens the search (the luckier seed wins); the
winner then simplifies and proves alone while the others idle. In the ``share`` mode the first
path is cut into one piece per worker, of about equal sweep (the farthest any robot point moves,
the measure that both simplifying and proving pay for), and every worker simplifies and proves
its piece at once; the pieces meet at planner vertices, so the joined path is proven piece by
piece. OMPL's own work-sharing tools (PRM with a shared roadmap, AnytimePathShortening,
PathHybridization) are not in the ompl 2.0.1 Python bindings, and threads in one process would
share the GIL with the Python validity checker anyway; processes sharing pieces of a path need
neither.
"""

from __future__ import annotations

from itertools import pairwise
from typing import Any

import numpy as np

from workloads.motion_planning.geometry import rotation_angle
from workloads.motion_planning.problem import Pose

MODES = ("divide", "race", "share")
# divide is the default: one search split between the workers (divided.py), then finished in pieces as
# share does; race and share run a whole search per worker (README, "The divided search").
DEFAULT_MODE = "divide"


def sweep(a: Pose, b: Pose, radius: float) -> float:
    """How far any robot point moves from a to b (linear position, slerp rotation)."""
    return float(np.linalg.norm(b.position() - a.position())) + radius * rotation_angle(a.quaternion(), b.quaternion())


def split_path(path: list[Pose], pieces: int, *, radius: float) -> list[list[Pose]]:
    """At most ``pieces`` consecutive pieces of about equal sweep, each sharing its last pose with the next.

    Cuts fall on the path's own vertices only, so a path of n poses gives at most n - 1 pieces.
    """
    if len(path) < 3 or pieces < 2:
        return [path]
    lengths = [sweep(a, b, radius) for a, b in pairwise(path)]
    total = sum(lengths)
    cuts, walked, target = [0], 0.0, 1
    for i, length in enumerate(lengths[:-1], start=1):
        walked += length
        if target < pieces and walked >= total * target / pieces - length / 2 and i > cuts[-1]:
            cuts.append(i)
            target += 1
    cuts.append(len(path) - 1)
    return [path[a:b + 1] for a, b in pairwise(cuts)]


def simplify_shares(pieces: list[list[Pose]], seconds: float, *, radius: float) -> list[float]:
    """The request's simplification budget split over the pieces by sweep: the same work, shared.

    Simplification runs until it converges or its budget is spent, and on the shipped problems
    one core spends the whole 0.5 s; a piece with the whole budget would too, and sharing would
    then save nothing on that phase.
    """
    sweeps = [sum(sweep(a, b, radius) for a, b in pairwise(piece)) for piece in pieces]
    total = sum(sweeps)
    return [seconds * s / total if total > 0 else seconds / len(pieces) for s in sweeps]


def join_reports(first: dict[str, Any], pieces: list[dict[str, Any] | None]) -> dict[str, Any]:
    """One answer from the race winner's report and its pieces' (None: that worker died).

    ``cpu_s`` is the critical path: the winner's CPU time to its first path plus the slowest piece's.
    """
    report = {**first, "simplify_time_s": max((p["simplify_time_s"] for p in pieces if p and "simplify_time_s" in p),
                                              default=0.0),
              "repairs": sum(p.get("repairs", 0) for p in pieces if p),
              "clearance_queries": sum(p.get("clearance_queries", 0) for p in pieces if p),
              "pieces": len(pieces),
              "cpu_s": first["cpu_s"] + max((p.get("cpu_s", 0.0) for p in pieces if p), default=0.0)}
    for p in pieces:
        if p is not None and "resolution" in p:
            report["resolution"], report["check_resolution"] = p["resolution"], p["check_resolution"]
    if any(p is None for p in pieces):
        return {**report, "solved": False, "status": "a worker died while finishing its piece", "path": []}
    bad = next((p for p in pieces if p is not None and not p["solved"]), None)
    if bad is not None:
        return {**report, "solved": False, "status": bad["status"], "path": []}
    path: list[Any] = list(pieces[0]["path"]) if pieces[0] else []
    for p in pieces[1:]:
        assert p is not None
        path += p["path"][1:]
    return {**report, "solved": True, "status": "exact solution", "path": path}
