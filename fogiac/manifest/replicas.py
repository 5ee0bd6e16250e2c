"""A node's replicas in the manifest: how many, how a reply names its request, and when the others are asked.

``replicas: N`` runs the node on N hosts of its own; the edge sends each request to every live replica
and hands the robot the first reply to each request (:class:`fogiac.plan.model.Replica`). Which
request a reply answers is ``reply_match``: by default its ``std_msgs/Header`` stamp (ROS practice: a
reply copies its request's header), else a field the node names. The manifest's topics carry no
message types, so a node may state them (``message_types``); a stated type is checked against the
table below at ``validate``, and an out topic without one is accepted with a one-line warning (and a
line in the plan) that its match is unchecked: the edge finds out at the first reply.
"""

from __future__ import annotations

import re
import warnings

from pydantic import Field

from fogiac.manifest.fields import _Model

MAX_REPLICAS = 8
DEFAULT_MATCH = "header.stamp"
_FIELD_PATH = re.compile(r"^[a-z_][a-z0-9_]*(\.[a-z_][a-z0-9_]*){0,7}$")
_TYPE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/(msg/)?[A-Z][A-Za-z0-9_]*$")

# Common ROS message types whose first field is a std_msgs/Header (ROS 1 and ROS 2 spell them alike,
# ROS 2 with "/msg/" in the middle), and those without one: enough to check the usual robot services.
_HEADERED = frozenset({
    "geometry_msgs/PointStamped", "geometry_msgs/PoseArray", "geometry_msgs/PoseStamped",
    "geometry_msgs/PoseWithCovarianceStamped", "geometry_msgs/PolygonStamped", "geometry_msgs/QuaternionStamped",
    "geometry_msgs/TransformStamped", "geometry_msgs/TwistStamped", "geometry_msgs/TwistWithCovarianceStamped",
    "geometry_msgs/Vector3Stamped", "geometry_msgs/WrenchStamped", "geometry_msgs/AccelStamped",
    "geometry_msgs/InertiaStamped",
    "nav_msgs/GridCells", "nav_msgs/OccupancyGrid", "nav_msgs/Odometry", "nav_msgs/Path",
    "sensor_msgs/BatteryState", "sensor_msgs/CameraInfo", "sensor_msgs/CompressedImage", "sensor_msgs/FluidPressure",
    "sensor_msgs/Illuminance", "sensor_msgs/Image", "sensor_msgs/Imu", "sensor_msgs/JointState", "sensor_msgs/Joy",
    "sensor_msgs/LaserScan", "sensor_msgs/MagneticField", "sensor_msgs/MultiDOFJointState",
    "sensor_msgs/MultiEchoLaserScan", "sensor_msgs/NavSatFix", "sensor_msgs/PointCloud", "sensor_msgs/PointCloud2",
    "sensor_msgs/Range", "sensor_msgs/RelativeHumidity", "sensor_msgs/Temperature", "sensor_msgs/TimeReference",
    "stereo_msgs/DisparityImage", "trajectory_msgs/JointTrajectory", "trajectory_msgs/MultiDOFJointTrajectory",
    "visualization_msgs/Marker", "visualization_msgs/ImageMarker", "vision_msgs/Detection2DArray",
    "vision_msgs/Detection3DArray", "vision_msgs/Classification", "moveit_msgs/DisplayTrajectory",
})
_HEADERLESS_PACKAGES = ("std_msgs/",)  # std_msgs/Float64, String, ... (std_msgs/Header itself: see has_header)
_HEADERLESS = frozenset({
    "geometry_msgs/Point", "geometry_msgs/Point32", "geometry_msgs/Pose", "geometry_msgs/Pose2D",
    "geometry_msgs/PoseWithCovariance", "geometry_msgs/Quaternion", "geometry_msgs/Transform", "geometry_msgs/Twist",
    "geometry_msgs/TwistWithCovariance", "geometry_msgs/Vector3", "geometry_msgs/Wrench", "geometry_msgs/Accel",
    "geometry_msgs/Polygon", "geometry_msgs/Inertia", "nav_msgs/MapMetaData", "sensor_msgs/RegionOfInterest",
    "sensor_msgs/ChannelFloat32", "sensor_msgs/PointField", "trajectory_msgs/JointTrajectoryPoint",
})


class MatchUnchecked(UserWarning):
    """A replicated node's out topic with no stated type: its reply match is accepted unchecked."""


class Hedge(_Model):
    """Ask the first replica, and the others only when it has not answered within ``delay_ms``."""

    delay_ms: int = Field(ge=1, le=60_000, description="How long the first replica has before the others are "
                          "asked too, in milliseconds (the 'hedged request': less bandwidth than asking all).")


def canonical_type(name: str) -> str:
    """``sensor_msgs/msg/Image`` (ROS 2) and ``sensor_msgs/Image`` (ROS 1) name the same type."""
    return name.replace("/msg/", "/")


def check_type(name: str) -> str:
    if not _TYPE.match(name):
        raise ValueError(f"{name!r} is not a ROS message type like 'geometry_msgs/PoseArray'")
    return name


def check_match(value: str) -> str:
    if not _FIELD_PATH.match(value):
        raise ValueError(f"{value!r} is not a message field like 'header.stamp' or 'request_id'")
    return value


def has_header(type_name: str) -> bool | None:
    """Whether the type carries a std_msgs/Header: True, False, or None when the table does not know it."""
    name = canonical_type(type_name)
    if name in _HEADERED or name == "std_msgs/Header":
        # a bare Header is laid out as a message that starts with one (seq, stamp, frame_id on ROS 1; stamp,
        # frame_id in CDR), and the edge reads a header's stamp from those leading bytes: it matches the same way
        return True
    if name in _HEADERLESS or name.startswith(_HEADERLESS_PACKAGES):
        return False
    return name.endswith("Stamped") or None  # the ROS convention for "X with a header"


def match_problems(outputs: tuple[str, ...], types: dict[str, str], match: str) -> list[tuple[str, str]]:
    """(problem, field) for each out topic whose stated type cannot carry ``match``."""
    if not match.startswith("header."):
        return []  # a field of the node's own choosing: the types are the node's business
    return [(f"{topic}: {types[topic]} has no std_msgs/Header, so replies cannot be matched by {match}; set "
             "reply_match to a field the reply copies from its request", "reply_match")
            for topic in outputs if topic in types and has_header(types[topic]) is False]


def unchecked(node: str, outputs: tuple[str, ...], types: dict[str, str], match: str) -> str | None:
    """The line saying which of a replicated node's out topics have no stated type (its match unchecked)."""
    untyped = [t for t in outputs if t not in types]
    if not untyped or not match.startswith("header."):
        return None
    return f"{node}: replies on {', '.join(untyped)} are matched by {match}, unchecked (no type in message_types)"


def warn_unchecked(line: str) -> None:
    """Said once the manifest is valid (never beside its errors), as a one-line warning."""
    warnings.warn(MatchUnchecked(line), stacklevel=3)
