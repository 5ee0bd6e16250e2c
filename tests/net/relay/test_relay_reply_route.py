"""The fleet's reply routing (``fogiac.net.relay.replyroute``) on real ROS 1 message bytes: equal stamps from two
robots kept apart and given back, other keys answered in arrival order, stray and keyless messages dropped and
counted, and what is remembered bounded (a cap and an age)."""

from __future__ import annotations

from typing import cast

from fogiac.net.relay.fleet import SharedPair
from fogiac.net.relay.match import key_reader
from fogiac.net.relay.node import RelayNode
from fogiac.net.relay.pubsub import TopicMeta
from fogiac.net.relay.replyroute import ReplyRouter
from fogiac.net.relay.shared import SharedTopics

PLAN = SharedPair("planner", frozenset({"/plan/request"}), frozenset({"/plan/reply"}))
STAMP = key_reader("header.stamp")
HEADER_DEF = "uint32 seq\ntime stamp\nstring frame_id\n"
SEQ = key_reader("seq", "std_msgs/Header", HEADER_DEF)


def header(seq: int, secs: int, nsecs: int = 0, frame: str = "") -> bytes:
    """A serialized std_msgs/Header."""
    text = frame.encode()
    return (seq.to_bytes(4, "little") + secs.to_bytes(4, "little") + nsecs.to_bytes(4, "little")
            + len(text).to_bytes(4, "little") + text)


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def router(*pairs: SharedPair, pending: int = 4096, expire_s: float = 60.0, clock: Clock | None = None) -> ReplyRouter:
    routes = ReplyRouter(pending=pending, expire_s=expire_s, clock=clock or Clock())
    routes.configure(pairs or (PLAN,))
    return routes


def test_equal_stamps_from_two_robots_each_get_their_own_reply_in_any_order() -> None:
    routes = router()
    a = routes.request("/plan/request", "arm1", header(1, 1000, frame="a"), STAMP)
    b = routes.request("/plan/request", "arm2", header(2, 1000, frame="b"), STAMP)
    assert a == header(1, 1000, frame="a")  # the first in flight is handed on untouched
    assert b == header(2, 1000, 1, frame="b")  # the second is seen by the node a nanosecond later
    # The node answers copying each request's header, the second first: each goes back to its robot, with the
    # stamp that robot sent.
    assert routes.reply("/plan/reply", header(2, 1000, 1, frame="B"), STAMP) == ("arm2", header(2, 1000, frame="B"))
    assert routes.reply("/plan/reply", header(1, 1000, frame="A"), STAMP) == ("arm1", header(1, 1000, frame="A"))
    assert routes.reply("/plan/reply", header(1, 1000, frame="A"), STAMP) is None  # answered already: nobody
    figures = routes.stats()["planner"]
    assert (figures["forwarded"], figures["answered"], figures["restamped"], figures["unmatched"]) == (2, 2, 1, 1)
    assert figures["pending"] == 0 and figures["served"] == {"arm1": 1, "arm2": 1}


def test_a_moved_stamp_carries_into_the_next_second_and_skips_stamps_in_flight() -> None:
    routes = router()
    routes.request("/plan/request", "arm1", header(0, 7, 999_999_999), STAMP)
    routes.request("/plan/request", "arm2", header(0, 8, 0), STAMP)  # the next nanosecond: in flight already
    moved = routes.request("/plan/request", "arm3", header(0, 7, 999_999_999), STAMP)
    assert moved == header(0, 8, 1)
    assert routes.reply("/plan/reply", header(0, 8, 1), STAMP) == ("arm3", header(0, 7, 999_999_999))
    assert routes.reply("/plan/reply", header(0, 8, 0), STAMP) == ("arm2", header(0, 8, 0))


def test_another_key_queues_equal_keys_in_arrival_order() -> None:
    """``match: seq``: nothing is moved; two robots' requests with one seq are answered oldest first."""
    routes = router(SharedPair("grasp", frozenset({"/g/req"}), frozenset({"/g/rep"}), "seq"))
    assert routes.request("/g/req", "arm1", header(5, 1), SEQ) == header(5, 1)
    assert routes.request("/g/req", "arm2", header(5, 2), SEQ) == header(5, 2)
    assert routes.reply("/g/rep", header(5, 1), SEQ) == ("arm1", header(5, 1))
    assert routes.reply("/g/rep", header(5, 2), SEQ) == ("arm2", header(5, 2))
    assert routes.reply("/g/rep", header(5, 2), SEQ) is None
    assert routes.stats()["grasp"]["queued"] == 1 and routes.stats()["grasp"]["restamped"] == 0


def test_keyless_requests_are_not_sent_and_keyless_or_stray_replies_reach_nobody() -> None:
    routes = router()
    assert routes.request("/plan/request", "arm1", b"\x01\x00", STAMP) is None  # too short for a stamp
    assert routes.reply("/plan/reply", b"\x01\x00", STAMP) is None
    assert routes.reply("/plan/reply", header(0, 99), STAMP) is None  # nobody asked
    assert routes.request("/plan/request", "arm1", header(0, 1), None) is None  # its type has no such field
    figures = routes.stats()["planner"]
    assert (figures["keyless"], figures["unmatched"], figures["forwarded"]) == (2, 2, 0)


def test_topics_outside_the_pairs_and_keyless_pairs_are_not_routed() -> None:
    routes = router(PLAN, SharedPair("map", frozenset({"/map/ask"}), frozenset({"/map/full"}), None))
    data = header(0, 1)
    assert routes.request("/arm1/scan", "arm1", data, STAMP) is data
    assert routes.request("/map/ask", "arm1", data, STAMP) is data  # no key: not remembered
    assert not routes.routes("/map/full") and not routes.routes("/arm1/scan") and routes.routes("/plan/reply")
    assert set(routes.stats()) == {"planner"}


def test_a_node_with_two_reply_topics_answers_each_request_once_on_each() -> None:
    both = SharedPair("planner", frozenset({"/plan/request"}), frozenset({"/plan/path", "/plan/status"}))
    routes = router(both)
    routes.request("/plan/request", "arm1", header(0, 3), STAMP)
    assert routes.reply("/plan/path", header(0, 3), STAMP) == ("arm1", header(0, 3))
    assert routes.reply("/plan/path", header(0, 3), STAMP) is None
    assert routes.reply("/plan/status", header(0, 3), STAMP) == ("arm1", header(0, 3))
    assert routes.stats()["planner"]["pending"] == 0


def test_what_is_remembered_is_capped_per_robot_and_expires() -> None:
    clock = Clock()
    routes = router(pending=3, expire_s=10.0, clock=clock)
    routes.request("/plan/request", "arm2", header(0, 100), STAMP)
    for secs in range(5):  # arm1 floods: only its own oldest are forgotten
        routes.request("/plan/request", "arm1", header(0, secs), STAMP)
    assert routes.stats()["planner"]["pending"] == 4 and routes.stats()["planner"]["forgotten"] == 2
    assert routes.reply("/plan/reply", header(0, 0), STAMP) is None  # forgotten: the oldest went first
    clock.now = 5.0
    routes.request("/plan/request", "arm2", header(0, 200), STAMP)
    clock.now = 12.0  # all but arm2's second are older than 10 s now
    assert routes.reply("/plan/reply", header(0, 4), STAMP) is None
    assert routes.reply("/plan/reply", header(0, 200), STAMP) == ("arm2", header(0, 200))
    figures = routes.stats()["planner"]
    assert (figures["expired"], figures["forgotten"], figures["unmatched"], figures["pending"]) == (4, 2, 2, 0)


def test_a_robot_repeating_one_stamp_gets_a_free_one_each_time() -> None:
    """The search for a free stamp starts after the last one given: a robot stamping every request 0 costs a step
    each, and once its requests are answered its next one is handed on untouched."""
    routes = router()
    seen = [routes.request("/plan/request", "arm1", header(i, 0), STAMP) for i in range(4)]
    assert seen == [header(i, 0, i) for i in range(4)]
    for i in range(4):
        assert routes.reply("/plan/reply", header(i, 0, i), STAMP) == ("arm1", header(i, 0))
    assert routes.request("/plan/request", "arm1", header(9, 0), STAMP) == header(9, 0)


def test_reconfiguring_keeps_an_unchanged_nodes_requests_and_drops_a_removed_one() -> None:
    routes = router()
    routes.request("/plan/request", "arm1", header(0, 1), STAMP)
    routes.configure((PLAN, SharedPair("grasp", frozenset({"/g/req"}), frozenset({"/g/rep"}))))
    assert routes.reply("/plan/reply", header(0, 1), STAMP) == ("arm1", header(0, 1))
    routes.request("/plan/request", "arm1", header(0, 2), STAMP)
    routes.configure(())  # no shared node any more (the file lost them, or one edge): nothing routed
    assert not routes.routes("/plan/reply") and routes.stats() == {}


def test_a_robots_hostile_definition_leaves_its_requests_unsent() -> None:
    """With a key other than the stamp, a request is keyed with the definition the robot's publisher sent: one that
    refers to itself (or is malformed) gives no reader, so its requests are not handed on, and nothing raises."""
    routes = router(SharedPair("grasp", frozenset({"/g/req"}), frozenset({"/g/rep"}), "seq"))
    topics = SharedTopics(cast(RelayNode, None), depth=4, router=routes)  # reader() needs no ROS node
    loop = TopicMeta("pkg/Loop", "*", "pkg/Loop next\n================\nMSG: pkg/Loop\npkg/Loop next\n", False)
    assert topics.reader("/g/req", loop) is None
    good = topics.reader("/g/req", TopicMeta("std_msgs/Header", "*", HEADER_DEF, False))
    assert good is not None and good(header(7, 1)) == (7).to_bytes(4, "little")
    assert routes.request("/g/req", "arm1", header(7, 1), topics.reader("/g/req", loop)) is None
    assert routes.stats()["grasp"]["keyless"] == 1
    assert topics.reader("/arm1/scan", loop) is None  # not a routed topic: never read
