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

from dataclasses import dataclass
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
    return [path[a:b + 1] for a, b in pairwise(cut_indices(path, pieces, radius=radius))]


def cut_indices(path: list[Pose], pieces: int, *, radius: float) -> list[int]:
    """The vertices :func:`split_path` cuts at, the path's ends included (piece i: cuts[i] to cuts[i + 1])."""
    if len(path) < 3 or pieces < 2:
        return [0, len(path) - 1]
    lengths = [sweep(a, b, radius) for a, b in pairwise(path)]
    total = sum(lengths)
    cuts, walked, target = [0], 0.0, 1
    for i, length in enumerate(lengths[:-1], start=1):
        walked += length
        if target < pieces and walked >= total * target / pieces - length / 2 and i > cuts[-1]:
            cuts.append(i)
            target += 1
    cuts.append(len(path) - 1)
    return cuts


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


@dataclass(frozen=True)
class Phases:
    """Where a divided solve's time went, phase by phase, and how much of it ran on one worker while
    the others waited (what Amdahl's law keeps from dividing).

    CPU seconds are the figures other jobs' load does not stretch (on a shared machine the wall can
    be half another job's). Serial CPU: one copy of the search's per-round draws and merges (every
    worker runs them; the other copies are repeated, not divided, work), any step one worker runs alone
    (``lift_cpu_s``: lifting the found path before it is cut, when that is not done in pieces), and the
    caller's own thread (``parent_cpu_s``: handing the request out, gathering and joining the reports).
    """

    workers: int
    solve_wall_s: float  # the call, request in to answer out
    search_wall_s: float
    search_cpu_s: float  # every worker's, waiting included
    merge_cpu_s: float  # drawing and merging the rounds: the mean per worker (each does it all)
    lift_wall_s: float  # one worker lifting the whole found path while the others wait (0: not done so)
    lift_cpu_s: float
    finish_wall_s: float  # simplifying and proving, from the first piece sent to the last report in
    finish_cpu_s: tuple[float, ...]  # per worker
    finish_busy_s: tuple[float, ...]  # per worker: wall seconds on its pieces
    finish_claims: tuple[int, ...] = ()  # pieces each worker finished (claimed from a shared counter)
    parent_cpu_s: float = 0.0  # the calling thread's: handing the request out, gathering and joining the reports

    @property
    def total_cpu_s(self) -> float:
        return self.search_cpu_s + self.lift_cpu_s + sum(self.finish_cpu_s) + self.parent_cpu_s

    @property
    def serial_cpu_s(self) -> float:
        return self.merge_cpu_s + self.lift_cpu_s + self.parent_cpu_s

    @property
    def serial_cpu_share(self) -> float:
        """Serial CPU over one worker's equivalent of the solve (the repeated merges counted once)."""
        one = self.total_cpu_s - (self.workers - 1) * self.merge_cpu_s
        return self.serial_cpu_s / one if one > 0 else 0.0

    @property
    def finish_wait_s(self) -> float:
        """Wall seconds of the finish in which a worker waited for another's last piece (mean)."""
        if not self.finish_busy_s:
            return 0.0
        return max(0.0, self.finish_wall_s - sum(self.finish_busy_s) / len(self.finish_busy_s))

    def projected_speedup_cpu(self, cores: int) -> float:
        """Amdahl's law on these CPU seconds: the serial CPU stays, the rest divides by ``cores``.
        A projection from a measured split, not a measurement; waiting (imbalance) is left out."""
        share = self.serial_cpu_share
        return 1.0 / (share + (1.0 - share) / cores) if self.total_cpu_s > 0 else 1.0

    def as_dict(self) -> dict[str, Any]:
        return {"workers": self.workers, "solve_wall_s": self.solve_wall_s, "search_wall_s": self.search_wall_s,
                "search_cpu_s": self.search_cpu_s, "merge_cpu_s": self.merge_cpu_s,
                "lift_wall_s": self.lift_wall_s, "lift_cpu_s": self.lift_cpu_s,
                "finish_wall_s": self.finish_wall_s, "finish_cpu_s": list(self.finish_cpu_s),
                "finish_busy_s": list(self.finish_busy_s), "finish_claims": list(self.finish_claims),
                "parent_cpu_s": self.parent_cpu_s,
                "serial_cpu_s": self.serial_cpu_s, "serial_cpu_share": self.serial_cpu_share,
                "total_cpu_s": self.total_cpu_s}
