"""Test client for the grasp node, run as its own process (rospy allows one node per process).

argv: DEPTH.npy FX FY CX CY TIMEOUT ENCODING... ; publishes CameraInfo and the depth image in
each encoding until a grasp answers it, then prints one JSON line per encoding. Requests are
matched to answers by stamp (rospy rewrites header.seq on publish).
"""

from __future__ import annotations

import json
import sys
import threading
import time

import numpy as np
import rospy
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Float64


def image_message(depth: np.ndarray, encoding: str, seq: int) -> Image:
    arr = depth.astype("<f4") if encoding == "32FC1" else np.round(depth * 1000).astype("<u2")
    msg = Image(height=depth.shape[0], width=depth.shape[1], encoding=encoding, is_bigendian=0)
    msg.step = depth.shape[1] * arr.itemsize
    msg.data = arr.tobytes()
    msg.header.stamp = rospy.Time(1000 + seq, 500)
    msg.header.frame_id = "camera_depth_optical_frame"
    return msg


def main() -> None:
    path, fx, fy, cx, cy, timeout, *encodings = sys.argv[1:]
    depth = np.load(path)
    rospy.init_node("grasp_test_client", anonymous=True, disable_signals=True)
    lock = threading.Lock()
    poses: list[PoseStamped] = []
    quality: list[float] = []
    seconds: list[float] = []

    def keep(store: list, value: object) -> None:
        with lock:
            store.append(value)

    rospy.Subscriber("/grasp", PoseStamped, lambda m: keep(poses, m))
    rospy.Subscriber("/grasp/quality", Float64, lambda m: keep(quality, m.data))
    rospy.Subscriber("/grasp/compute_time", Float64, lambda m: keep(seconds, m.data))
    info_pub = rospy.Publisher("/depth/camera_info", CameraInfo, queue_size=1, latch=True)
    image_pub = rospy.Publisher("/depth/image", Image, queue_size=1)
    info = CameraInfo(height=depth.shape[0], width=depth.shape[1])
    info.K = [float(fx), 0.0, float(cx), 0.0, float(fy), float(cy), 0.0, 0.0, 1.0]
    info_pub.publish(info)
    deadline = time.monotonic() + float(timeout)
    for n, encoding in enumerate(encodings):
        seq = n * 1000
        sent: set[int] = set()
        answer = None
        while answer is None and time.monotonic() < deadline:
            seq += 1
            image_pub.publish(image_message(depth, encoding, seq))
            sent.add(seq)
            t = time.monotonic()
            while answer is None and time.monotonic() - t < 1.0:
                with lock:
                    answer = next((p for p in poses if p.header.stamp.secs - 1000 in sent), None)
                time.sleep(0.02)
        if answer is None:
            print(json.dumps({"encoding": encoding, "error": "no grasp before the timeout"}), flush=True)
            continue
        # The quality and time messages follow the pose: wait for one of each per pose up to this answer.
        with lock:
            want = poses.index(answer) + 1
        settle = time.monotonic() + 5
        while time.monotonic() < settle:
            with lock:
                if len(quality) >= want and len(seconds) >= want:
                    break
            time.sleep(0.01)
        with lock:
            q, s = list(quality), list(seconds)
        p, o = answer.pose.position, answer.pose.orientation
        print(json.dumps({
            "encoding": encoding,
            "stamp": [answer.header.stamp.secs, answer.header.stamp.nsecs],
            "frame_id": answer.header.frame_id,
            "position": [p.x, p.y, p.z],
            "orientation": [o.x, o.y, o.z, o.w],
            "quality": q[-1] if q else None,
            "compute_time": s[-1] if s else None,
        }), flush=True)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
