"""ROS 1 node around :class:`system.Slam`, on standard messages only (no message build step).

Topics (node name ``slam``, so ``~x`` is ``/slam/x``; TUM's bag names in, remap as usual):

- in  ``/camera/rgb/image_color``  sensor_msgs/Image (bgr8, rgb8 or mono8)
- in  ``/camera/depth/image``      sensor_msgs/Image (16UC1 millimetres or 32FC1 metres; not in mono)
- in  ``/camera/rgb/camera_info``  sensor_msgs/CameraInfo: the intrinsics (frames wait for it)
- out ``~pose``          geometry_msgs/PoseStamped: the camera's pose in the map, with the colour
  image's header stamp (frame_id ``map``); published only for frames that tracked
- out ``~compute_time``  std_msgs/Float64: seconds from the frame's arrival to its pose
- out ``~map_points``    sensor_msgs/PointCloud2 (x, y, z float32): the whole map, after each
  keyframe, at most once per ``~cloud_period`` seconds (default 1)
- out ``~map_created``   std_msgs/Float64, latched, once: seconds from the first frame's arrival to the
  first bundle-adjusted map back in tracking (``run``'s ``map_created_s``, measured in the node)

Params: ``~cores`` (0 or unset: all), ``~mono`` (false), ``~features`` (1000).

Colour and depth are paired on equal stamps (a camera driver stamps both alike). A worker thread
extracts and tracks; pairs arriving while it is busy replace the waiting one (the newest frame
is the one worth tracking), so the node keeps up in real time and drops what it cannot do.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
import rospy
from geometry_msgs.msg import Point, PoseStamped, Quaternion
from geometry_msgs.msg import Pose as PoseMsg
from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField
from std_msgs.msg import Float64, Header

from fogiac.errors import WorkloadError
from workloads.slam.camera import Intrinsics
from workloads.slam.features import Extractor
from workloads.slam.geometry import rot_to_quat
from workloads.slam.system import Slam, pin_cores
from workloads.slam.tracking import Config

NODE_NAME = "slam"
IMAGE, DEPTH, INFO = "/camera/rgb/image_color", "/camera/depth/image", "/camera/rgb/camera_info"


def image_to_grey(msg: Any) -> np.ndarray:
    channels = {"mono8": 1, "bgr8": 3, "rgb8": 3}.get(msg.encoding)
    if channels is None:
        raise WorkloadError(f"image encoding {msg.encoding!r}; valid: mono8, bgr8, rgb8")
    data = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)[:, :msg.width * channels]
    if channels == 1:
        return np.ascontiguousarray(data)
    rgb = data.reshape(msg.height, msg.width, 3).astype(np.float32)
    weights = np.array([0.114, 0.587, 0.299] if msg.encoding == "bgr8" else [0.299, 0.587, 0.114], np.float32)
    return (rgb @ weights).astype(np.uint8)


def depth_to_metres(msg: Any) -> np.ndarray:
    if msg.encoding == "16UC1":
        raw = np.frombuffer(msg.data, ">u2" if msg.is_bigendian else "<u2").reshape(msg.height, msg.step // 2)
        return raw[:, :msg.width].astype(np.float32) / 1000.0
    if msg.encoding == "32FC1":
        raw = np.frombuffer(msg.data, ">f4" if msg.is_bigendian else "<f4").reshape(msg.height, msg.step // 4)
        return np.nan_to_num(raw[:, :msg.width].astype(np.float32), nan=0.0)
    raise WorkloadError(f"depth encoding {msg.encoding!r}; valid: 16UC1 (mm), 32FC1 (m)")


def intrinsics_from(msg: Any) -> Intrinsics:
    k = msg.K
    return Intrinsics(fx=k[0], fy=k[4], cx=k[2], cy=k[5], width=msg.width, height=msg.height)


def pose_to_msg(pose: np.ndarray) -> Any:
    q = rot_to_quat(pose[:3, :3])
    return PoseMsg(Point(*pose[:3, 3]), Quaternion(*q))


def cloud_msg(points: np.ndarray, header: Any) -> Any:
    fields = [PointField(name, 4 * i, PointField.FLOAT32, 1) for i, name in enumerate("xyz")]
    data = points.astype(np.float32).tobytes()
    return PointCloud2(header=header, height=1, width=len(points), fields=fields, is_bigendian=False,
                       point_step=12, row_step=12 * len(points), data=data, is_dense=True)


class SlamNode:
    def __init__(self, *, mono: bool, features: int, cloud_period: float) -> None:
        self.mono, self.features, self.cloud_period = mono, features, cloud_period
        self.slam: Slam | None = None
        self.extractor: Extractor | None = None
        self._images: dict[int, Any] = {}
        self._depths: dict[int, Any] = {}
        self._waiting: tuple[Any, Any, float] | None = None
        self._cond = threading.Condition()
        self._last_cloud = 0.0
        self._frames = 0
        self._first_arrival: float | None = None
        self._map_told = False
        self.pose_pub = rospy.Publisher("~pose", PoseStamped, queue_size=10)
        self.time_pub = rospy.Publisher("~compute_time", Float64, queue_size=10)
        self.cloud_pub = rospy.Publisher("~map_points", PointCloud2, queue_size=1, latch=True)
        self.map_created_pub = rospy.Publisher("~map_created", Float64, queue_size=1, latch=True)

    def on_info(self, msg: Any) -> None:
        if self.slam is None:
            k = intrinsics_from(msg)
            self.extractor = Extractor(k, features=self.features)
            self.slam = Slam(k, Config(features=self.features), mono=self.mono)
            rospy.loginfo(f"slam: camera {k.width}x{k.height} fx {k.fx:.1f}; {'mono' if self.mono else 'rgbd'}")

    def on_image(self, msg: Any) -> None:
        self._pair(msg.header.stamp.to_nsec(), image=msg)

    def on_depth(self, msg: Any) -> None:
        self._pair(msg.header.stamp.to_nsec(), depth=msg)

    def _pair(self, stamp: int, *, image: Any = None, depth: Any = None) -> None:
        arrived = time.monotonic()
        with self._cond:
            if image is not None:
                self._images[stamp] = image
            if depth is not None:
                self._depths[stamp] = depth
            if stamp in self._images and (self.mono or stamp in self._depths):
                self._waiting = (self._images.pop(stamp), self._depths.pop(stamp, None), arrived)
                for older in [s for s in (*self._images, *self._depths) if s < stamp]:
                    self._images.pop(older, None)
                    self._depths.pop(older, None)
                self._cond.notify()

    def work(self) -> None:
        while not rospy.is_shutdown():
            with self._cond:
                self._cond.wait_for(lambda: self._waiting is not None or rospy.is_shutdown(), timeout=0.5)
                pair, self._waiting = self._waiting, None
            if pair is None or self.slam is None or self.extractor is None:
                continue
            try:
                self._track(*pair)
            except Exception as err:  # a robot waits for poses: log the bug, keep serving
                rospy.logerr(f"slam: {type(err).__name__}: {err}")

    def _track(self, image: Any, depth: Any, arrived: float) -> None:
        assert self.slam is not None and self.extractor is not None
        grey = image_to_grey(image)
        metres = None if depth is None else depth_to_metres(depth)
        features = self.extractor(self._frames, image.header.stamp.to_sec(), grey, metres)
        self._frames += 1
        if self._first_arrival is None:
            self._first_arrival = arrived
        result = self.slam.track(features)
        seconds = time.monotonic() - arrived
        self.time_pub.publish(Float64(seconds))
        first_map = self.slam.stats.first_map_at
        if first_map is not None and not self._map_told:
            self._map_told = True
            self.map_created_pub.publish(Float64(first_map - self._first_arrival))
        if result.tracked and result.pose is not None:
            header = Header(stamp=image.header.stamp, frame_id="map")
            self.pose_pub.publish(PoseStamped(header=header, pose=pose_to_msg(result.pose)))
        if result.keyframe and time.monotonic() - self._last_cloud >= self.cloud_period:
            self._last_cloud = time.monotonic()
            self.cloud_pub.publish(cloud_msg(self.slam.tracker.map_points(), Header(stamp=image.header.stamp,
                                                                                      frame_id="map")))

    def close(self) -> None:
        if self.slam is not None:
            self.slam.close()


def main() -> None:
    rospy.init_node(NODE_NAME)
    cores = pin_cores(int(rospy.get_param("~cores", 0)))
    node = SlamNode(mono=bool(rospy.get_param("~mono", False)), features=int(rospy.get_param("~features", 1000)),
                    cloud_period=float(rospy.get_param("~cloud_period", 1.0)))
    rospy.on_shutdown(node.close)
    rospy.Subscriber(INFO, CameraInfo, node.on_info, queue_size=1)
    rospy.Subscriber(IMAGE, Image, node.on_image, queue_size=2, buff_size=2**24)
    if not node.mono:
        rospy.Subscriber(DEPTH, Image, node.on_depth, queue_size=2, buff_size=2**24)
    rospy.loginfo(f"slam: ready on {cores} cores, waiting for {INFO}")
    node.work()
