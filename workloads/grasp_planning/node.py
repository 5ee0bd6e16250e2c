"""The ROS 1 node: depth image + CameraInfo in, grasp pose, quality and compute time out.

Standard message types only, so nothing needs building on the machine it lands on. The
pose's header is the image's header, unchanged: a client matches answers to requests by
stamp and measures the round trip with it. Topics and parameters: see README.md.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import rospy
import torch
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Float64

from fogiac.errors import WorkloadError
from workloads.grasp_planning.camera import Intrinsics
from workloads.grasp_planning.inputs import depth_from_buffer
from workloads.grasp_planning.planner import MODEL_PATH, Grasp, GraspPlanner


@dataclass(frozen=True)
class Answer:
    pose: PoseStamped
    quality: float
    seconds: float


def intrinsics_from_info(info: CameraInfo) -> Intrinsics:
    k = info.K
    if k[0] <= 0 or k[4] <= 0:
        raise WorkloadError(f"CameraInfo K has no focal length: {list(k)}")
    return Intrinsics(fx=float(k[0]), fy=float(k[4]), cx=float(k[2]), cy=float(k[5]))


def pose_message(image: Image, grasp: Grasp) -> PoseStamped:
    msg = PoseStamped()
    msg.header = image.header
    p, q = grasp.pose.position, grasp.pose.orientation
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = p
    msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w = q
    return msg


class GraspNode:
    """Keeps the latest CameraInfo and answers each depth image with a grasp."""

    def __init__(self, planner: GraspPlanner) -> None:
        self.planner = planner
        self._info: Intrinsics | None = None
        self._lock = threading.Lock()

    def on_info(self, info: CameraInfo) -> None:
        try:
            intr = intrinsics_from_info(info)
        except WorkloadError as err:
            rospy.logerr_throttle(5.0, str(err))
            return
        with self._lock:
            self._info = intr

    def answer(self, image: Image) -> Answer | None:
        with self._lock:
            intr = self._info
        if intr is None:
            rospy.logwarn_throttle(5.0, "grasp_planner: no CameraInfo yet, dropping depth image")
            return None
        start = time.perf_counter()
        depth = depth_from_buffer(
            bytes(image.data), encoding=image.encoding, height=image.height, width=image.width,
            step=image.step, big_endian=bool(image.is_bigendian), source="depth image",
        )
        grasp = self.planner.plan(depth, intr)
        return Answer(pose=pose_message(image, grasp), quality=grasp.quality, seconds=time.perf_counter() - start)


def main() -> None:
    rospy.init_node("grasp_planner")
    threads = int(rospy.get_param("~threads", 0))
    if threads:
        torch.set_num_threads(threads)
    planner = GraspPlanner.load(rospy.get_param("~model", str(MODEL_PATH)), device=rospy.get_param("~device", "auto"))
    node = GraspNode(planner)
    pose_pub = rospy.Publisher("grasp", PoseStamped, queue_size=1)
    quality_pub = rospy.Publisher("grasp/quality", Float64, queue_size=1)
    time_pub = rospy.Publisher("grasp/compute_time", Float64, queue_size=1)

    def on_image(image: Image) -> None:
        try:
            ans = node.answer(image)
        except WorkloadError as err:
            rospy.logerr_throttle(5.0, f"grasp_planner: {err}")
            return
        if ans is not None:
            pose_pub.publish(ans.pose)
            quality_pub.publish(Float64(ans.quality))
            time_pub.publish(Float64(ans.seconds))

    rospy.Subscriber("depth/camera_info", CameraInfo, node.on_info, queue_size=1)
    rospy.Subscriber("depth/image", Image, on_image, queue_size=1, buff_size=1 << 24)
    rospy.loginfo(f"grasp_planner: ready on {planner.device}, model {rospy.get_param('~model', str(MODEL_PATH))}")
    rospy.spin()
