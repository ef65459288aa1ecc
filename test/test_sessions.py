"""The consultant's session table and the entity bitsets its candidate sets use."""

from __future__ import annotations

import pytest

from fsreg_ros.core import bitset
from fsreg_ros.core.sessions import SessionError, SessionTable


def test_sessions_open_use_close_and_refuse_unknown_ids():
    table: SessionTable[str] = SessionTable(capacity=4, timeout=10.0)
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
    table: SessionTable[str] = SessionTable(capacity=2, timeout=5.0)
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


def test_a_restarted_table_never_reuses_ids():
    assert SessionTable().open("x", 0.0) != SessionTable().open("x", 0.0)


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
