"""The consultant's session table and the entity bitsets its candidate sets use."""

from __future__ import annotations

import pytest

from fsreg_ros.core.memory import bitset
from fsreg_ros.core.consultant.views import SessionError, ViewTable


def test_sessions_open_use_close_and_refuse_unknown_ids():
    table: ViewTable[str] = ViewTable(capacity=4, timeout=10.0)
    first = table.open("a", now=0.0)
    second = table.open("b", now=0.0)
    assert first != second and len(table) == 2
    assert table.get(first, now=1.0) == "a"
    assert table.close(first, now=2.0) == "a"
    with pytest.raises(SessionError, match="no open session"):
        table.get(first, now=2.0)
    with pytest.raises(SessionError):
        table.close("nonsense", now=2.0)
    assert len(table) == 1


def test_sessions_expire_when_unused_and_the_least_recently_used_is_dropped():
    table: ViewTable[str] = ViewTable(capacity=2, timeout=5.0)
    a = table.open("a", now=0.0)
    b = table.open("b", now=1.0)
    table.get(a, now=2.0)  # a is now the most recently used
    c = table.open("c", now=3.0)  # full: b goes
    with pytest.raises(SessionError):
        table.get(b, now=3.0)
    assert table.get(c, now=3.0) == "c"
    # a was last used at 2.0: expired at 7.5; c (3.0) still open
    assert table.expire(now=7.5) == 1 and len(table) == 1
    with pytest.raises(SessionError, match="expired after 5 s"):
        table.get(a, now=7.5)
    assert table.get(c, now=7.5) == "c"


def test_a_client_over_its_quota_loses_its_own_oldest_session_never_anothers():
    table: ViewTable[str] = ViewTable(capacity=100, timeout=60.0, per_client=3)
    rr = table.open("rr-1", now=0.0, client="rr")
    hog = [table.open(f"hog-{i}", now=float(i), client="hog") for i in range(10)]
    assert table.held("hog") == 3 and table.held("rr") == 1
    assert table.get(rr, now=20.0) == "rr-1"  # untouched by the hog's opens
    assert [table.get(s, now=20.0) for s in hog[-3:]] == ["hog-7", "hog-8", "hog-9"]
    with pytest.raises(SessionError, match="at most 3 per client"):
        table.get(hog[6], now=20.0)
    assert table.dropped == 7


def test_a_full_table_drops_from_the_client_holding_the_most():
    table: ViewTable[str] = ViewTable(capacity=4, timeout=60.0, per_client=3)
    a1 = table.open("a1", 0.0, client="a")
    b = [table.open(f"b{i}", 1.0 + i, client="b") for i in range(3)]
    table.get(b[0], now=5.0)  # b0 is now b's most recently used
    c1 = table.open("c1", 6.0, client="c")  # full: b holds the most, its LRU (b1) goes
    assert len(table) == 4 and table.held("b") == 2
    with pytest.raises(SessionError):
        table.get(b[1], now=6.0)
    assert table.get(a1, now=6.0) == "a1" and table.get(c1, now=6.0) == "c1"
    a2 = table.open("a2", 7.0, client="a")  # b still holds the most (2): its LRU (b2) goes
    with pytest.raises(SessionError):
        table.get(b[2], now=7.0)
    # the opener is (one of) the largest holders: its own LRU goes
    a3 = table.open("a3", 8.0, client="a")
    with pytest.raises(SessionError):
        table.get(a1, now=8.0)
    assert [table.get(s, now=8.0) for s in (a2, a3, b[0], c1)] == ["a2", "a3", "b0", "c1"]


def test_closed_and_expired_sessions_free_their_clients_quota():
    table: ViewTable[str] = ViewTable(capacity=10, timeout=5.0, per_client=2)
    first = table.open("x", 0.0, client="rr")
    table.open("y", 0.0, client="rr")
    table.close(first, 1.0)
    assert table.held("rr") == 1
    table.expire(10.0)
    assert table.held("rr") == 0 and len(table) == 0 and table.dropped == 0


def test_a_restarted_table_never_reuses_ids():
    assert ViewTable().open("x", 0.0) != ViewTable().open("x", 0.0)


def test_bitsets_round_trip_in_entity_order():
    names = [f"e{i}" for i in range(20)]
    bits = bitset.from_indices([3, 0, 17, 8], 20)
    assert bits == (1 << 0) | (1 << 3) | (1 << 8) | (1 << 17)
    assert bitset.indices(bits) == [0, 3, 8, 17]
    assert bitset.names(bits, names) == ["e0", "e3", "e8", "e17"]
    assert bitset.indices(0) == [] and bitset.from_indices([], 0) == 0
    # written by member rank: members 0, 3, 8, 17 -> ranks 0..3; {3, 17} -> ranks 1 and 3
    assert bitset.positions((1 << 3) | (1 << 17) | (1 << 5), bits) == 0b1010
    assert bitset.positions(bits, 0) == 0
