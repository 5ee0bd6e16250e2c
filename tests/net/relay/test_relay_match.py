"""Reply keys read off ROS 1 serialized bytes (fogiac.net.relay.match), against hand-serialized messages."""

from __future__ import annotations

import struct

import pytest

from fogiac.net.relay.errors import RelayError
from fogiac.msgtypes import parse_definition
from fogiac.net.relay.match import key_reader


def string(text: str) -> bytes:
    return struct.pack("<I", len(text)) + text.encode()


HEADER = "uint32 seq\ntime stamp\nstring frame_id\n"
# A request type the way rospy sends its definition: the main type, then each nested type after a rule.
DEFINITION = ("# a planning request\nHeader header\nstring[] names\nfloat64[3] goal\nint32 MAX=7\n"
              "Item[] items\nuint64 id\n"
              "================================================================================\n"
              "MSG: std_msgs/Header\n" + HEADER +
              "================================================================================\n"
              "MSG: demo/Item\nstring label\nuint8[] blob\n")


def request(stamp: tuple[int, int], ident: int, names: list[str]) -> bytes:
    header = struct.pack("<III", 5, *stamp) + string("map")
    body = struct.pack("<I", len(names)) + b"".join(string(n) for n in names)
    body += struct.pack("<3d", 1.0, 2.0, 3.0)
    body += struct.pack("<I", 2) + string("a") + struct.pack("<I", 2) + b"xy" + string("bb") + struct.pack("<I", 0)
    return header + body + struct.pack("<Q", ident)


def test_header_stamp_is_bytes_4_to_12() -> None:
    key = key_reader("header.stamp")
    assert key(request((17, 42), 1, [])) == struct.pack("<II", 17, 42)
    assert key(b"\x00" * 8) is None  # too short to carry a header


def test_a_field_after_strings_and_arrays_is_found_by_walking_the_definition() -> None:
    key = key_reader("id", "demo/Plan", DEFINITION)
    assert key(request((1, 0), 99, ["left", "right"])) == struct.pack("<Q", 99)
    assert key(request((1, 0), 99, [])) == struct.pack("<Q", 99)  # same field, other offsets
    assert key_reader("header.frame_id", "demo/Plan", DEFINITION)(request((1, 0), 3, ["x"])) == string("map")
    assert key(request((1, 0), 99, ["a"])[:-3]) is None  # truncated: no key rather than a wrong one


def test_constants_and_comments_are_not_fields() -> None:
    fields = parse_definition(DEFINITION, "demo/Plan")
    assert [f.name for f in fields["demo/Plan"]] == ["header", "names", "goal", "items", "id"]
    assert fields["demo/Plan"][3].base == "demo/Item"


@pytest.mark.parametrize("match, why", [("nope", "has no field 'nope'"), ("items.label", "is an array"),
                                        ("", "names no field")])
def test_a_key_that_names_no_field_is_an_error(match: str, why: str) -> None:
    with pytest.raises(RelayError, match=why):
        key_reader(match, "demo/Plan", DEFINITION)


def test_a_field_key_needs_the_definition() -> None:
    with pytest.raises(RelayError, match="no message definition"):
        key_reader("id", "demo/Plan", "")
