"""ACT-R base-level activation as a forgetting rule (core/memory/activation.py, docs/semantics.md section 5).

Hand-computed crossing times and WM contents, pyactr's ``baselevel_learning`` as an
independent implementation of the activation values, and a restart.  The lazy buffer
against the naive eager reference on random operation sequences is in
test_properties.py.
"""

from __future__ import annotations

import math
import os
from decimal import Decimal, localcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyactr.utilities import baselevel_learning

from fsreg_ros.core.forgetting.policies import ForgettingPolicy, PolicyError
from fsreg_ros.core.memory import WMBuffer, WMEvent
from fsreg_ros.core.memory.trace import HISTORY, LONGEST, NEVER, Trace, activation, crossing, lifetime
from fsreg_ros.core.forgetting.settings import MAX_ACTIVATION_DECAY, MAX_ACTIVATION_THRESHOLD, MIN_ACTIVATION_DECAY
from fsreg_ros.core.forgetting.wm_manager import WMManager


def trace_of(times):
    trace = Trace(times[0])
    for t in times[1:]:
        trace.add(t)
    return trace


def policy(tau: float, d: float = 0.5, rules: str = "activation", **more) -> ForgettingPolicy:
    return ForgettingPolicy.parse(rules, activation_decay=d, activation_threshold=tau, **more)


# ------------------------------------------------------------ the formula
@pytest.mark.parametrize("times, now, d", [
    ([0.0], 3.0, 0.5),
    ([0.0, 5.0], 10.0, 0.5),
    ([1.0, 2.0, 4.0, 8.0], 9.5, 0.3),
    ([0.0, 0.0, 7.25], 12.0, 0.8),  # two encodings at one time count twice
    ([float(t) for t in range(HISTORY)], 30.0, 0.5),  # as many as are kept exactly
    ([3.0, 40.0, 41.0, 100.0, 250.5], 1000.0, 0.65),
])
def test_activation_is_pyactrs_base_level_learning(times, now, d):
    """The exact sum (n <= HISTORY) against pyactr 0.3.2's ``utilities.baselevel_learning``."""
    expected = baselevel_learning(now, np.array(times), True, d)
    assert activation(trace_of(times), now, d) == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_older_presentations_follow_petrovs_approximation():
    """Beyond HISTORY presentations the older ones are approximated (Petrov 2006): close to pyactr's exact sum."""
    times = [float(3 * k) for k in range(40)]  # 40 presentations, every 3 s
    for now, d in [(121.0, 0.5), (150.0, 0.3), (400.0, 0.8)]:
        exact = baselevel_learning(now, np.array(times), True, d)
        approximated = activation(trace_of(times), now, d)
        assert approximated != exact and abs(approximated - exact) < 0.01


def test_the_crossing_is_where_activation_meets_the_threshold():
    assert crossing(trace_of([4.0]), 0.5, -1.0) == 4.0 + math.exp(2.0) == 4.0 + lifetime(0.5, -1.0)
    for times, d, tau in [([0.0, 10.0], 0.5, -0.6), ([1.0, 2.0, 4.0, 8.0], 0.3, -0.2),
                          ([float(t) for t in range(30)], 0.5, 0.5), ([0.0, 0.0], 0.9, -2.0)]:
        trace = trace_of(times)
        c = crossing(trace, d, tau)
        assert c > times[-1] + lifetime(d, tau) - 1e-9
        assert activation(trace, c, d) == pytest.approx(tau, abs=1e-9)
        assert activation(trace, c - 1e-6, d) > tau > activation(trace, c + 1e-6, d)


# ------------------------------------------- the crossing, to the last bits
def _reference_strength(trace: Trace, age: Decimal, d: Decimal) -> Decimal:
    """sum_j (t - t_j)^-d at ``age`` after the last encoding, Petrov's term for the older ones, in decimals.

    50 digits, and for Petrov's term as many more as its spread is smaller than its age,
    so that its difference of powers, written as docs/semantics.md defines it, does not cancel.
    """
    last = Decimal(trace.recent[-1])
    total = sum(((age + (last - Decimal(r))) ** -d for r in trace.recent), Decimal(0))
    older = trace.n - len(trace.recent)
    if older:
        first, oldest = Decimal(trace.first), Decimal(trace.recent[0])
        a, spread = age + (last - oldest), oldest - first
        if spread == 0:
            return total + older * a ** -d
        with localcontext() as ctx:
            ctx.prec = 50 + max(0, int((a / spread).log10()) + 1)
            b = a + spread
            total += older * (b ** (1 - d) - a ** (1 - d)) / ((1 - d) * spread)
    return +total


def _reference_crossing_age(trace: Trace, d: float, tau: float) -> Decimal:
    """The age (time since the last encoding) at which A meets ``tau``: regula falsi (Illinois) on ln(age), in decimals.

    The root lies between one encoding's lifetime exp(-tau/d) and n^(1/d) times it (each
    of the n terms is at most the last one's); A is nearly linear in ln(age) there.
    """
    with localcontext() as ctx:
        ctx.prec = 50
        dd, target = Decimal(d), Decimal(tau)

        def excess(v: Decimal) -> Decimal:
            return _reference_strength(trace, v.exp(), dd).ln() - target

        lo = -target / dd  # ln of the ages
        hi = lo + Decimal(trace.n).ln() / dd
        f_lo, f_hi, side = excess(lo), excess(hi), 0
        if f_lo <= 0 or f_hi >= 0:  # (one encoding: lo = hi)
            return (lo if f_lo <= 0 else hi).exp()
        for _ in range(200):
            v = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            f = excess(v)
            if abs(f) <= Decimal("1e-40") or hi - lo <= Decimal("1e-40") * (1 + abs(lo)):
                break
            if f > 0:
                lo, f_lo = v, f
                if side == 1:
                    f_hi /= 2
                side = 1
            else:
                hi, f_hi = v, f
                if side == -1:
                    f_lo /= 2
                side = -1
        return v.exp()


# Encoding gaps: repeats at one time, subnormal and tiny ones (the older presentations may span
# almost nothing of their age: Petrov's term cancels), and ordinary ones; d and tau over their whole range.
_GAPS = st.one_of(st.just(0.0), st.floats(5e-324, 1e-300), st.floats(1e-12, 1e-6), st.floats(1e-3, 50.0))
_TRACES = st.tuples(st.one_of(st.just(0.0), st.floats(1e-3, 1e6)), st.lists(_GAPS, max_size=20))
_D = st.floats(MIN_ACTIVATION_DECAY, MAX_ACTIVATION_DECAY)
_TAU = st.floats(-MAX_ACTIVATION_THRESHOLD, MAX_ACTIVATION_THRESHOLD)
_EXAMPLES = settings(max_examples=int(os.environ.get("FSREG_HYPOTHESIS_EXAMPLES", "200")), deadline=None)


def _trace_from(start: float, gaps: list) -> Trace:
    times = [start]
    for gap in gaps:
        times.append(times[-1] + gap)
    return trace_of(times)


@_EXAMPLES
@given(_TRACES, _D, _TAU)
def test_crossing_is_the_root_to_the_last_bits(start_gaps, d, tau):
    """crossing() is the root of A(t) = tau (as docs/semantics.md defines A) within 1e-12 of its age and one
    rounding of the time, or NEVER past the clock's range; never an error.

    A 50-digit bisection is the reference.  Before the fix a subnormal spread of the older
    presentations divided by zero, a lifetime below the last time's resolution evaluated an
    age of 0, and a spread much smaller than its age (Petrov's term cancelling) moved the root.
    """
    trace = _trace_from(*start_gaps)
    last = trace.recent[-1]
    age = _reference_crossing_age(trace, d, tau)
    c = crossing(trace, d, tau)
    if age > Decimal(LONGEST) * Decimal("1.000001"):
        assert c == NEVER
        return
    if age > Decimal(LONGEST) * Decimal("0.999999"):
        return  # on the edge of the clock's range: either answer
    want = Decimal(last) + age
    assert c != NEVER and c >= last
    assert abs(Decimal(c) - want) <= age * Decimal("1e-12") + Decimal(math.ulp(float(want))), (c, float(want))


@_EXAMPLES
@given(_TRACES, _D, st.floats(1e-6, 1e4))
def test_activation_is_the_defined_sum_to_the_last_bits(start_gaps, d, age):
    """activation() is ln of the defined sum (Petrov's term for the older ones) within 1e-12, never an error."""
    trace = _trace_from(*start_gaps)
    t = trace.recent[-1] + age
    if t <= trace.recent[-1]:
        return
    with localcontext() as ctx:
        ctx.prec = 50
        want = _reference_strength(trace, Decimal(t) - Decimal(trace.recent[-1]), Decimal(d)).ln()  # age exact
    assert abs(Decimal(activation(trace, t, d)) - want) <= Decimal("1e-12") * max(1, abs(want))


def test_crossing_where_the_older_presentations_span_little_of_their_age():
    """Hand-made cases the property test found: a subnormal spread, and a spread of 1e-9 s among ages of ~100 s."""
    subnormal = trace_of([0.0, 5e-324, *[1.0 + k for k in range(HISTORY)]])  # Petrov span 5e-324
    age = _reference_crossing_age(subnormal, 0.9, -1.0)
    c = crossing(subnormal, 0.9, -1.0)  # (1 - d) times the spread underflowed to 0: ZeroDivisionError
    assert abs(Decimal(c) - Decimal(subnormal.recent[-1]) - age) <= age * Decimal("1e-12")
    tight = trace_of([1.0, 1.0 + 1e-9, 1.0 + 2e-9, *[1.0 + 3e-9 + 1e-9 * k for k in range(HISTORY)]])
    for d, tau in [(0.5, -2.0), (0.9, -3.0), (0.2, -0.5)]:
        want = Decimal(tight.recent[-1]) + _reference_crossing_age(tight, d, tau)
        assert abs(Decimal(crossing(tight, d, tau)) - want) <= want * Decimal("1e-13")


def test_trace_round_trip_and_refusals():
    trace = trace_of([float(t) for t in range(12)])
    assert trace.to_json() == [12, 0.0, *[float(t) for t in range(4, 12)]]
    copy = Trace.from_json(trace.to_json())
    assert (copy.n, copy.first, copy.recent) == (trace.n, trace.first, trace.recent)
    for bad in ([1, 0.0], [1, 0.0, 1.0, 2.0], [3, 0.0, 2.0, 1.0], [3, 0.0, float("nan")], "x", [True, 0.0, 1.0],
                [3, 0.0, 1.0, 2.0], [12, 0.0, *[float(t) for t in range(5, 12)]]):  # (fewer times than it keeps)
        with pytest.raises(ValueError, match="activation trace"):
            Trace.from_json(bad)


def test_trace_columns_keep_each_ring_on_one_cache_line_as_they_grow():
    """Each slot's ring of :data:`HISTORY` times starts a 64-byte line, after growing and widening too; traces kept."""
    from fsreg_ros.core.memory.trace_columns import TraceColumns

    columns = TraceColumns(2, 3)
    span = lifetime(0.5, -1.0)
    for k, time in enumerate([0.0, 1.0, 2.5] + [3.0 + t for t in range(HISTORY)]):  # (slot 1 of row 2 wraps)
        columns.encoded(np.array([0, 5]), np.array([k > 0, k > 0]), time, span, 0.5)
    before = [(t.n, t.first, t.recent, t.due) for t in (columns.get(0, 0), columns.get(1, 2))]
    for change in (lambda: None, lambda: columns.grow(5), lambda: columns.widen(3)):
        change()
        assert columns.recent.ctypes.data % 64 == 0 and columns.recent.shape[2] * 8 == 64
        assert columns.recent.flags.c_contiguous
        assert [(t.n, t.first, t.recent, t.due) for t in (columns.get(0, 0), columns.get(1, 2))] == before
    assert before[1][0] == 3 + HISTORY and before[1][2] == [3.0 + t for t in range(HISTORY)]


# --------------------------------------------------------------- the rule
def test_policy_parsing():
    assert policy(-1.0).to_json() == {"policy": "activation", "activation_decay": 0.5, "activation_threshold": -1.0}
    assert policy(-1.0, rules="activation+displacement", capacity=2).limits().activation == (0.5, -1.0)
    with pytest.raises(PolicyError, match="combines decay and activation"):
        policy(-1.0, rules="decay+activation", decay_period=5.0)
    with pytest.raises(PolicyError, match="needs 'activation_threshold'"):
        ForgettingPolicy.parse("activation")
    with pytest.raises(PolicyError, match=r"activation_decay must be <= 0.99"):
        policy(-1.0, d=1.0)


def managed(p: ForgettingPolicy):
    events: list[WMEvent] = []
    buffer = WMBuffer("d", events.append)
    manager = WMManager()
    manager.manage(buffer, p)
    return buffer, manager, events


def quiet(column_min: int) -> tuple[WMBuffer, WMManager]:
    """Return a managed buffer under activation+displacement (tau -1, capacity 2) with no event sink.

    ``column_min`` 1: column queues; 10**9: dict queues (the two paths a test compares).
    """
    buffer, manager, _ = managed(policy(-1.0, rules="activation+displacement", capacity=2))
    buffer.sink, buffer.column_min = None, column_min
    return buffer, manager


def on_both_paths():
    """Yield ``(column_min, buffer, manager)`` of :func:`quiet`: column queues, then dict queues."""
    for column_min in (1, 10**9):
        yield (column_min, *quiet(column_min))


def kept(buffer: WMBuffer, names: list[str]) -> list:
    """Return the queues of ``names`` as a store keeps them: (property, trace) per item, LRU first."""
    return [[(item[0], item[5]) for item in buffer.export_queue(name)] for name in names]


def test_exact_wm_contents_at_given_times():
    """d = 0.5, tau = ln(20^-0.5 + 10^-0.5): one encoding at t stays until t + exp(-2 tau) = t + 3.4316 s."""
    tau = math.log(20 ** -0.5 + 10 ** -0.5)
    single = math.exp(-2 * tau)  # 3.4316... s
    buffer, manager, events = managed(policy(tau))
    buffer.encode("e", ["a"], "speaker", 0.0, 0)
    manager.advance(2.0)
    buffer.encode("e", ["b"], "rr", 2.0, 1)
    manager.advance(single - 0.01)
    assert buffer.queue("e") == ("a", "b")
    manager.advance(single + 0.01)
    assert buffer.queue("e") == ("b",)  # a (once, at 0) crossed at 3.43
    manager.advance(2.0 + single - 0.01)
    assert buffer.queue("e") == ("b",)
    manager.advance(2.0 + single + 0.01)
    assert buffer.queue("e") == ()  # b (once, at 2) at 5.43
    buffer.encode("e", ["a"], "speaker", 10.0, 2)  # a enters again: a new history
    buffer.encode("f", ["a"], "speaker", 10.0, 2)
    buffer.encode("f", ["a"], "speaker", 12.0, 3)
    manager.advance(13.0)
    assert buffer.queue("e") == ("a",) and buffer.queue("f") == ("a",)
    manager.advance(10.0 + single + 0.001)
    assert buffer.snapshot() == {"f": ["a"]}
    forgets = [(e.entity, e.property, e.cause, e.time) for e in events if e.op == "forget"]
    assert forgets == [("e", "a", "activation", pytest.approx(single)), ("e", "b", "activation",
                       pytest.approx(2.0 + single)), ("e", "a", "activation", pytest.approx(10.0 + single))]


def test_a_refresh_extends_the_stay_to_the_hand_computed_crossing():
    """tau = ln(5^-0.5 + 4^-0.5): alone, an encoding stays 1.115 s; refreshed at 1, A(t) = ln(t^-0.5 + (t - 1)^-0.5)
    meets tau at t = 5."""
    tau = math.log(5 ** -0.5 + 4 ** -0.5)
    buffer, manager, events = managed(policy(tau))
    buffer.encode("e", ["a", "b"], "speaker", 0.0, 0)
    buffer.encode("e", ["a"], "speaker", 1.0, 1)
    manager.advance(1.2)
    assert buffer.queue("e") == ("a",)  # b, once at 0, crossed at 1.115
    manager.advance(4.999)
    assert buffer.queue("e") == ("a",)
    manager.advance(5.001)
    assert buffer.queue("e") == ()
    assert [(e.property, e.time) for e in events if e.op == "forget"] == [
        ("b", pytest.approx(math.exp(-2 * tau))), ("a", pytest.approx(5.0, abs=1e-9))]


def test_activation_with_displacement_and_an_encoding_after_a_crossing():
    """Entries whose crossing is at or before an encoding's time go first: displacement then finds room."""
    buffer, manager, events = managed(policy(-1.0, rules="activation+displacement", capacity=2))
    L = math.exp(2.0)  # 7.389 s per single encoding
    buffer.encode("e", ["a", "b"], "rr", 0.0, 0)
    buffer.encode("e", ["c"], "rr", L, 1)  # a and b crossed at L: no displacement
    assert buffer.queue("e") == ("c",)
    assert [(e.property, e.cause) for e in events if e.op == "forget"] == [("a", "activation"), ("b", "activation")]
    buffer.encode("e", ["d", "f"], "rr", L + 1.0, 2)
    assert buffer.queue("e") == ("d", "f") and events[-1].cause == "displacement"


@pytest.mark.parametrize("columns", [False, True])
def test_a_late_encoding_counts_at_the_clock(columns):
    """An encoding stamped before the clock (a late message, a clock that jumped back) counts at the clock.

    tau = 0: one encoding stays 1 s, two at one time 4 s (the previous release failed on
    the late one: a negative age, a complex power).  ``columns``: the rule-3 path over
    column queues (no event sink), as a REG call over many distractors takes it.
    """
    from fsreg_ros.core.memory import bitset

    tau = 0.0
    buffer, manager, events = managed(policy(tau, rules="activation+displacement", capacity=3))
    buffer.column_min = 1 if columns else 10**9
    if columns:
        buffer.sink = None
    names = ["e", "f"]
    buffer.encode_members(bitset.from_indices([0, 1], 2), names, "a", "reg-distractor", 10.0, 0)
    manager.advance(10.0)
    buffer.encode_members(bitset.from_indices([0], 2), names, "a", "reg-distractor", 7.0, 1)  # late: at 10
    assert buffer.export_queue("e")[0][5] == [2, 10.0, 10.0, 10.0]  # count, first time, kept times
    manager.advance(13.999)
    assert buffer.queue("e") == ("a",) and buffer.queue("f") == ()  # f's one encoding at 10 went at 11
    manager.advance(14.001)
    assert buffer.queue("e") == ()


def test_rows_checked_at_a_clock_are_not_taken_for_rows_not_checked():
    """Column rows brought up to a clock are not checked again at it; the others still are, before encoding.

    tau = 0, capacity 2: one encoding stays 1 s, three at one time 9 s.  e and f get "a"
    three times at 0, e "b" once at 0.5 (gone at 1.5; "a" is e's least recently used).
    At 2, "c" goes into f (f's row checked at 2), then "d" into e and f: e's row was not
    checked at 2, so "b" goes before "d" comes in, and "a" stays (had "b" still been
    there, the full row would have lost "a" to "d").  As from dict queues.
    """
    from fsreg_ros.core.memory import bitset

    names = ["e", "f"]
    queues = []
    for column_min in (1, 10**9):  # column queues, dict queues
        buffer, manager, events = managed(policy(0.0, rules="activation+displacement", capacity=2))
        buffer.sink, buffer.column_min = None, column_min
        both, e, f = (bitset.from_indices(rows, 2) for rows in ([0, 1], [0], [1]))
        for _ in range(3):
            buffer.encode_members(both, names, "a", "reg-distractor", 0.0, 0)
        manager.advance(0.5)
        buffer.encode_members(e, names, "b", "reg-distractor", 0.5, 1)
        manager.advance(2.0)
        buffer.encode_members(f, names, "c", "reg-distractor", 2.0, 2)
        buffer.encode_members(both, names, "d", "reg-distractor", 2.0, 2)
        queues.append((buffer.queue("e"), buffer.queue("f"), len(buffer), set(buffer.columns.entities)))
    assert queues[0] == (("a", "d"), ("c", "d"), 4, {"e", "f"})
    assert queues[1][:3] == queues[0][:3] and queues[1][3] == set()


def test_one_times_encodings_that_write_a_slot_again_note_what_the_dict_queues_do():
    """The encodings made at one time and clock are noted together; a row that refreshes an entry, then displaces it,
    displaces its own new entries, and gets one property twice keeps the traces a dict queue keeps.

    Capacity 2, tau -1 (nothing goes).  At 0, e and f get a and b.  At 1, e gets a (a
    refresh), c (b out), d (a out: refreshed, then displaced), g (c out: new, then
    displaced) and g again; f gets g.  Items are (property, ..., trace) as a store keeps
    them: count, first time, kept times.
    """
    from fsreg_ros.core.memory import bitset

    names = ["e", "f"]
    got = []
    for column_min, buffer, manager in on_both_paths():
        both, e = bitset.from_indices([0, 1], 2), bitset.from_indices([0], 2)
        for prop in ("a", "b"):
            buffer.encode_members(both, names, prop, "reg-distractor", 0.0, 0)
        manager.advance(1.0)
        for prop in ("a", "c", "d", "g"):
            buffer.encode_members(e, names, prop, "reg-distractor", 1.0, 1)
        buffer.encode_members(both, names, "g", "reg-distractor", 1.0, 1)
        got.append(kept(buffer, names))
        if column_min == 1:
            assert set(buffer.columns.entities) == {"e", "f"}
    assert got[0] == [[("d", [1, 1.0, 1.0]), ("g", [2, 1.0, 1.0, 1.0])],
                      [("b", [1, 0.0, 0.0]), ("g", [1, 1.0, 1.0])]]
    assert got[1] == got[0]


def test_a_description_joins_the_batch_of_its_time_and_is_noted_as_a_dict_queue_notes_it():
    """Rule 1 into column queues at the time of rule-3 encodings: a refresh of what the batch wrote counts twice.

    Capacity 2, tau -1 (nothing goes).  At 1, e and f get a (rule 3); then e's description
    a, b, c (a refreshed: two encodings; c displaces a) and f's a, a (three).  Items are
    (property, trace) as a store keeps them.
    """
    from fsreg_ros.core.memory import bitset

    names = ["e", "f"]
    got = []
    for column_min, buffer, manager in on_both_paths():
        manager.advance(1.0)
        buffer.encode_members(bitset.from_indices([0, 1], 2), names, "a", "reg-distractor", 1.0, 0)
        buffer.encode("e", ["a", "b", "c"], "speaker", 1.0, 0)
        buffer.encode("f", ["a", "a"], "speaker", 1.0, 0)
        got.append(kept(buffer, names))
        if column_min == 1:
            assert set(buffer.columns.entities) == {"e", "f"}
    assert got[0] == [[("b", [1, 1.0, 1.0]), ("c", [1, 1.0, 1.0])], [("a", [3, 1.0, 1.0, 1.0, 1.0])]]
    assert got[1] == got[0]


def test_a_description_encoded_into_a_column_queue_first_forgets_what_crossed():
    """Rule 1 into a column queue (no sink) stays in its row and forgets what crossed first, as a dict queue does.

    tau -1, capacity 2: one encoding stays L = e^2 s, two at one time 4 L.  e and f get b
    twice at 0 and a at 0.5 (b is the front).  At L + 0.6, a has crossed: "c" into e takes
    its place (no displacement of b), and "a" into f comes in anew (one encoding, not a
    refresh).  Items are (property, trace) as a store keeps them.
    """
    from fsreg_ros.core.memory import bitset

    names = ["e", "f"]
    L = math.exp(2.0)
    got = []
    for column_min, buffer, manager in on_both_paths():
        both = bitset.from_indices([0, 1], 2)
        for _ in range(2):
            buffer.encode_members(both, names, "b", "reg-distractor", 0.0, 0)
        manager.advance(0.5)
        buffer.encode_members(both, names, "a", "reg-distractor", 0.5, 1)
        manager.advance(L + 0.6)
        buffer.encode("e", ["c"], "speaker", L + 0.6, 2)
        buffer.encode("f", ["a"], "speaker", L + 0.6, 2)
        got.append(kept(buffer, names))
        got.append((len(buffer), buffer.nonempty_entities(), buffer.take_changes()))
        if column_min == 1:
            assert set(buffer.columns.entities) == {"e", "f"}  # (encoded in their rows)
    assert got[0] == [[("b", [2, 0.0, 0.0, 0.0]), ("c", [1, L + 0.6, L + 0.6])],
                      [("b", [2, 0.0, 0.0, 0.0]), ("a", [1, L + 0.6, L + 0.6])]]
    assert got[1] == (4, ["e", "f"], ["e", "f"])
    assert got[2:] == got[:2]


def test_column_queues_written_by_a_description_restart_from_their_export_as_dict_queues_do():
    """Column queues a description wrote in their rows are exported and restored with their traces (a restart).

    Capacity 2, tau -1 (one encoding stays L = e^2 s, two at one time 4 L).  At 0, e and f
    get a (rule 3) at 0.5, then e's description b, a.  The queues are exported, a fresh buffer
    restores them, f and e get c at 1 (the restored queues move into rows with their
    traces) and the clock passes L: b and f's a (one encoding each) go, e's a (two) stays.
    """
    from fsreg_ros.core.memory import bitset

    names = ["e", "f"]
    L = math.exp(2.0)
    got = []
    for column_min, buffer, manager in on_both_paths():
        both = bitset.from_indices([0, 1], 2)
        manager.advance(0.5)
        buffer.encode_members(both, names, "a", "reg-distractor", 0.5, 0)
        buffer.encode("e", ["b", "a"], "speaker", 0.5, 0)
        if column_min == 1:
            assert set(buffer.columns.entities) == {"e", "f"}  # (the description stayed in e's row)
        saved = {name: buffer.export_queue(name) for name in names}
        stamp, ticks = buffer.counters()
        restarted, manager = quiet(column_min)
        restarted.restore(saved, stamp, ticks, restarted.limits)
        manager.advance(1.0)
        restarted.encode_members(both, names, "c", "reg-distractor", 1.0, 1)
        manager.advance(L + 0.75)
        got.append(kept(restarted, names))
        got.append((saved, len(restarted)))
    assert got[0] == [[("a", [2, 0.5, 0.5, 0.5]), ("c", [1, 1.0, 1.0])], [("c", [1, 1.0, 1.0])]]
    assert got[1][1] == 3
    assert got[2:] == got[:2]


def test_rows_that_widen_restart_from_their_export_and_find_their_slots_again():
    """Activation alone (no capacity): column rows widen past 4 slots, are exported, restored and encoded again.

    tau -1 (one encoding stays L = e^2 s).  e, f and g get a, b, c, d, h at 0 (rows
    widen to 8 slots) and e again a at 0.5.  A fresh buffer restores the export (a
    restart); x and a go to every row at 1 (the restored queues move into rows, a
    refreshed where it is); at L + 0.75 b, c, d and h (one encoding each, at 0) are gone.  The
    slot map says where each row holds each property throughout; dict queues agree.
    """
    from fsreg_ros.core.memory import bitset

    names = ["e", "f", "g"]
    L = math.exp(2.0)
    everyone = bitset.from_indices([0, 1, 2], 3)
    got = []
    for column_min in (1, 10**9):  # column queues, dict queues
        buffer, manager, _ = managed(policy(-1.0))
        buffer.sink, buffer.column_min = None, column_min
        for prop in ("a", "b", "c", "d", "h"):
            buffer.encode_members(everyone, names, prop, "reg-distractor", 0.0, 0)
        manager.advance(0.5)
        buffer.encode_members(bitset.from_indices([0], 3), names, "a", "reg-distractor", 0.5, 1)
        saved = {name: buffer.export_queue(name) for name in names}
        restarted, manager, _ = managed(policy(-1.0))
        restarted.sink, restarted.column_min = None, column_min
        restarted.restore(saved, *buffer.counters(), restarted.limits)
        manager.advance(1.0)
        for prop in ("x", "a"):
            restarted.encode_members(everyone, names, prop, "reg-distractor", 1.0, 2)
        store = restarted.columns.store
        if column_min == 1:
            assert store is not None and not store.bounded and store.width == 8 and store.slot_of is not None
            for row, name in enumerate(names):  # the map: each property's slot in each row
                props = store.prop[:, row].tolist()
                assert {restarted.columns.prop_name[p]: k for k, p in enumerate(props) if p >= 0} == {
                    restarted.columns.prop_name[p]: int(store.slot_of[p, row]) for p in range(store.slot_of.shape[0])
                    if store.slot_of[p, row] >= 0}
        manager.advance(L + 0.75)
        got.append([list(restarted.queue(name)) for name in names])
        got.append(kept(restarted, names))
    assert got[0] == [["x", "a"], ["x", "a"], ["x", "a"]]
    assert got[1] == [[("x", [1, 1.0, 1.0]), ("a", [3, 0.0, 0.0, 0.5, 1.0])],
                      [("x", [1, 1.0, 1.0]), ("a", [2, 0.0, 0.0, 1.0])],
                      [("x", [1, 1.0, 1.0]), ("a", [2, 0.0, 0.0, 1.0])]]
    assert got[2:] == got[:2]


# ------------------------------------------------------------ persistence
def test_a_restart_restores_the_encoding_histories(tmp_path):
    """The journal (encodings, the clock's ``advance``) and the checkpoint (items with their traces) both restore
    the histories: the restarted consultant forgets at the same crossing times."""
    from fsreg_ros.contract.consultant_codec import apply
    from fsreg_ros.core.consultant.consultant import Consultant
    from fsreg_ros.core.consultant.service import ConsultantService
    from fsreg_ros.core.state.store import DomainStore, fingerprint

    pref = ["male", "glasses", "hat"]
    facts = {"f1": {"male": 1.0, "glasses": 1.0, "hat": 1.0}, "f2": {"glasses": 1.0}}
    tau = math.log(5 ** -0.5 + 4 ** -0.5)  # as above: once -> 1.115 s; at 0 and 1 -> crosses at 5
    settings = {"policy": "activation", "activation_decay": 0.5, "activation_threshold": tau}

    def make():
        store = DomainStore(tmp_path / "faces.sqlite3", fingerprint(pref, facts, 0.5, {}))
        service = ConsultantService(Consultant("faces", facts, pref), store=store, clock="sim", now=lambda: 0.0)
        service.restore(store.open())
        return service

    def call(service, op, **fields):
        return apply(service, op, {"op": op, **fields}).reply

    service = make()
    call(service, "configure", policy=settings, time=0.0)
    for time, props in ((0.0, ["male", "glasses"]), (1.0, ["male"])):
        call(service, "encode", entity="f1", properties=props, cause="speaker", time=time)
    call(service, "advance", time=1.2)  # glasses (once, at 0) crossed at 1.115
    live = {e: service.buffer.export_queue(e) for e in service.buffer.nonempty_entities()}
    assert live == {"f1": [("male", 3, 1, "speaker", None, [2, 0.0, 0.0, 1.0])]}
    assert service.store.journal_length() == 4  # configure, two encodes, advance
    service.store.close()  # abruptly: no checkpoint
    service = make()  # from the journal
    assert service.store.journal_length() == 4
    assert {e: service.buffer.export_queue(e) for e in service.buffer.nonempty_entities()} == live
    service.maintain()  # the replayed journal becomes a checkpoint
    assert service.store.journal_length() == 0
    service.store.close()
    service = make()  # from the checkpoint
    assert {e: service.buffer.export_queue(e) for e in service.buffer.nonempty_entities()} == live
    call(service, "configure", policy=settings, time=4.0)
    assert call(service, "advance", time=4.999)["queues_changed"] == 0
    assert call(service, "advance", time=5.001)["queues_changed"] == 1
    assert service.buffer.snapshot() == {}
    # A late encoding (stamped 7, the clock at 10) counts at 10, and a restart from the journal replays it so.
    call(service, "encode", entity="f2", properties=["glasses"], cause="speaker", time=10.0)
    call(service, "advance", time=10.0)
    call(service, "encode", entity="f2", properties=["glasses"], cause="speaker", time=7.0)
    late = {e: service.buffer.export_queue(e) for e in service.buffer.nonempty_entities()}
    assert late == {"f2": [("glasses", 5, 1, "speaker", None, [2, 10.0, 10.0, 10.0])]}
    service.store.close()
    service = make()
    assert {e: service.buffer.export_queue(e) for e in service.buffer.nonempty_entities()} == late
