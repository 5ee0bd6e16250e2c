"""The divided search: one bidirectional tree search whose work is split between the workers.

A race (``planner.py``) runs one whole search per worker and keeps the first to finish, so k
workers do k times the work for the luck of the best draw. Here the workers grow the *same* two
trees (one from the start, one from the goal, RRT-Connect's extend-then-connect) in rounds:

- every round has a fixed batch of samples, drawn from the seed's stream, after the connects the
  merge before left unfinished; sample ``i`` extends the start tree when ``i + round`` is even, else
  the goal tree, from its nearest node (in the trees as merged ``rounds.LAG`` rounds back, so the
  workers need not wait for a round's last tasks before the next round starts) by at most
  ``step`` (and ``EXTEND_CHECKS`` checks), to ``BACK_OFF`` checks short of the last pose its check
  passed when blocked (a node touching a wall is a path vertex no proof can pass); the other tree's
  nearest node then goes straight toward the new node for at most ``CONNECT_CHECKS`` checks, its
  valid prefix (backed off alike) added as nodes a step apart; a full reach joins the trees;
- each task is a pure function of the trees and the seed (:meth:`TreeWorker.task`), so it does not
  matter which worker runs it; ``rounds.py`` hands them out, and every worker applies the same
  :func:`merge_round` (task order) to its own copy of the trees;
- the first round with a joining task ends the search: the lowest such task's path (the rounds
  already started after it are dropped).

So the k workers together do the work one worker would do, each about 1/k of it, and the
answer depends on the seed alone, not on k or on which worker took which task (the batch is
``batch_size(k)``: the same for any k up to 8). What stays serial is the merge every worker
applies; ``rounds.Division`` measures it.

Pure numpy and fcl (no OMPL): the workers run it beside their ``search.Search``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from workloads.motion_planning.geometry import CollisionChecker
from workloads.motion_planning.problem import Pose, Problem, space_extent

DEFAULT_BATCH = 32  # samples per round for up to 8 workers; 4 per worker beyond
STEP_FRACTION = 0.2  # the extend step, of the space's extent (RRT-Connect's default range)
CONNECT_CHECKS = 64  # a connect checks at most this many poses per round, then goes on in the next
EXTEND_CHECKS = 64  # an extension checks at most this many poses (and steps no farther than RRT-Connect would)
MAX_CHAIN = 4  # nodes a connect adds in one round
BACK_OFF = 2  # a blocked motion's last node this many checks short of the last pose that passed
DRAW_ROUNDS = 16  # rounds whose samples are drawn at once (one draw a round cost as much as the merge)


def batch_size(workers: int) -> int:
    """Samples per round: fixed up to 8 workers (so 1 and 2 workers search alike), then 4 per worker."""
    return max(DEFAULT_BATCH, 4 * workers)


def as_array(pose: Pose) -> np.ndarray:
    """(x, y, z, qw, qx, qy, qz): the order fcl takes."""
    q = pose.quaternion()
    return np.array([pose.x, pose.y, pose.z, q[0], q[1], q[2], q[3]])


def as_pose(row: np.ndarray) -> Pose:
    return Pose.from_arrays(row[:3], row[3:])


class Trees:
    """Both trees (0: from the start, 1: from the goal) as growable arrays of poses and parents."""

    def __init__(self, start: np.ndarray, goal: np.ndarray) -> None:
        self.poses = [start[None, :].copy(), goal[None, :].copy()]
        self.parents = [np.array([-1]), np.array([-1])]

    def size(self, tree: int) -> int:
        return len(self.parents[tree])

    def append(self, merge: list[tuple[np.ndarray, np.ndarray]]) -> None:
        for tree, (poses, parents) in enumerate(merge):
            if len(parents):
                self.poses[tree] = np.concatenate([self.poses[tree], poses])
                self.parents[tree] = np.concatenate([self.parents[tree], parents])

    def branch(self, tree: int, node: int) -> list[np.ndarray]:
        """Poses from the tree's root to ``node``."""
        out = []
        while node >= 0:
            out.append(self.poses[tree][node])
            node = int(self.parents[tree][node])
        return out[::-1]


def distances(poses: np.ndarray, pose: np.ndarray, radius: float) -> np.ndarray:
    """The sweep from each of ``poses`` to ``pose``: how far any robot point moves (position + radius * turn)."""
    dot = np.abs(poses[:, 3:] @ pose[3:])
    return np.linalg.norm(poses[:, :3] - pose[:3], axis=1) + radius * 2.0 * np.arccos(np.minimum(1.0, dot))


def between(a: np.ndarray, b: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Poses at fractions ``ts`` from a to b: linear position, shortest-arc slerp (OMPL's SE(3) way)."""
    q0, q1 = a[3:], b[3:].copy()
    dot = float(q0 @ q1)
    if dot < 0.0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + ts[:, None] * (q1 - q0)
    else:
        theta = math.acos(min(1.0, dot))
        q = (np.sin((1 - ts) * theta)[:, None] * q0 + np.sin(ts * theta)[:, None] * q1) / math.sin(theta)
    q /= np.linalg.norm(q, axis=1)[:, None]
    return np.hstack([a[:3] + ts[:, None] * (b[:3] - a[:3]), q])


class TreeWorker:
    """One worker's side of the divided search on one problem: a copy of the trees, fcl checks."""

    def __init__(self, problem: Problem, checker: CollisionChecker | None = None) -> None:
        self.problem = problem
        self.checker = checker or CollisionChecker(problem)
        self.radius = problem.robot.radius()
        self.lo, self.hi = np.array(problem.bounds_min), np.array(problem.bounds_max)
        self.extent = space_extent(problem)
        self.step = STEP_FRACTION * self.extent
        self.trees: Trees | None = None
        self.resolution = 0.0
        self.seed = 0
        self.batch = DEFAULT_BATCH
        self.view = (1, 1)
        self._rng, self._drawn, self._ahead = np.random.default_rng(0), 0, np.empty((0, 7))

    def begin(self, start: Pose, goal: Pose, *, resolution: float, seed: int, batch: int) -> str | None:
        """New trees; a status when no search is needed (``invalid start``, ``invalid goal``, ``straight``:
        the straight move is free). Every worker checks this alike: a few checks, the same answer."""
        self.trees = Trees(as_array(start), as_array(goal))
        self.resolution, self.seed, self.batch = resolution, seed, batch
        self._rng, self._drawn, self._ahead = np.random.default_rng(seed), 0, np.empty((0, 7))
        self.step = min(STEP_FRACTION * self.extent, EXTEND_CHECKS * resolution)
        a, b = self.trees.poses[0][0], self.trees.poses[1][0]
        if not self._free(a):
            return "invalid start"
        if not self._free(b):
            return "invalid goal"
        return "straight" if self.valid_prefix(a, b, limit=None)[0] == 1.0 else None

    def task(self, i: int, number: int, pending: list[tuple[int, int, int]], samples: np.ndarray,
             view: tuple[int, int] | None = None) -> tuple[Any, ...]:
        """Task ``i`` of round ``number``: first the connects an earlier round left unfinished (``pending``:
        the tree of the node to reach, that node, the other tree's node to go on from), then the samples.

        ``view``: how many nodes of each tree the round sees (the trees as they stood ``LAG`` rounds back;
        later nodes are ignored, so the answer does not depend on how far this worker's copy has got)."""
        assert self.trees is not None
        self.view = view or (self.trees.size(0), self.trees.size(1))
        if i < len(pending):
            tree, x, c = pending[i]
            return (i, tree, x, None, *self.connect(tree, self.trees.poses[tree][x], c))
        return self.extend(i, (i + number) % 2, samples[i - len(pending)])

    def _seen(self, tree: int) -> np.ndarray:
        assert self.trees is not None
        return self.trees.poses[tree][:self.view[tree]]

    def samples(self, number: int) -> np.ndarray:
        """The round's batch of uniform poses, the same in every worker: the seed's one stream, drawn a
        round at a time in round order (every worker draws every round, in order; a fresh generator per
        round cost as much as merging it)."""
        if number != self._drawn:
            raise ValueError(f"round {number}'s samples drawn out of order (next: {self._drawn})")
        self._drawn += 1
        at = (number % DRAW_ROUNDS) * self.batch
        if at == 0:  # the next DRAW_ROUNDS rounds' samples at once
            n = DRAW_ROUNDS * self.batch
            positions = self._rng.uniform(self.lo, self.hi, size=(n, 3))
            q = self._rng.normal(size=(n, 4))
            self._ahead = np.hstack([positions, q / np.linalg.norm(q, axis=1)[:, None]])
        return self._ahead[at:at + self.batch]

    def extend(self, index: int, tree: int, sample: np.ndarray) -> tuple[Any, ...]:
        """(index, tree, near, new pose or None, other tree's node, its chain toward the new pose, joined,
        the connect goes on next round)."""
        assert self.trees is not None
        poses = self._seen(tree)
        d = distances(poses, sample, self.radius)
        near = int(np.argmin(d))
        target = sample if d[near] <= self.step else between(poses[near], sample,
                                                             np.array([self.step / d[near]]))[0]
        reached, _ = self.valid_prefix(poses[near], target, limit=None)
        if reached == 0.0:
            return (index, tree, near, None, -1, [], False, False)
        new = target if reached == 1.0 else between(poses[near], target, np.array([reached]))[0]
        y = int(np.argmin(distances(self._seen(1 - tree), new, self.radius)))
        return (index, tree, near, new, *self.connect(tree, new, y))

    def connect(self, tree: int, new: np.ndarray, y: int) -> tuple[int, list[np.ndarray], bool, bool]:
        """The other tree's node ``y`` goes straight toward ``new`` for at most ``CONNECT_CHECKS`` checks:
        (y, the nodes it adds a step apart, whether it reached ``new``, whether it goes on next round).

        The cap keeps every task short, so no worker waits long on another's last task of a round."""
        assert self.trees is not None
        origin = self.trees.poses[1 - tree][y]
        got, capped = self.valid_prefix(origin, new, limit=CONNECT_CHECKS)
        if got == 1.0:
            return (y, [], True, False)
        length = got * float(distances(origin[None, :], new, self.radius)[0])
        if length < self.resolution:
            return (y, [], False, False)
        count = min(MAX_CHAIN, int(length // self.step) + 1)
        fractions = [got * (j + 1) / count for j in range(count)]  # a step apart or more, the last at ``got``
        return (y, list(between(origin, new, np.array(fractions))), False, capped)

    def valid_prefix(self, a: np.ndarray, b: np.ndarray, *, limit: int | None) -> tuple[float, bool]:
        """The fraction of a -> b whose poses, no robot point moving more than the resolution between two,
        all pass the collision check, from a onward (a itself is taken as checked); and whether it
        stopped at ``limit`` checks, all passed, short of b.

        Stopped by a collision, the fraction ends ``BACK_OFF`` checks short of the last pose that
        passed: a node there would touch the wall, and a path vertex with no clearance can be neither
        lifted clear nor proven, so its path ended "unproven" (home, 2 seeds of 13)."""
        sweep = float(distances(a[None, :], b, self.radius)[0])
        n = max(1, math.ceil(sweep / self.resolution))
        upto = n if limit is None else min(n, limit)
        poses = between(a, b, np.arange(1, upto + 1) / n)
        for i, pose in enumerate(poses):
            if not self.checker.is_free(pose[:3], pose[3:]):
                return max(0, i - BACK_OFF) / n, False
        return upto / n, upto < n

    def _free(self, pose: np.ndarray) -> bool:
        return bool(np.all(self.lo <= pose[:3]) and np.all(pose[:3] <= self.hi)) and self.checker.is_free(
            pose[:3], pose[3:])


def merge_round(trees: Trees, results: list[tuple[Any, ...]]
                ) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[int, int, int]], list[Pose] | None]:
    """The round's nodes in task order (appended to ``trees``), the connects to go on with next round,
    and the path if a task joined the trees."""
    sizes = [trees.size(0), trees.size(1)]
    added: list[list[np.ndarray]] = [[], []]
    parents: list[list[int]] = [[], []]
    pending: list[tuple[int, int, int]] = []
    path: list[Pose] | None = None
    for _, tree, near, new, y, chain, joined, goes_on in sorted(results, key=lambda r: r[0]):
        if new is None and y < 0:
            continue  # an extension that did not move
        if joined and path is None:
            own = trees.branch(tree, near) + ([] if new is None else [new])
            theirs = trees.branch(1 - tree, y)[::-1]
            rows = own + theirs if tree == 0 else (own + theirs)[::-1]
            path = [as_pose(r) for r in rows]
        x = near  # the node the other tree reaches for: this task's new node, or (a connect going on) ``near``
        if new is not None:
            added[tree].append(new)
            parents[tree].append(near)
            x = sizes[tree] + len(parents[tree]) - 1
        parent = y
        for pose in chain:
            added[1 - tree].append(pose)
            parents[1 - tree].append(parent)
            parent = sizes[1 - tree] + len(parents[1 - tree]) - 1
        if goes_on:
            pending.append((tree, x, parent))
    merge = [(np.array(added[t]).reshape(-1, 7), np.array(parents[t], dtype=np.int64)) for t in (0, 1)]
    trees.append(merge)
    return merge, pending, path
