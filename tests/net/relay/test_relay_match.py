"""Reply keys read off ROS 1 serialized bytes (fogiac.net.relay.match), against hand-serialized messages."""

from __future__ import annotations

import struct

import pytest

from fogiac.msgtypes import parse_definition
from fogiac.net.relay.errors import RelayError
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


# Issue 35 (3): a replica's message definition is hostile input. Each of these raised RecursionError (ending
# every link), looped up to 2^32 times, or raised an uncaught ValueError; now each is refused in one line, or
# the message has no key, at once.
SELF = "Header header\nNode root\nuint64 id\n=====\nMSG: demo/Node\nNode[] children\n"
DEEP = "Header header\nL0 next\nuint64 id\n" + "".join(
    f"=====\nMSG: demo/L{i}\nL{i + 1} next\n" for i in range(200)) + "=====\nMSG: demo/L200\nuint8 x\n"


@pytest.mark.parametrize("definition, why", [
    (SELF, "contains itself"),
    ("Header header\nA a\nuint64 id\n=====\nMSG: demo/A\nB b\n=====\nMSG: demo/B\nA[2] a\n", "contains itself"),
    (DEEP, "nest deeper than 32"),
    ("Header header\nfloat64[abc] goal\nuint64 id\n", "array size 'abc'"),
    ("Header header\nfloat64[99999999999] goal\nuint64 id\n", "array size '99999999999'"),
    ("Header header\nfloat64[٣] goal\nuint64 id\n", "array size"),
    ("Header header\n[] goal\nuint64 id\n", "no type"),
    ("uint64 id\n" + "#" * (1 << 20), "characters, over"),
], ids=["self", "cycle", "deep", "size", "huge-size", "digit", "no-type", "big"])
def test_a_hostile_definition_is_refused_in_one_line(definition: str, why: str) -> None:
    with pytest.raises(RelayError, match=why) as err:
        key_reader("id", "demo/Plan", definition)
    assert "\n" not in str(err.value)


def test_an_array_count_in_the_data_cannot_make_a_key_read_loop() -> None:
    """A definition may be fine while a message's counts are not: 2^32 - 1 items of an empty type, or of a
    one-byte one, in a message of a few bytes."""
    empty = "Header header\nE[] items\nuint64 id\n=====\nMSG: demo/E\n"
    byte = "Header header\nB[] items\nuint64 id\n=====\nMSG: demo/B\nuint8 x\nstring s\n"
    header = struct.pack("<III", 1, 2, 3) + string("")
    message = header + struct.pack("<I", 0xFFFFFFFF) + struct.pack("<Q", 7)
    assert key_reader("id", "demo/Plan", empty)(message) == struct.pack("<Q", 7)  # empty items take no bytes
    assert key_reader("id", "demo/Plan", byte)(message) is None  # 4 billion items in 8 bytes: too short


def test_types_that_hold_two_of_the_next_are_read_without_walking_every_path() -> None:
    """Thirty levels, each two of the next: 2^30 paths to the innermost type, one fixed size."""
    levels = "".join(f"=====\nMSG: demo/T{i}\nT{i + 1} a\nT{i + 1} b\n" for i in range(30))
    definition = "Header header\nT0 tree\nstring note\nuint64 id\n" + levels + "=====\nMSG: demo/T30\n"
    message = struct.pack("<III", 1, 2, 3) + string("") + string("hi") + struct.pack("<Q", 9)
    assert key_reader("id", "demo/Plan", definition + "uint8 x\n")(message) is None  # the tree is 2^30 bytes
    assert key_reader("id", "demo/Plan", definition)(message) == struct.pack("<Q", 9)  # the tree is empty
