"""The first-reply core (fogiac.net.replicas.Merge), driven with explicit times: which replica is asked
when, which reply is published, what is remembered and for how long."""

from __future__ import annotations

from fogiac.net.replicas import Merge


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


def test_memory_is_bounded_and_a_key_without_bytes_is_passed_unmatched() -> None:
    m = Merge([(0, "a")], remember=3)
    for k in (b"1", b"2", b"3", b"4"):
        m.request("/q", k, None, [0], now=0.0)
        assert m.reply("/r", 0, k, now=0.1)
    assert m.reply("/r", 0, b"4", now=0.2) is False  # remembered
    assert m.reply("/r", 0, b"1", now=0.2) is True  # forgotten: the window is the last 3 keys
    assert m.reply("/r", 0, None, now=0.2) is True and m.unmatched == 1


def test_keyless_replies_pass_from_one_replica_only_until_it_falls_silent() -> None:
    m = Merge([(0, "a"), (1, "b")], silent_after=1.0)
    m.request("/q", None, None, [0, 1], now=0.0)
    assert m.reply("/r", 1, None, now=0.1) is True  # b answered first: its keyless replies pass
    assert m.reply("/r", 0, None, now=0.2) is False  # a's can't be told from b's copies
    m.request("/q", None, None, [0, 1], now=0.3)
    assert m.reply("/r", 0, None, now=2.0) is True  # b has not answered for 1.7 s: a takes over
    assert m.reply("/r", 1, None, now=2.1) is False
