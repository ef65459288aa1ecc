"""The core's fast paths equal their plain definitions.

* ``simulation.dumps`` writes exactly ``json.dumps(sort_keys=True, indent=2, ensure_ascii=False)``;
* a :class:`Consultant` built from facts (checked by set operations, holders packed from
  (property, entity) pairs) holds and refuses exactly what a fact-by-fact build would;
* ``bitset.rows_from_pairs`` equals one ``from_indices`` per row, in one block or many.
"""

from __future__ import annotations

import json
import os
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fsreg_ros.core.memory import bitset
from fsreg_ros.core.consultant.consultant import Consultant, KnowledgeError, check_certainty
from fsreg_ros.core.simulation.simulator import dumps

# ------------------------------------------------------------------ dumps
LEAVES = st.none() | st.booleans() | st.integers() | st.floats() | st.text()
TREES = st.recursive(
    LEAVES, lambda inner: st.lists(inner) | st.tuples(inner, inner) | st.dictionaries(st.text(), inner), max_leaves=40
)


@settings(max_examples=400, deadline=None)
@given(TREES)
def test_dumps_is_the_standard_librarys_indented_sorted_text(value):
    assert dumps(value) == json.dumps(value, sort_keys=True, indent=2, ensure_ascii=False) + "\n"


@pytest.mark.parametrize("value", [
    {"turns": [{"candidates": ["e1", "é2", "a\"b\\c\n"], "x": [1, 2.5, None, True]}]},
    {"a": [float("nan"), float("inf"), -float("inf"), -0.0, 10**30, 1e-300]},
    {"empty": [], "nested": {}, "tuple": ("a", 1), "mixed": ["a", {"b": ["c"]}, ["d", "e"]]},
    {1: "int key", 2: None},  # not string keys: the standard library writes them
    {"sub": type("S", (str,), {})("subclass")},  # a str subclass, likewise
])
def test_dumps_of_edge_values(value):
    assert dumps(value) == json.dumps(value, sort_keys=True, indent=2, ensure_ascii=False) + "\n"


@pytest.mark.parametrize("value", [{"a": {1, 2}}, {1: "a", "b": 2}])
def test_dumps_refuses_what_json_refuses(value):
    with pytest.raises(TypeError):
        dumps(value)


# --------------------------------------------------------------- consultant
PROPS = ["p0", "p1", "p2", "p3"]
CERTAINTIES = (
    st.sampled_from([1.0, 0.5, 0.0, -0.0, 0.25, 0.75, 1, 0, True, False, float("nan"), float("inf"), 1.5, -0.1, 2])
    | st.floats(0.0, 1.0)
)
FACTS = st.dictionaries(st.sampled_from(PROPS + ["unknown"]), CERTAINTIES, max_size=5)


def reference_build(entities: dict, threshold: float) -> tuple:
    """The consultant's LTM as a fact-by-fact build defines it: (certainties, holders) or the error's text."""
    certainty = {}
    for entity, facts in entities.items():
        for prop, c in facts.items():
            if prop not in PROPS:
                return (f"domain 'd', entity '{entity}': unknown property '{prop}' "
                        "(not in the domain's preference order)")
            try:
                check_certainty(f"certainty of '{prop}' for '{entity}'", c)
            except KnowledgeError as err:
                return str(err)
        certainty[entity] = {p: float(c) for p, c in facts.items() if c > 0}
    names = list(entities)
    holders = {}
    for prop in PROPS:
        held = [i for i, e in enumerate(names) if threshold <= 0.0 or certainty[e].get(prop, 0.0) >= threshold]
        holders[prop] = sum(1 << i for i in held)
    return certainty, holders


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(st.sampled_from([f"e{i}" for i in range(12)]), FACTS, max_size=12),
       st.sampled_from([0.5, 0.0, 1.0, 0.3]))
def test_consultant_build_equals_fact_by_fact(entities, threshold):
    expected = reference_build(entities, threshold)
    if isinstance(expected, str):
        with pytest.raises(KnowledgeError) as err:
            Consultant("d", entities, PROPS, threshold)
        assert str(err.value) == expected
        return
    consultant = Consultant("d", entities, PROPS, threshold)
    certainty, holders = expected
    assert consultant.entities == list(entities)
    assert consultant._certainty == certainty
    for entity, facts in certainty.items():  # floats, not ints or bools
        assert all(type(c) is float for c in facts.values()), entity
    assert consultant._holders == holders
    for prop in PROPS:
        assert consultant.holders(prop) == {e for i, e in enumerate(entities) if holders[prop] >> i & 1}
    assert consultant.members(consultant.open_set()) == list(entities)


def test_consultant_build_keeps_its_own_copy_of_the_facts():
    facts = {"e1": {"p0": 1.0, "p1": 0.0}, "e2": {"p1": 1.0}}
    consultant = Consultant("d", facts, PROPS)
    consultant.assert_facts("e1", {"p0": 0.0}, 0.0)
    assert facts["e1"] == {"p0": 1.0, "p1": 0.0}  # the caller's mapping is not changed
    assert consultant.holders("p0") == set() and consultant.holders("p1") == {"e2"}


def test_names_follow_entities_appended_later():
    consultant = Consultant("d", {"e1": {"p0": 1.0}}, PROPS)
    assert consultant.members(consultant.open_set()) == ["e1"]
    consultant.assert_facts("e2", {"p0": 1.0}, 0.0)
    assert consultant.members(consultant.open_set()) == ["e1", "e2"]
    assert consultant.holders("p0") == {"e1", "e2"}


# ------------------------------------------------------------------ bitsets
@settings(max_examples=200, deadline=None)
@given(st.integers(1, 70), st.integers(1, 9), st.data())
def test_rows_from_pairs_equals_one_bitset_per_row(size, nrows, data):
    pairs = data.draw(st.lists(st.tuples(st.integers(0, nrows - 1), st.integers(0, size - 1)), max_size=200))
    rows = np.array([r for r, _ in pairs], dtype=np.intp)
    columns = np.array([c for _, c in pairs], dtype=np.intp)
    expected = [bitset.from_indices([c for r, c in pairs if r == k], size) for k in range(nrows)]
    assert bitset.rows_from_pairs(rows, columns, nrows, size) == expected


def test_rows_from_pairs_in_many_blocks(monkeypatch):
    monkeypatch.setattr(bitset, "BLOCK_BYTES", 16)  # 16 flags per block: one row per block at size 10
    rows = np.array([2, 0, 1, 2, 0], dtype=np.intp)
    columns = np.array([9, 0, 3, 1, 5], dtype=np.intp)
    assert bitset.rows_from_pairs(rows, columns, 3, 10) == [0b100001, 0b1000, 0b1000000010]


# ------------------------------------------------ column queues, eagerly trimmed
WM_ENTITIES = [f"e{i}" for i in range(8)]
WM_PROPS = ["a", "b", "c", "d", "e"]
WM_OPS = st.lists(
    st.one_of(
        st.tuples(st.just("members"), st.sets(st.integers(0, 7), min_size=1), st.sampled_from(WM_PROPS)),
        st.tuples(st.just("members"), st.sets(st.integers(0, 7), min_size=1), st.sampled_from(WM_PROPS)),
        st.tuples(st.just("encode"), st.integers(0, 7), st.lists(st.sampled_from(WM_PROPS), min_size=1, max_size=3)),
        st.tuples(st.just("decay_now"), st.integers(1, 4)),
        st.tuples(st.just("decay_now"), st.integers(1, 4)),
        st.tuples(st.just("lazy"), st.integers(1, 2)),
        st.tuples(st.just("evict"), st.integers(0, 12)),
        st.tuples(st.just("clear")),
        st.tuples(st.just("limits"), st.sampled_from([None, 1, 2, 3])),
        st.tuples(st.just("remove"), st.integers(0, 7), st.sampled_from(WM_PROPS)),
        st.tuples(st.just("take")),
    ),
    max_size=40,
)


def _limits(capacity):
    from fsreg_ros.core.memory import Limits

    return Limits(retains=False) if capacity is None else Limits(capacity=capacity)


def _state(b) -> tuple:
    """What two buffers that did the same must hold alike: queues, origins, size (also read at once)."""
    together = {e: b.queue_with_origins(e) for e in WM_ENTITIES}
    queues, origins = {e: list(b.queue(e)) for e in WM_ENTITIES}, {e: b.origins(e) for e in WM_ENTITIES}
    assert together == {e: (tuple(queues[e]), origins[e]) for e in WM_ENTITIES}
    return queues, origins, len(b)


def _state_with_exports(b) -> tuple:
    """:func:`_state`, each queue as persistence exports it (activation's traces included), strengths, own clocks."""
    return (*_state(b)[:2], {e: b.export_queue(e) for e in WM_ENTITIES}, len(b),
            {e: b.strength(e) for e in WM_ENTITIES}, b.export_episodes())


def _agree(op, buffers, heard_events, plain_events, seen: int, trimmed: bool, state) -> tuple[int, bool]:
    """Check that ``op`` did the same in every buffer; return (events seen, queues trimmed since the last take).

    ``take`` compares the change records (as sets once new limits trimmed queues, which they do in
    no specified order); the events since ``seen`` must be equal (as multisets after new limits);
    ``state(b)`` must be equal for every buffer.
    """
    kind = op[0]
    if kind == "take":
        changes = [b.take_changes() for b in buffers]
        if trimmed:
            assert all(set(c) == set(changes[0]) for c in changes), (op, changes)
        else:
            assert all(c == changes[0] for c in changes), (op, changes)
        trimmed = False
    if kind == "limits":
        assert Counter(heard_events[seen:]) == Counter(plain_events[seen:])
        trimmed = True
    else:
        assert heard_events[seen:] == plain_events[seen:], op
    seen = len(plain_events)
    assert len(heard_events) == seen
    states = [state(b) for b in buffers]
    assert all(x == states[0] for x in states), op
    return seen, trimmed


@settings(max_examples=int(os.environ.get("FSREG_HYPOTHESIS_EXAMPLES", "300")), deadline=None)
@given(st.integers(1, 3), WM_OPS)
def test_column_queues_decay_evict_and_clear_as_dict_queues(capacity, ops):
    """Eager decay, a shared pool's eviction, clearing and new limits on column queues are the dict queues' own.

    ``plain`` keeps dict queues; ``heard`` has column queues; both have an event sink except
    while encoding members (as a consultant nobody listens to), so ``heard``'s pops are
    reported from the columns; ``quiet`` and ``other`` have column queues and no sink, ``quiet`` decaying in
    its column rows' own entity list (the fast path), ``other`` in an equal copy.  Events
    (in order), queues, origins, sizes and the change record (in order) must be equal.
    """
    from fsreg_ros.core.memory.ticks import TickRun
    from fsreg_ros.core.memory import WMBuffer

    heard_events: list = []
    plain_events: list = []
    plain = WMBuffer("d", plain_events.append)
    plain.column_min = 10**9
    heard, quiet, other = WMBuffer("d", heard_events.append), WMBuffer("d"), WMBuffer("d")
    buffers = (plain, heard, quiet, other)
    for b in buffers[1:]:
        b.column_min = 1
    for b in buffers:
        b.set_limits(_limits(capacity), 0.0)
    ticks = seen = 0
    trimmed = False
    for t, op in enumerate(ops, start=1):
        kind = op[0]
        if kind == "members":
            members = bitset.from_indices(sorted(op[1]), len(WM_ENTITIES))
            heard.sink = plain.sink = None  # nobody listens to these encodings
            for b in buffers:
                b.encode_members(members, WM_ENTITIES, op[2], "reg-distractor", float(t), t)
            heard.sink, plain.sink = heard_events.append, plain_events.append
        elif kind == "encode":
            for b in buffers:
                b.encode(WM_ENTITIES[op[1]], op[2], "speaker", float(t), t)
        elif kind in ("decay_now", "lazy"):
            run = TickRun(0.0, 0.5, ticks + 1, op[1])
            ticks += op[1]
            for b in buffers:
                if kind == "lazy":
                    b.decay(run)
                else:
                    b.decay_now(run, list(WM_ENTITIES) if b is other else WM_ENTITIES)
        elif kind == "evict":
            for b in buffers:
                b.evict_oldest(op[1], "shared-capacity", float(t))
        elif kind == "clear":
            for b in buffers:
                b.clear("reset", float(t), t)
        elif kind == "limits":
            for b in buffers:
                b.set_limits(_limits(op[1]), float(t))
        elif kind == "remove":
            for b in buffers:
                b.remove(WM_ENTITIES[op[1]], op[2], "retract", float(t))
        seen, trimmed = _agree(op, buffers, heard_events, plain_events, seen, trimmed, _state)
    changes = [b.take_changes() for b in buffers]
    assert all(set(c) == set(changes[0]) for c in changes)


# ------------------------------------------- column queues under rule activation
ACT_OPS = st.lists(
    st.one_of(
        st.tuples(st.just("members"), st.sets(st.integers(0, 7), min_size=1), st.sampled_from(WM_PROPS)),
        st.tuples(st.just("members"), st.sets(st.integers(0, 7), min_size=1), st.sampled_from(WM_PROPS[:2])),
        # the same members encoded again and again (traces longer than HISTORY), then the clock runs on
        st.tuples(st.just("burst"), st.sets(st.integers(0, 7), min_size=1), st.sampled_from(WM_PROPS[:2]),
                  st.integers(2, 12), st.floats(0.0, 3.0), st.floats(0.0, 40.0)),
        st.tuples(st.just("encode"), st.integers(0, 7), st.lists(st.sampled_from(WM_PROPS), min_size=1, max_size=3)),
        # members encoded at a time the clock already passed (a late message): due at once, maybe
        st.tuples(st.just("stale"), st.sets(st.integers(0, 7), min_size=1), st.sampled_from(WM_PROPS[:2]),
                  st.sampled_from([0.5, 3.0, 30.0])),
        st.tuples(st.just("wait"), st.sampled_from([0.0, 0.25, 1.0, 2.5, 6.0, 20.0])),
        st.tuples(st.just("wait"), st.floats(0.0, 12.0)),
        st.tuples(st.just("creep"), st.integers(5, 60)),  # the clock in small steps, WM read at each
        # the clock to just before, at or just after one of the next crossings (as plain solves them)
        st.tuples(st.just("cross"), st.integers(0, 3), st.sampled_from([-1e-8, -2e-9, 0.0, 1e-8])),
        st.tuples(st.just("cross"), st.integers(0, 3), st.sampled_from([-1e-8, -2e-9, 0.0, 1e-8])),
        st.tuples(st.just("lazy"), st.integers(1, 2)),
        st.tuples(st.just("evict"), st.integers(0, 12)),
        st.tuples(st.just("clear")),
        st.tuples(st.just("limits"), st.sampled_from([1, 2, 3, None]),
                  st.sampled_from([None, (0.5, -0.9), (0.3, -0.4)])),
        st.tuples(st.just("remove"), st.integers(0, 7), st.sampled_from(WM_PROPS)),
        st.tuples(st.just("take")),
        st.tuples(st.just("restart")),  # each buffer restored from its own export (the column form's included)
    ),
    max_size=50,
)


@settings(max_examples=int(os.environ.get("FSREG_HYPOTHESIS_EXAMPLES", "300")), deadline=None)
@given(st.sampled_from([1, 2, 3, None, None]), st.sampled_from([(0.5, -0.9), (0.3, -0.4), (0.8, -1.3), (0.5, 0.2)]),
       st.sampled_from([(1, 64), (2, 64), (4, 64), (1, 2)]), st.booleans(), st.sampled_from([None, 0, 40]), ACT_OPS)
def test_column_queues_under_activation_as_dict_queues(capacity, params, widths, in_numpy, map_max, ops):
    """Rule ``activation`` on column queues (traces in slots, crossings decided in numpy) is the dict queues' own.

    With a capacity (the rows' width) and without one (rows that widen as queues grow,
    from ``widths[0]`` slots up to ``widths[1]``, then queue by queue).  ``in_numpy``:
    every slot whose bound passed is decided by :func:`crossings.passages`, however few
    (otherwise up to ``_FEW`` go one by one, as here they mostly would).  ``map_max``: the
    bytes rows that widen may give their slot map (None: the default; 0: no map; 40: a map
    dropped once a fifth property comes).

    As :func:`test_column_queues_decay_evict_and_clear_as_dict_queues`: ``plain`` keeps
    dict queues, ``heard`` column queues with an event sink except while encoding members,
    ``quiet`` column queues and no sink.  Encodings often refresh (traces beyond
    ``HISTORY`` too) and the clock jumps past lifetimes, so entries go at crossings solved
    for many slots at once.  Events (in order), queues, origins, exported items with
    their traces, sizes and the change record (in order) must be equal.
    """
    from fsreg_ros.core.memory import Limits, WMBuffer, crossings
    from fsreg_ros.core.memory import columns as column_queues

    heard_events: list = []
    plain_events: list = []
    plain = WMBuffer("d", plain_events.append)
    plain.column_min = 10**9
    heard, quiet = WMBuffer("d", heard_events.append), WMBuffer("d")
    buffers = (plain, heard, quiet)
    for b in buffers[1:]:
        b.column_min = 1
    for b in buffers:
        b.set_limits(Limits(capacity=capacity, activation=params), 0.0)
    kept = column_queues._FIRST_WIDTH, column_queues.COLUMN_MAX_WIDTH, crossings.FEW, column_queues.SLOT_MAP_MAX
    column_queues._FIRST_WIDTH, column_queues.COLUMN_MAX_WIDTH = widths
    if in_numpy:
        crossings.FEW = 0
    if map_max is not None:
        column_queues.SLOT_MAP_MAX = map_max
    try:
        _activation_ops(ops, plain, heard, quiet, plain_events, heard_events)
    finally:
        (column_queues._FIRST_WIDTH, column_queues.COLUMN_MAX_WIDTH, crossings.FEW,
         column_queues.SLOT_MAP_MAX) = kept


@settings(max_examples=int(os.environ.get("FSREG_HYPOTHESIS_EXAMPLES", "300")), deadline=None)
@given(st.sampled_from([1, 2, 3, None, None]),
       st.sampled_from([(0.5, -0.9), (0.3, -0.4), (0.8, -1.3), (0.5, 0.2), (0.5, -0.6), (0.5, 0.0)]),
       st.sampled_from([(1, 64), (2, 64), (4, 64), (1, 2)]), st.booleans(), ACT_OPS)
def test_column_queues_on_the_words_clock_as_dict_queues(capacity, params, widths, in_numpy, ops):
    """Rule ``activation`` on the words clock: column queues (each row on its entity's clock) are the dict queues' own.

    As :func:`test_column_queues_under_activation_as_dict_queues`, every limits on the
    words clock: WM contents, events, exported traces, strengths and the entities' clocks
    (:meth:`WMBuffer.export_episodes`) equal, a restart from each buffer's own export
    included.  Lifetimes from under one word (tau 0.2: an entry goes at its entity's next
    encoding) to several.
    """
    from fsreg_ros.core.memory import Limits, WMBuffer, crossings
    from fsreg_ros.core.memory import columns as column_queues

    heard_events: list = []
    plain_events: list = []
    plain = WMBuffer("d", plain_events.append)
    plain.column_min = 10**9
    heard, quiet = WMBuffer("d", heard_events.append), WMBuffer("d")
    for b in (heard, quiet):
        b.column_min = 1
    for b in (plain, heard, quiet):
        b.set_limits(Limits(capacity=capacity, activation=params, activation_clock="words"), 0.0)
    kept = column_queues._FIRST_WIDTH, column_queues.COLUMN_MAX_WIDTH, crossings.FEW
    column_queues._FIRST_WIDTH, column_queues.COLUMN_MAX_WIDTH = widths
    if in_numpy:
        crossings.FEW = 0
    try:
        in_rows = _activation_ops(ops, plain, heard, quiet, plain_events, heard_events, "words")
    finally:
        column_queues._FIRST_WIDTH, column_queues.COLUMN_MAX_WIDTH, crossings.FEW = kept
    if ops and ops[0][0] in ("members", "burst") and (capacity or 0) <= widths[1]:
        assert in_rows[0]  # the quiet buffer's queues went to the column form


def _activation_ops(ops, plain, heard, quiet, plain_events, heard_events, clock="seconds"):
    """Run ``ops`` on the three buffers of :func:`test_column_queues_under_activation_as_dict_queues`, comparing.

    ``clock``: the activation clock of every limits set.  Returns, per op, whether ``quiet``
    held column queues after it.
    """
    from fsreg_ros.core.memory.ticks import TickRun
    from fsreg_ros.core.memory import Limits, trace as trace_math

    buffers = (plain, heard, quiet)
    ticks = seen = 0
    now = 0.0
    trimmed = False
    in_rows = []
    for op in ops:
        kind = op[0]
        if kind == "members":
            members = bitset.from_indices(sorted(op[1]), len(WM_ENTITIES))
            heard.sink = plain.sink = None  # nobody listens to these encodings
            for b in buffers:
                b.encode_members(members, WM_ENTITIES, op[2], "reg-distractor", now, 1)
            heard.sink, plain.sink = heard_events.append, plain_events.append
        elif kind == "burst":
            members = bitset.from_indices(sorted(op[1]), len(WM_ENTITIES))
            heard.sink = plain.sink = None
            for _ in range(op[3]):
                for b in buffers:
                    b.encode_members(members, WM_ENTITIES, op[2], "reg-distractor", now, 1)
                now += op[4]
            heard.sink, plain.sink = heard_events.append, plain_events.append
            now += op[5]
            for b in buffers:
                b.advance(now)
        elif kind == "encode":
            for b in buffers:
                b.encode(WM_ENTITIES[op[1]], op[2], "speaker", now, 2)
        elif kind == "stale":
            members = bitset.from_indices(sorted(op[1]), len(WM_ENTITIES))
            heard.sink = plain.sink = None
            for b in buffers:
                b.encode_members(members, WM_ENTITIES, op[2], "reg-distractor", now - op[3], 1)
            heard.sink, plain.sink = heard_events.append, plain_events.append
        elif kind == "wait":
            now += op[1]
            for b in buffers:
                b.advance(now)
        elif kind == "creep":
            for _ in range(op[1]):
                now += 0.1
                for b in buffers:
                    b.advance(now)
                assert len({tuple(tuple(b.queue(e)) for e in WM_ENTITIES) for b in buffers}) == 1, (op, now)
        elif kind == "cross":
            act = plain.activation
            upcoming = [] if act is None else sorted(
                c for entity, traces in act.traces.items() for prop, trace in traces.items()
                if prop in (plain.store.get(entity) or ())
                for c in [trace_math.crossing(trace, act.decay, act.threshold)] if now < c < 1e6)
            if len(upcoming) > op[1]:
                now = max(now, upcoming[op[1]] + op[2])
                for b in buffers:
                    b.advance(now)
        elif kind == "lazy":
            run = TickRun(now, 0.5, ticks + 1, op[1])
            ticks += op[1]
            for b in buffers:
                b.decay(run)
        elif kind == "evict":
            for b in buffers:
                b.evict_oldest(op[1], "shared-capacity", now)
        elif kind == "clear":
            for b in buffers:
                b.clear("reset", now, 3)
        elif kind == "limits":
            for b in buffers:
                b.set_limits(Limits(capacity=op[1], activation=op[2], activation_clock=clock), now)
        elif kind == "remove":
            for b in buffers:
                b.remove(WM_ENTITIES[op[1]], op[2], "retract", now)
        elif kind == "restart":
            for b in buffers:
                queues, clocks = {e: b.export_queue(e) for e in WM_ENTITIES}, b.export_episodes()
                b.restore(queues, *b.counters(), b.limits)
                b.restore_episodes(clocks)
        seen, trimmed = _agree(op, buffers, heard_events, plain_events, seen, trimmed, _state_with_exports)
        assert heard_events[seen:] == plain_events[seen:], op  # what the reads caught up
        for b in buffers[1:]:  # slots past those ever used are empty in every row, and never due
            store = b.columns.store
            if store is not None:
                assert (store.prop[store.used:] < 0).all() and store.used <= store.width, op
                if store.traces is not None:
                    assert (store.traces.due[store.used:] == trace_math.NEVER).all(), op
                    # each row's bound is at most its slots' earliest due: a read checks it alone
                    assert (store.traces.row_due <= store.traces.due.min(axis=0)).all(), op
                if store.slot_of is not None:  # the slot map says where each row holds each property
                    truth = np.full(store.slot_of.shape, -1, dtype=np.int8)
                    for k in range(store.used):
                        held = np.flatnonzero(store.prop[k] >= 0)
                        truth[store.prop[k, held], held] = k
                    assert (store.slot_of == truth).all(), op
        seen = len(plain_events)
        in_rows.append(bool(quiet.columns.entities))
    changes = [b.take_changes() for b in buffers]
    assert all(set(c) == set(changes[0]) for c in changes)
    return in_rows


@settings(max_examples=int(os.environ.get("FSREG_HYPOTHESIS_EXAMPLES", "300")), deadline=None)
@given(st.sampled_from([(0.5, -0.9), (0.3, -0.4), (0.8, -1.3), (0.5, 0.2), (0.5, -0.5 * np.log(10.0))]),
       # (gaps of 0, subnormal ones, tiny ones: the older presentations may span almost nothing)
       st.lists(st.lists(st.just(0.0) | st.floats(5e-324, 1e-300) | st.floats(1e-12, 1e-6) | st.floats(1e-6, 30.0),
                         min_size=1, max_size=25), min_size=1, max_size=12),
       st.sampled_from([-1e-3, -1e-8, -2e-9, -1e-12, 0.0, 1e-12, 2e-9, 1e-8, 1e-3, 1.0]))
def test_passages_in_numpy_decide_as_crossing(params, gaps, offset):
    """:func:`crossings.passages` (numpy, many traces at once) decides as :func:`trace.crossing`.

    Each trace is kept in a slot of :class:`trace_columns.TraceColumns` by encodings (the
    Petrov approximation past ``HISTORY`` encodings included) and read back equal to the
    :class:`trace.Trace` the same encodings make; the slot's ``due`` is at most its
    crossing.  At a clock ``offset`` (relative) from each crossing, a trace said gone
    crossed by then, one said staying crosses later and its bound, less ``MARGIN``, is at
    most the crossing, and one left undecided is within 1e-8 (relative) of the clock or one
    :class:`crossings._Newton` leaves to :func:`trace.crossing`; the one-by-one
    decision (:func:`crossings.gone_by`) likewise.
    """
    from fsreg_ros.core.memory import crossings, trace_columns
    from fsreg_ros.core.memory import trace as activation

    d, tau = params
    span = activation.lifetime(d, tau)
    columns = trace_columns.TraceColumns(2, len(gaps))
    traces, flat = [], []
    for row, steps in enumerate(gaps):
        slot = row % 2
        at = slot * len(gaps) + row
        time = float(row)
        trace = activation.Trace(time)
        columns.encoded(np.array([at]), np.array([False]), time, span, d)
        for gap in steps[1:]:
            time += gap
            trace.add(time)
            columns.encoded(np.array([at]), np.array([True]), time, span, d)
        got = columns.get(slot, row)
        assert (got.n, got.first, got.recent) == (trace.n, trace.first, trace.recent)
        assert got.due <= activation.crossing(trace, d, tau)  # a lower bound (the crossing, for one encoding)
        if trace.n > 1:
            traces.append(trace)
            flat.append(at)
    if not flat:
        return
    n, first, times = columns.ordered(np.array(flat, dtype=np.intp))
    others = crossings._Newton(n, first, times, d, tau).other.tolist()
    for k, trace in enumerate(traces):
        want = activation.crossing(trace, d, tau)
        if want == activation.NEVER:
            continue
        now = want + offset * max(1.0, abs(want))
        gone, bound = crossings.passages(n[k:k + 1], first[k:k + 1], times[:, k:k + 1], d, tau, now)
        close = abs(now - want) <= 1e-8 * max(1.0, abs(want))
        if gone[0]:
            assert want <= now, (want, now)
        elif bound[0] > -np.inf:
            later = float(bound[0])
            assert want > now and later - crossings.MARGIN * max(1.0, abs(later)) <= want, (want, now, later)
        else:
            assert close or others[k], (want, now)
        gone, later = crossings.gone_by(trace, now, d, tau)
        if gone:
            assert want <= now and later is None, (want, now)
        else:
            assert want > now - 1e-8 * max(1.0, abs(want)), (want, now)
            if later is not None:  # staying: a lower bound of the crossing, past the clock
                assert now < later <= want, (want, now, later)
