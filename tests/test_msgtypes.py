"""The one message-type store (fogiac.msgtypes): where a reply's match field is in ROS 1 and CDR bytes.

Offsets are checked against messages serialized by hand, field by field, in each generation's layout.
"""

from __future__ import annotations

import struct

import pytest

from fogiac import msgtypes
from fogiac.msgtypes import CDR, HEADER, ROS1, MatchError, UnknownType


def ros1_string(text: str) -> bytes:
    return struct.pack("<I", len(text)) + text.encode()


def cdr_header(sec: int, nanosec: int, frame: str) -> bytes:
    """Encapsulation (CDR little-endian), int32 sec, uint32 nanosec, string frame_id (length with its NUL)."""
    return b"\x00\x01\x00\x00" + struct.pack("<iI", sec, nanosec) + struct.pack("<I", len(frame) + 1) \
        + frame.encode() + b"\x00"


def test_header_stamp_in_ros1_is_bytes_4_to_12_after_seq() -> None:
    at = ROS1.locate(HEADER, "header.stamp")
    assert (at.offset, at.size, at.base) == (4, 8, "time")
    data = struct.pack("<III", 7, 17, 42) + ros1_string("map")
    assert ROS1.key_reader(HEADER, "header.stamp")(data) == struct.pack("<II", 17, 42)


def test_header_stamp_in_cdr_is_bytes_4_to_12_after_the_encapsulation() -> None:
    at = CDR.locate("sensor_msgs/msg/Image", "header.stamp")
    assert (at.offset, at.size, at.base) == (4, 8, "builtin_interfaces/Time")
    assert CDR.key_reader(HEADER, "header.stamp")(cdr_header(17, 42, "map")) == struct.pack("<iI", 17, 42)
    assert CDR.key_reader(HEADER, "header.stamp")(b"\x00\x01\x00\x00\x01") is None  # too short for a stamp


def test_a_nested_field_has_its_own_offset_and_type() -> None:
    nanosec = CDR.locate("geometry_msgs/msg/PoseStamped", "header.stamp.nanosec")
    assert (nanosec.offset, nanosec.size, nanosec.base) == (8, 4, "uint32")
    assert CDR.key_reader(HEADER, "header.stamp.nanosec")(cdr_header(1, 99, "")) == struct.pack("<I", 99)
    store = ROS1.with_definition("Header header\nPart part\nuint64 id\n"
                                 "================================================================================\n"
                                 "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
                                 "================================================================================\n"
                                 "MSG: demo/Part\nuint16 kind\nfloat64 weight\n", "demo/Grasp")
    weight = store.locate("demo/Grasp", "part.weight")
    assert (weight.offset, weight.size, weight.base) == (None, 8, "float64")  # after a string: data-dependent
    data = struct.pack("<III", 1, 2, 3) + ros1_string("arm") + struct.pack("<Hd", 4, 0.5) + struct.pack("<Q", 9)
    assert store.key_reader("demo/Grasp", "part.weight")(data) == struct.pack("<d", 0.5)
    assert store.key_reader("demo/Grasp", "id")(data) == struct.pack("<Q", 9)


def test_cdr_pads_a_field_to_its_own_size() -> None:
    store = CDR.with_definition("uint8 flag\nfloat64 value\n", "demo/Padded")
    assert store.locate("demo/Padded", "value").offset == 4 + 8  # flag at 0, 7 bytes of padding, then value
    assert ROS1.with_definition("uint8 flag\nfloat64 value\n", "demo/Padded").locate("demo/Padded", "value").offset == 1


def test_a_missing_match_field_is_one_clear_line() -> None:
    with pytest.raises(MatchError) as caught:
        ROS1.locate("std_msgs/Float64", "header.stamp")
    assert str(caught.value) == "std_msgs/Float64 has no std_msgs/Header"
    with pytest.raises(MatchError) as caught:
        CDR.locate("sensor_msgs/msg/Image", "header.seq")  # ROS 2's Header dropped seq
    assert str(caught.value) == "std_msgs/Header has no field 'seq'"
    assert "\n" not in str(caught.value)


def test_what_the_store_does_not_know_is_said_apart_from_what_is_wrong() -> None:
    with pytest.raises(UnknownType):
        ROS1.locate("my_msgs/Grasp", "request_id")
    with pytest.raises(UnknownType):
        ROS1.locate("sensor_msgs/Image", "height")  # known to begin with a Header; the rest is not here
    assert msgtypes.has_header("my_msgs/GraspStamped") is True and msgtypes.has_header("my_msgs/Grasp") is None


def test_the_three_readers_share_the_default_match() -> None:
    from fogiac.manifest.nodes import Node
    from fogiac.net.relay.match import DEFAULT_MATCH as relay_default
    from fogiac.net.zenoh.replicas import SUPPORTED_MATCH

    assert Node.model_fields["reply_match"].default == relay_default == SUPPORTED_MATCH == msgtypes.DEFAULT_MATCH
