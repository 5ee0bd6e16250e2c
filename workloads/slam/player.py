"""Robot side: publish a TUM sequence as a camera would, and collect the poses the node sends back.

Colour (bgr8), depth (16UC1 millimetres) and camera info go out at the sequence's frame rate
(or ``rate``), stamped with the sequence's own timestamps, so the poses that come back form a TUM
trajectory that is evaluated against the folder's ground truth. The round trip of a frame is the
time from publishing its images to receiving its pose (matched on the stamp).

``lockstep`` sends each frame only once the node has answered the one before (its compute time
came back), so no frame is dropped for arriving while the node is busy and every round trip is
one frame's own: what a benchmark of the node through a link measures. The report's ``fps`` is
poses over the seconds from the first frame sent to the last pose received.
"""

from __future__ import annotations

import statistics
import threading
import time
from functools import partial
from typing import Any

import cv2
import numpy as np
import rospy
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Float64, Header

from fogiac.errors import WorkloadError
from workloads.slam.geometry import make, quat_to_rot
from workloads.slam.node import DEPTH, IMAGE, INFO
from workloads.slam.system import evaluate
from workloads.slam.tum import Sequence, Trajectory

POSE, COMPUTE_TIME, MAP_POINTS = "/slam/pose", "/slam/compute_time", "/slam/map_points"
MAP_CREATED = "/slam/map_created"
ANSWER_S = 10.0  # lockstep: how long a frame waits for its answer before the next goes out (a frame may be lost)


def _more(answers: list[float], than: int) -> bool:
    return len(answers) > than


def camera_info(seq: Sequence, header: Any) -> Any:
    k = seq.intrinsics
    return CameraInfo(header=header, width=k.width, height=k.height, distortion_model="plumb_bob", D=[0.0] * 5,
                      K=[k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0], R=[1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
                      P=[k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0])


def image_msgs(seq: Sequence, index: int, header: Any) -> tuple[Any, Any]:
    frame = seq.frames[index]
    colour = cv2.imread(str(frame.rgb), cv2.IMREAD_COLOR)
    raw = cv2.imread(str(frame.depth), cv2.IMREAD_UNCHANGED)
    if colour is None or raw is None:
        raise WorkloadError(f"cannot read {frame.rgb if colour is None else frame.depth}")
    mm = np.round(raw.astype(np.float64) * 1000.0 / seq.intrinsics.depth_scale).astype("<u2")
    h, w = raw.shape
    image = Image(header=header, height=h, width=w, encoding="bgr8", is_bigendian=0, step=3 * w,
                  data=colour.tobytes())
    depth = Image(header=header, height=h, width=w, encoding="16UC1", is_bigendian=0, step=2 * w, data=mm.tobytes())
    return image, depth


def play(seq: Sequence, *, rate: float | None = None, wait_s: float = 30.0, linger_s: float = 5.0,
         mono: bool = False, lockstep: bool = False) -> dict[str, object]:
    """Publish every frame, then wait ``linger_s`` for the last poses; figures of the round trip.

    With ``lockstep`` the next frame goes out when this one's answer came (or after ``ANSWER_S``) instead
    of at the frame rate, and the player does not linger after the last answer."""
    if not rospy.core.is_initialized():
        rospy.init_node("slam_player", anonymous=True, disable_signals=True)
    image_pub = rospy.Publisher(IMAGE, Image, queue_size=2)
    depth_pub = rospy.Publisher(DEPTH, Image, queue_size=2)
    info_pub = rospy.Publisher(INFO, CameraInfo, queue_size=2, latch=True)
    sent: dict[int, float] = {}
    round_trips: list[float] = []
    compute: list[float] = []
    poses: dict[int, np.ndarray] = {}
    lock = threading.Lock()
    answered = threading.Condition(lock)
    last_pose_at = [0.0]
    map_created: list[float] = []

    def on_compute(msg: Any) -> None:
        with answered:
            compute.append(msg.data)
            answered.notify_all()

    def on_pose(msg: Any) -> None:
        stamp = msg.header.stamp.to_nsec()
        p, q = msg.pose.position, msg.pose.orientation
        with lock:
            if stamp in sent:
                round_trips.append(time.monotonic() - sent[stamp])
            poses[stamp] = make(quat_to_rot(np.array([q.x, q.y, q.z, q.w])), np.array([p.x, p.y, p.z]))
            last_pose_at[0] = time.monotonic()

    rospy.Subscriber(POSE, PoseStamped, on_pose, queue_size=100)
    rospy.Subscriber(COMPUTE_TIME, Float64, on_compute, queue_size=100)
    rospy.Subscriber(MAP_CREATED, Float64, lambda m: map_created.append(m.data), queue_size=1)
    clouds: list[int] = []
    rospy.Subscriber(MAP_POINTS, PointCloud2, lambda m: clouds.append(m.width), queue_size=10)
    info_pub.publish(camera_info(seq, Header(stamp=rospy.Time.from_sec(seq.frames[0].stamp))))
    deadline = time.monotonic() + wait_s
    while image_pub.get_num_connections() == 0 or (not mono and depth_pub.get_num_connections() == 0):
        if time.monotonic() > deadline:
            raise WorkloadError(f"no subscriber on {IMAGE} within {wait_s:.0f} s: is the slam node running?")
        time.sleep(0.05)
    time.sleep(0.5)  # the node's camera-info callback sets up its tracker
    period = 1.0 / (rate or seq.rate_hz)
    start = time.monotonic()
    for i, frame in enumerate(seq.frames):
        header = Header(stamp=rospy.Time.from_sec(frame.stamp), frame_id="camera_rgb_optical_frame")
        image, depth = image_msgs(seq, i, header)
        if not lockstep and (delay := start + i * period - time.monotonic()) > 0:
            time.sleep(delay)
        with lock:
            answers = len(compute)
        # The node drops frames that come before its camera info; so the first frame, in lockstep, goes
        # again each second until it is answered (as a camera keeps sending).
        for _ in range(max(1, int(wait_s)) if lockstep and i == 0 else 1):
            with lock:
                sent[header.stamp.to_nsec()] = time.monotonic()
            depth_pub.publish(depth)
            image_pub.publish(image)
            if lockstep:
                with answered:  # the node publishes a compute time for every frame it takes, tracked or not
                    if answered.wait_for(partial(_more, compute, answers), timeout=1.0 if i == 0 else ANSWER_S):
                        break
    time.sleep(0.2 if lockstep else linger_s)  # a pose follows its compute time
    with lock:
        stamps = sorted(poses)
        trajectory = Trajectory(np.array(stamps, dtype=np.float64) / 1e9,
                                np.array([poses[s] for s in stamps]).reshape(-1, 4, 4))
        trips = sorted(round_trips)
        first_sent = min(sent.values()) if sent else start
        took = last_pose_at[0] - first_sent if poses else 0.0
    report: dict[str, object] = {
        "frames": len(seq.frames), "poses": len(trajectory),
        "fps": round(len(trajectory) / took, 2) if took > 0 else None,
        "map_created_s": round(map_created[0], 3) if map_created else None,
        "round_trip_ms_median": round(1000 * statistics.median(trips), 1) if trips else None,
        "round_trip_ms_p95": round(1000 * trips[int(0.95 * (len(trips) - 1))], 1) if trips else None,
        "compute_ms_median": round(1000 * statistics.median(compute), 1) if compute else None,
        # Round trip less the node's own time: transport both ways (and, through fogiac, the relay).
        "network_ms_median": round(1000 * (statistics.median(trips) - statistics.median(compute)), 1)
        if trips and compute else None,
        "compute_time_messages": len(compute), "map_clouds": len(clouds), "map_points": clouds[-1] if clouds else 0,
    }
    if seq.groundtruth is not None and len(trajectory) >= 3:
        report["ate_rmse_m"] = round(evaluate(trajectory, seq.groundtruth, mono=mono)[0], 5)
    return report
