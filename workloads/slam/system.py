"""The SLAM system: tracking here, local mapping and loop closing in their own processes.

Thread and process model (measured, not assumed: ``cv2`` releases the GIL while extracting ORB
features, GTSAM does not while optimising):

- the caller's thread tracks (``Tracker.track``) and owns the map;
- ``run_sequence`` reads and extracts frames ahead of it in ``cores`` threads;
- a mapping process runs local bundle adjustments; tracking hands it a new window whenever it
  is idle and a keyframe has arrived since (ORB-SLAM2's local mapping also skips to the newest);
- a loop process keeps the bag-of-words database, checks each keyframe for a loop and runs the
  pose-graph optimisation that tracking asks for when one closes.

``--cores N`` pins the process (and so its children) to N CPUs with ``sched_setaffinity``: the
edge's one core and the cloud's many run the same program. Processes are spawned and warmed up
before the clock starts; results come back on queues that tracking polls between frames.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import resource
import sys
import time
from collections import deque
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fogiac.errors import WorkloadError
from workloads.slam import sim3
from workloads.slam.backend import (
    BundleResult,
    PoseGraphJob,
    PoseGraphResult,
    bundle_adjust,
    optimise_pose_graph,
)
from workloads.slam.camera import Intrinsics
from workloads.slam.features import Extractor, Features
from workloads.slam.geometry import ate_rmse
from workloads.slam.loop import Loop, LoopDetector, LoopKeyframe
from workloads.slam.tracking import Config, Tracker, TrackResult
from workloads.slam.tum import FrameFiles, Sequence, Trajectory, load_frame, matched_positions

FLUSH = "flush"
# Monocular loops through a Sim(3) pose graph (the loop edge carries the scale the map drifted by,
# points and frames follow their keyframe's similarity) instead of the SE(3) one RGB-D keeps (its
# scale is metric). Off: on the rendered bigloops the map now keeps its scale by itself (0.41-0.44
# map units per metre at both ends of bigloop-1's loop), so there is little to correct, and the
# loop's scale read from one keyframe's points (1.09 there, the truth about 1.04) bent the loop
# more than it straightened it: bigloop-1 2.1 -> 3.6 cm, bigloop-0 unchanged (README, Known limits).
SIM3_LOOPS = False


def pin_cores(cores: int) -> int:
    """Restrict this process (and what it starts later) to ``cores`` of the CPUs it may use; 0: all."""
    allowed = sorted(os.sched_getaffinity(0))
    if cores > 0:
        allowed = allowed[:cores]
        os.sched_setaffinity(0, allowed)
    return len(allowed)


def cpu_seconds(pids: list[int]) -> float:
    """CPU seconds (user + system) so far of this process, all its threads, and the live processes ``pids``."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime + sum(process_cpu_seconds(pid) for pid in pids)


def process_cpu_seconds(pid: int) -> float:
    """CPU seconds (user + system) so far of the live process ``pid``; 0 if it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime


def _mapping_main(inbox: Any, outbox: Any) -> None:
    cv2.setNumThreads(1)
    outbox.put("ready")
    while (job := inbox.get()) is not None:
        try:
            outbox.put(bundle_adjust(job))
        except Exception as err:  # tracking waits for an answer before the next job: send one it will drop
            print(f"slam mapping: {type(err).__name__}: {err}", file=sys.stderr, flush=True)
            outbox.put(BundleResult(-1, job.kf_ids, job.poses, job.point_ids, job.positions,
                                    np.zeros((0, 2), np.int64), 0.0))


def _loop_main(inbox: Any, outbox: Any, intrinsics: Intrinsics, min_gap: int) -> None:
    cv2.setNumThreads(1)
    detector = LoopDetector(intrinsics, min_gap=min_gap)
    outbox.put("ready")
    while (message := inbox.get()) is not None:
        if isinstance(message, LoopKeyframe):
            loop = detector.add(message)
            if loop is not None:
                outbox.put(loop)
        elif isinstance(message, PoseGraphJob):
            outbox.put(optimise_pose_graph(message))
        else:
            outbox.put(message)  # a flush marker: everything sent before it is done


def _with_similarities(job: PoseGraphJob, loops: list[Loop]) -> PoseGraphJob:
    """The monocular graph: every loop edge (the job's last ``len(loops)``) measured as a similarity."""
    relative = job.relative.copy()
    for n, lp in enumerate(loops):
        if lp.similarity is not None:
            relative[len(relative) - len(loops) + n] = lp.similarity
    return replace(job, relative=relative, similarity=True)


@dataclass
class Stats:
    bundle_runs: int = 0
    bundle_s: float = 0.0
    loops: list[Loop] = field(default_factory=list)
    first_map_at: float | None = None  # monotonic time the first bundle-adjusted map was back
    first_map_frame: int | None = None  # frames tracked by then
    first_job_at: float | None = None  # monotonic time the first bundle adjustment was handed to mapping
    first_bundle_s: float | None = None  # the first map's adjustment's own seconds, in the mapping process
    frames: int = 0


class Slam:
    """Feed :meth:`track` frames' features in order; :meth:`finish` waits for the back end."""

    def __init__(self, intrinsics: Intrinsics, config: Config | None = None, *, mono: bool = False) -> None:
        self.tracker = Tracker(intrinsics, config, mono=mono)
        self.stats = Stats()
        ctx = mp.get_context("spawn")
        self._map_in, self._map_out, self._loop_in, self._loop_out = ctx.Queue(), ctx.Queue(), ctx.Queue(), ctx.Queue()
        self._procs = [
            ctx.Process(target=_mapping_main, args=(self._map_in, self._map_out), daemon=True, name="slam-mapping"),
            ctx.Process(target=_loop_main, args=(self._loop_in, self._loop_out, intrinsics,
                                                 self.tracker.config.loop_min_gap), daemon=True, name="slam-loop"),
        ]
        for proc in self._procs:
            proc.start()
        for outbox, proc in zip((self._map_out, self._loop_out), self._procs, strict=True):
            try:
                outbox.get(timeout=120)
            except queue.Empty:
                self.close()
                raise WorkloadError(f"the {proc.name} process did not start within 120 s") from None
        self._mapping_busy = False
        self._graphs_pending = 0
        self._loop_sent = 0  # keyframes handed to loop closing so far

    def track(self, features: Features) -> TrackResult:
        self._poll()
        self.stats.frames += 1
        result = self.tracker.track(features)
        if result.keyframe:
            if self.tracker.mono and SIM3_LOOPS:  # a loop's scale is read from the query's adjusted points
                self._adjust_now()
            for kf_id in range(self._loop_sent, len(self.tracker.map.keyframes)):
                self._loop_in.put(self._loop_keyframe(kf_id))
            self._loop_sent = len(self.tracker.map.keyframes)
            if self.tracker.mono:
                self._adjust_now()  # nothing left to do if it ran above
            else:
                self._start_bundle()
            if self.stats.first_map_at is None and self._mapping_busy:
                self._await_first_map()
        return result

    def _loop_keyframe(self, kf_id: int) -> LoopKeyframe:
        """The keyframe as loop closing sees it; monocular: with the points it made itself marked."""
        lk = self.tracker.loop_keyframe(kf_id)
        if not self.tracker.mono:
            return lk
        ids = self.tracker.map.keyframes[kf_id].point_ids
        fresh = np.zeros(len(ids), bool)
        fresh[ids >= 0] = self.tracker.map.points.ref[ids[ids >= 0]] == kf_id
        return replace(lk, fresh=fresh)

    def _adjust_now(self, timeout: float = 60.0) -> None:
        """Monocular: adjust the window around each new keyframe before tracking goes on. A monocular
        map has no depth to hold its scale; tracked on an unadjusted window, keyframes came out with
        short baselines and the map shrank (rendered bigloop, measured: adjusting 9 of 53 keyframes in
        the background gave 58 cm ATE; waiting for each adjustment before the next frame, 2.1 cm)."""
        deadline = time.monotonic() + timeout
        while self._mapping_busy and time.monotonic() < deadline:
            self._poll(block=0.5)
        self._start_bundle()
        while self._mapping_busy and time.monotonic() < deadline:
            self._poll(block=0.5)

    def _await_first_map(self, timeout: float = 60.0) -> None:
        """Block until the first adjustment is back. The first map is the one serial chain in the system
        (frames to the second keyframe, then its adjustment): while tracking waits, the adjustment has a
        core of its own where there are two or more, instead of sharing it with the frames that tracking
        would run ahead on an unadjusted map (extraction keeps reading ahead meanwhile)."""
        deadline = time.monotonic() + timeout
        while self.stats.first_map_at is None and self._mapping_busy and time.monotonic() < deadline:
            self._poll(block=0.5)

    def _start_bundle(self) -> None:
        if self._mapping_busy:
            return
        job = self.tracker.bundle_job()
        if job is not None:
            if self.stats.first_job_at is None:
                self.stats.first_job_at = time.monotonic()
            self._map_in.put(job)
            self._mapping_busy = True

    def _poll(self, *, block: float = 0.0) -> None:
        """Apply whatever the back end has finished; wait up to ``block`` seconds for the first answer."""
        for outbox in (self._map_out, self._loop_out):
            while True:
                try:
                    message = outbox.get(timeout=block) if block else outbox.get_nowait()
                except queue.Empty:
                    break
                block = 0.0
                self._handle(message)

    def _handle(self, message: object) -> None:
        if isinstance(message, BundleResult):
            self._mapping_busy = False
            self.stats.bundle_runs += 1
            self.stats.bundle_s += message.seconds
            if self.tracker.apply_bundle(message) and self.stats.first_map_at is None:
                self.stats.first_map_at = time.monotonic()
                self.stats.first_map_frame = self.stats.frames
                self.stats.first_bundle_s = message.seconds
            self._start_bundle()
        elif isinstance(message, Loop):
            self.stats.loops.append(message)
            job = self.tracker.pose_graph_job(message)
            if self.tracker.mono and SIM3_LOOPS:
                job = _with_similarities(job, self.tracker.loops)
            self._loop_in.put(job)
            self._graphs_pending += 1
        elif isinstance(message, PoseGraphResult):
            self._graphs_pending -= 1
            if self.tracker.mono and SIM3_LOOPS:
                rigid = sim3.correct_map(self.tracker.map, message.before, message.after)
                message = PoseGraphResult(message.epoch, message.kf_ids, message.before, rigid, message.seconds)
            self.tracker.apply_pose_graph(message)
        elif message == FLUSH:
            self._flushed = True

    def finish(self, *, timeout: float = 300.0) -> None:
        """Wait until loop closing has seen every keyframe and mapping is idle."""
        deadline = time.monotonic() + timeout
        self._flushed = False
        self._loop_in.put(FLUSH)
        while (not self._flushed or self._graphs_pending or self._mapping_busy) and time.monotonic() < deadline:
            self._poll(block=0.05)
        if self.tracker.mono and len(self.tracker.map.keyframes) >= 3:
            job = self.tracker.bundle_job(whole=True)
            if job is not None:
                self._map_in.put(job)
                self._mapping_busy = True
                while self._mapping_busy and time.monotonic() < deadline:
                    self._poll(block=0.05)

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self._procs if p.pid is not None]

    def close(self) -> None:
        for inbox in (self._map_in, self._loop_in):
            inbox.put(None)
        for proc in self._procs:
            proc.join(timeout=10)
            if proc.is_alive():
                proc.terminate()

    def __enter__(self) -> Slam:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class RunResult:
    frames: int
    tracked: int
    fps: float
    map_created_s: float | None
    wall_s: float
    keyframes: int
    map_points: int
    loops: tuple[tuple[int, int], ...]  # (query keyframe, matched keyframe) of each loop closed
    bundle_runs: int
    cores: int
    cores_used: float  # CPU seconds of tracking, extraction, mapping and loop closing / tracking's wall seconds
    mono: bool
    stage_cpu_s: dict[str, float]  # CPU seconds per stage while tracking: read, extract, track, mapping, loop
    first_map_frame: int | None  # frames handed to tracking when the first adjusted map came back
    map_chain_s: dict[str, float]  # the first map's chain: second keyframe made, adjustment's own time, map back
    trajectory: Trajectory
    ate_rmse_m: float | None = None
    scale: float | None = None  # Sim(3) alignment's scale (monocular)

    def summary(self) -> dict[str, object]:
        out: dict[str, object] = {
            "frames": self.frames, "tracked": self.tracked,
            "tracked_ratio": round(self.tracked / max(self.frames, 1), 4), "fps": round(self.fps, 2),
            "map_created_s": None if self.map_created_s is None else round(self.map_created_s, 3),
            "wall_s": round(self.wall_s, 3), "keyframes": self.keyframes, "map_points": self.map_points,
            "loops": len(self.loops), "bundle_runs": self.bundle_runs, "cores": self.cores,
            "cores_used": round(self.cores_used, 2),
            "stage_cpu_s": {k: round(v, 3) for k, v in self.stage_cpu_s.items()},
            "first_map_frame": self.first_map_frame,
            "map_chain_s": {k: round(v, 3) for k, v in self.map_chain_s.items()},
            "mode": "mono" if self.mono else "rgbd",
        }
        if self.ate_rmse_m is not None:
            out["ate_rmse_m"] = round(self.ate_rmse_m, 5)
            out["alignment"] = "sim3" if self.mono else "se3"
        if self.scale is not None:
            out["scale"] = round(self.scale, 4)
        return out


_WORKER: dict[str, Any] = {}


def _extract_init(intrinsics: Intrinsics, features: int, mono: bool) -> None:
    cv2.setNumThreads(1)
    _WORKER.update(extractor=Extractor(intrinsics, features=features), intrinsics=intrinsics, mono=mono)


def _extract_ready(delay: float) -> int:
    time.sleep(delay)  # long enough that each warm-up call lands on a worker of its own
    return os.getpid()


def _extract_frame(index: int, frame: FrameFiles) -> tuple[Features, float, float]:
    """(features, CPU seconds reading, CPU seconds extracting) of one frame, in an extraction process."""
    t0 = time.thread_time()
    grey, depth = load_frame(frame, _WORKER["intrinsics"])
    t1 = time.thread_time()
    features = _WORKER["extractor"](index, frame.stamp, grey, None if _WORKER["mono"] else depth)
    return features, t1 - t0, time.thread_time() - t1


def extraction_pool(intrinsics: Intrinsics, *, workers: int, features: int, mono: bool) -> ProcessPoolExecutor:
    """``workers`` extraction processes, started and warmed up (OpenCV imported, ORB made) before any clock."""
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                               initializer=_extract_init, initargs=(intrinsics, features, mono))
    list(pool.map(_extract_ready, [0.2] * workers))
    return pool


def _frames(seq: Sequence, pool: ProcessPoolExecutor, *, ahead: int, cpu: dict[str, float]) -> Iterator[Features]:
    """Features of every frame in order, read and extracted ``ahead`` frames in advance by the pool's
    processes (not threads: reading and extracting hold the GIL for part of each frame, and tracking
    holds it for most of its own); adds each stage's CPU seconds to ``cpu``."""
    pending = deque(pool.submit(_extract_frame, i, seq.frames[i]) for i in range(min(ahead, len(seq.frames))))
    for i in range(len(seq.frames)):
        if i + ahead < len(seq.frames):
            pending.append(pool.submit(_extract_frame, i + ahead, seq.frames[i + ahead]))
        t0 = time.monotonic()
        features, read_s, extract_s = pending.popleft().result()
        cpu["wait_wall"] += time.monotonic() - t0
        cpu["read"] += read_s
        cpu["extract"] += extract_s
        yield features


def _map_chain(stats: Stats, start: float) -> dict[str, float]:
    chain = {}
    if stats.first_job_at is not None:
        chain["keyframes_s"] = stats.first_job_at - start
    if stats.first_bundle_s is not None:
        chain["bundle_s"] = stats.first_bundle_s
    if stats.first_map_at is not None:
        chain["map_back_s"] = stats.first_map_at - start
    return chain


def evaluate(trajectory: Trajectory, truth: Trajectory, *, mono: bool) -> tuple[float, float]:
    """(ATE RMSE in metres, alignment scale): SE(3) alignment for RGB-D, Sim(3) for monocular."""
    estimate, true = matched_positions(trajectory, truth)
    rmse, alignment = ate_rmse(estimate, true, with_scale=mono)
    return rmse, alignment.scale


def run_sequence(seq: Sequence, *, cores: int = 0, mono: bool = False, config: Config | None = None,
                 max_frames: int | None = None) -> RunResult:
    """Run the whole system on a sequence as fast as it goes; times count from the first frame."""
    got = pin_cores(cores)
    cv2.setNumThreads(1)
    config = config or Config()
    if max_frames is not None:
        seq = Sequence(seq.root, seq.frames[:max_frames], seq.intrinsics, seq.groundtruth)
    with (Slam(seq.intrinsics, config, mono=mono) as slam,
          extraction_pool(seq.intrinsics, workers=got, features=config.features, mono=mono) as pool):
        pids = [*slam.pids, *(p.pid for p in pool._processes.values() if p.pid is not None)]  # noqa: SLF001
        stages = {"read": 0.0, "extract": 0.0, "track": 0.0, "track_wall": 0.0, "wait_wall": 0.0}
        back_start = [process_cpu_seconds(pid) for pid in slam.pids]
        start, cpu_start = time.monotonic(), cpu_seconds(pids)
        tracked = 0
        for features in _frames(seq, pool, ahead=2 * got + 1, cpu=stages):
            t0, w0 = time.thread_time(), time.monotonic()
            tracked += slam.track(features).tracked
            stages["track"] += time.thread_time() - t0
            stages["track_wall"] += time.monotonic() - w0
        tracking_s = time.monotonic() - start
        tracked += slam.tracker.placed_late
        cpu_s = cpu_seconds(pids) - cpu_start
        for name, pid, before in zip(("mapping", "loop"), slam.pids, back_start, strict=True):
            stages[name] = process_cpu_seconds(pid) - before
        slam.finish()
        wall_s = time.monotonic() - start
        first_map = slam.stats.first_map_at
        trajectory = slam.tracker.trajectory()
        result = RunResult(
            frames=len(seq.frames), tracked=tracked, fps=len(seq.frames) / tracking_s,
            map_created_s=None if first_map is None else first_map - start, wall_s=wall_s,
            keyframes=len(slam.tracker.map.keyframes), map_points=slam.tracker.map.points.count,
            loops=tuple((lp.query, lp.match) for lp in slam.stats.loops), bundle_runs=slam.stats.bundle_runs,
            cores=got, cores_used=cpu_s / tracking_s, mono=mono, trajectory=trajectory,
            stage_cpu_s=stages, first_map_frame=slam.stats.first_map_frame,
            map_chain_s=_map_chain(slam.stats, start),
        )
    if seq.groundtruth is not None and len(trajectory) >= 3:
        rmse, scale = evaluate(trajectory, seq.groundtruth, mono=mono)
        result = RunResult(**{**result.__dict__, "ate_rmse_m": rmse, "scale": scale if mono else None})
    return result
