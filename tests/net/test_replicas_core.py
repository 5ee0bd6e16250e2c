"""The first-reply core (fogiac.net.replicas.Merge), driven with explicit times: which replica is asked
when, which reply is published, what is remembered and for how long."""

from __future__ import annotations

import pytest

from fogiac.net.replicas import Merge, host_figures
from fogiac.plan.cost import replica_words


def test_all_asks_every_live_replica_and_publishes_each_key_once_per_topic() -> None:
    m = Merge([(0, "a"), (1, "b")])
    assert m.request("/req", b"k1", "data", [0, 1], now=0.0) == [0, 1]
    assert m.reply("/rep", 1, b"k1", now=0.2) is True
    assert m.reply("/rep", 0, b"k1", now=0.5) is False  # the late copy
    assert m.reply("/other", 0, b"k1", now=0.5) is True  # another out topic delivers its own first reply
    stats = m.stats({0, 1}, now=1.0)
    a, b = stats["replicas"]
    assert (a["won"], a["late"], b["won"], b["late"]) == (1, 1, 1, 0)
    assert b["latency_ms"] == 200.0 and a["latency_ms"] == 500.0 and stats["duplicates_dropped"] == 1


def test_delayed_asks_the_first_then_the_others_only_when_unanswered() -> None:
    m = Merge([(0, "a"), (1, "b")], hedge="delayed", hedge_delay_s=0.1)
    assert m.request("/req", b"k1", "d1", [0, 1], now=0.0) == [0]
    assert m.request("/req", b"k2", "d2", [0, 1], now=0.01) == [0]
    assert m.reply("/rep", 0, b"k1", now=0.05)
    assert m.due(0.05, [0, 1]) == []  # not yet
    assert m.due(0.2, [0, 1]) == [("/req", "d2", [1])]  # k1 was answered in time, k2 not
    assert m.next_due() is None


def test_delayed_prefers_the_fastest_once_all_have_answered_and_avoids_a_silent_one() -> None:
    m = Merge([(0, "a"), (1, "b")], hedge="delayed", hedge_delay_s=0.1, silent_after=1.0)
    for n, (key, first) in enumerate(((b"1", 0), (b"2", 1))):  # b first once it is known fastest
        assert m.request("/q", key, None, [0, 1], now=n) == [first]
        m.due(n + 0.2, [0, 1])  # nobody answered in time: both asked
        m.reply("/r", 1, key, now=n + 0.21)  # b is fast
        m.reply("/r", 0, key, now=n + 0.5)  # a is slow
    assert m.request("/q", b"3", None, [0, 1], now=3.0) == [1]  # b, the fastest, now goes first
    assert m.request("/q", b"4", None, [0, 1], now=3.1) == [1]
    # b stops answering: after silent_after, a goes first again
    assert m.request("/q", b"5", None, [0, 1], now=5.0) == [0]
    assert m.stats({0, 1}, now=5.0)["replicas"][1]["health"] == "silent"
    assert m.stats({0}, now=5.0)["replicas"][1]["health"] == "down"


def test_memory_is_bounded_and_a_forgotten_or_answered_key_is_never_delivered_again() -> None:
    m = Merge([(0, "a")], remember=3)
    for k in (b"1", b"2", b"3", b"4"):
        m.request("/q", k, None, [0], now=0.0)
        assert m.reply("/r", 0, k, now=0.1)
    assert m.reply("/r", 0, b"4", now=0.2) is False  # answered: a second copy answers nothing
    assert m.reply("/r", 0, b"1", now=0.2) is False  # forgotten (the window is the last 3 requests): dropped
    assert m.reply("/r", 0, None, now=0.2) is False and m.unmatched == 1  # every request answered
    assert len(m._requests) == 3 and {k for _, k in m._queues} == {"any", b"2", b"3", b"4"}
    assert m.stats({0}, now=1.0)["replicas"][0]["unsolicited"] == 3


def test_keyless_replies_pass_from_one_replica_only_until_it_falls_silent() -> None:
    m = Merge([(0, "a"), (1, "b")], silent_after=1.0)
    m.request("/q", None, None, [0, 1], now=0.0)
    assert m.reply("/r", 1, None, now=0.1) is True  # b answered first: its keyless replies pass
    assert m.reply("/r", 0, None, now=0.2) is False  # a's can't be told from b's copies
    m.request("/q", None, None, [0, 1], now=0.3)
    assert m.reply("/r", 0, None, now=2.0) is True  # b has not answered for 1.7 s: a takes over
    assert m.reply("/r", 1, None, now=2.1) is False


def test_a_reply_before_its_request_is_dropped_and_the_real_answer_passes() -> None:
    """Issue 35 (2): a replica answering a key the robot has not asked took the key, and the real answer
    to that request was then dropped as a copy."""
    m = Merge([(0, "a"), (1, "b")])
    assert m.reply("/r", 0, b"k1", now=0.0) is False  # nobody asked k1 yet
    m.request("/q", b"k1", None, [0, 1], now=0.1)
    assert m.reply("/r", 1, b"k1", now=0.2) is True  # the real answer
    assert m.reply("/r", 0, b"k1", now=0.3) is False
    a, b = m.stats({0, 1}, now=1.0)["replicas"]
    assert (a["unsolicited"], a["late"], a["won"], b["won"]) == (1, 1, 0, 1)


def test_junk_keys_cannot_push_an_answered_key_out_and_let_its_copy_through() -> None:
    """Issue 35 (2): keys were remembered per topic and evicted after ``remember``: junk keys from one
    replica pushed a delivered key out, and a late copy of it was delivered a second time."""
    m = Merge([(0, "a"), (1, "b")], remember=4)
    m.request("/q", b"real", None, [0, 1], now=0.0)
    assert m.reply("/r", 1, b"real", now=0.1) is True
    for n in range(100):
        assert m.reply("/r", 0, b"junk%d" % n, now=0.2) is False
    assert m.reply("/r", 0, b"real", now=0.3) is False  # the late copy
    assert m.reply("/r", 1, b"real", now=0.3) is False  # and again
    assert m.delivered == 1 and m.stats({0, 1}, now=1.0)["unsolicited"] == 101


def test_a_replica_answers_only_the_requests_sent_to_it() -> None:
    m = Merge([(0, "a"), (1, "b")], hedge="delayed", hedge_delay_s=0.1)
    assert m.request("/q", b"k1", None, [0, 1], now=0.0) == [0]
    assert m.reply("/r", 1, b"k1", now=0.05) is False  # b was not asked (yet)
    assert m.reply("/r", 0, b"k1", now=0.06) is True


def test_keyless_chatter_from_one_replica_does_not_suppress_the_healthy_one() -> None:
    """Issue 35 (2): the keyless slot went to whoever replied first, so one replica's chatter (keyless
    replies nobody asked for) kept the healthy replica's answers from the robot."""
    m = Merge([(0, "a"), (1, "b")])
    for n in range(20):
        assert m.reply("/r", 0, None, now=n * 0.01) is False  # before any request: answers nothing
    delivered = 0
    for n in range(10):
        m.request("/q", b"%d" % n, None, [0, 1], now=1.0 + n)
        delivered += m.reply("/r", 1, None, now=1.0 + n + 0.1)  # the healthy one answers each
        assert m.reply("/r", 0, None, now=1.0 + n + 0.2) is False  # the chatter: its copy, late
        assert m.reply("/r", 0, None, now=1.0 + n + 0.3) is False  # and more: it was asked once
    assert delivered == 10
    a, b = m.stats({0, 1}, now=20.0)["replicas"]
    assert (b["won"], a["won"], a["late"], a["unsolicited"]) == (10, 0, 10, 30)


@pytest.mark.parametrize("key", [b"\0" * 8, b"same"], ids=["zero stamp", "equal stamps"])
def test_requests_with_one_key_are_each_answered_once_never_merged(key: bytes) -> None:
    """Issue 35 (8): five requests with a zero (or one equal) stamp got one answer: their replies were
    taken for copies of the first."""
    m = Merge([(0, "a"), (1, "b")])
    for n in range(5):
        m.request("/q", key, n, [0, 1], now=n)
    published = [m.reply("/r", i, key, now=10 + n) for n in range(5) for i in (1, 0)]
    assert published == [True, False] * 5
    assert m.reply("/r", 0, key, now=20) is False and m.delivered == 5  # a sixth: nothing left to answer


def test_a_keyed_reply_answers_a_request_that_had_no_key() -> None:
    """A request too short for a key (no Header) may still get a keyed reply: it answers the replica's
    oldest request without one, once."""
    m = Merge([(0, "a"), (1, "b")])
    m.request("/q", None, None, [0, 1], now=0.0)
    assert m.reply("/r", 0, b"anything", now=0.1) is True
    assert m.reply("/r", 1, b"other", now=0.2) is False and m.reply("/r", 0, b"more", now=0.3) is False


def test_replicas_are_counted_from_1_wherever_they_are_shown() -> None:
    """Issue 35 (23): status said "0/2", "1/2" and "replica 1 of planner on planner-r2" beside hosts named r1
    and r2 and the plan's "replica 1 of 2"."""
    from fogiac.lifecycle.report import replicas_lines
    from fogiac.plan.model import Replica, Route

    routes = [Route(host=f"planner-r{i + 1}", connect_via="loopback", port=0, auto=False, to_cloud=("/q",),
                    to_edge=("/r",), listed=(), compression=(), queue_size=2,
                    replica=Replica("planner", i, 2, "header.stamp")) for i in range(2)]
    stats = Merge([(0, "planner-r1"), (1, "planner-r2")], silent_after=1.0)
    stats.request("/q", b"k", None, [0, 1], now=0.0)
    stats.reply("/r", 0, b"k", now=0.1)
    figures = host_figures(routes, lambda group: stats.stats({0, 1}, now=5.0))
    assert [figures[h]["number"] for h in ("planner-r1", "planner-r2")] == [1, 2]
    lines = replicas_lines([{"host": h, "replica": f} for h, f in figures.items()])
    assert list(lines[0].columns[1].cells) == ["1/2", "2/2"]
    assert lines[1:] == ["replica 2 of planner on planner-r2 stopped answering (last answer never)"]
    assert replica_words(routes[1].replica) == "replica 2 of 2"
