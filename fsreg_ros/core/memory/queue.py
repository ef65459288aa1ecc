"""A WM queue and what is said about it: entries, exported items, events, origins.

``Q[entity]`` is a :class:`Queue`: an insertion-ordered dict property -> entry, LRU
at the front and MRU at the back.  Reading a queue never refreshes recency; only
encoding does.  An entry is its *stamp* (an ``int``: every push in a domain gets the
next value of one counter) while the property has not been encoded again since it
entered the queue; a refreshed entry is the pair ``(stamp, reference)``, the
reference being the stamp it entered with or, for an entry restored from a store,
its origin itself (:func:`entry_stamp`, and the buffer's origin log,
:mod:`fsreg_ros.core.memory.origins`).

:class:`WMEvent` is what an event sink hears; :class:`QueueItem` is one entry as a
store keeps it.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Optional, Union

#: Causes an event can have (docs/semantics.md section 2).
ENCODE_CAUSES = ("speaker", "rr", "reg-distractor")
FORGET_CAUSES = ("decay", "activation", "displacement", "similarity", "global-capacity", "shared-capacity", "reset",
                 "retract", "episodes")


class WMEvent(NamedTuple):
    """One encoding or forgetting in a domain's WM buffer (immutable).

    ``time`` is the robot-clock time the change happened at (a decay tick's own
    time, even when a lazy queue catches up later); ``turn`` is the dialogue turn
    index that caused it, or ``None`` for clock-driven and administrative changes.
    A named tuple rather than a frozen dataclass: one is built per encoding, and a
    tuple is about three times cheaper to build.
    """

    op: str  # "encode" | "forget"
    domain: str
    entity: str
    property: str
    cause: str
    time: float
    turn: Optional[int] = None

    def to_json(self) -> dict:
        return self._asdict()


EventSink = Callable[[WMEvent], None]

#: ``(cause, turn)`` of the encoding that made a property enter a queue.
Origin = tuple[str, Optional[int]]
#: The origin of entries restored from a store that kept none (items of three fields).
UNKNOWN_ORIGIN: Origin = ("unknown", None)
#: A dict queue's entry: its stamp, or ``(stamp, reference)`` once refreshed (see the module docstring).
Entry = Union[int, tuple]


class QueueItem(NamedTuple):
    """One entry of an exported queue (:meth:`WMBuffer.export_queue`), for a store.

    ``stamp`` is the entry's latest encoding stamp; ``hits`` its LFU count (1 when LFU
    is not in force); ``cause`` and ``turn`` its origin: the encoding that made the
    property enter the queue.  The first three fields keep the order of the former
    ``(property, stamp, hits)`` tuples.
    """

    property: str
    stamp: int
    hits: int
    cause: str
    turn: Optional[int]


class TracedItem(NamedTuple):
    """A :class:`QueueItem` with its activation trace (rule ``activation``: ``[n, first, recent times...]``)."""

    property: str
    stamp: int
    hits: int
    cause: str
    turn: Optional[int]
    trace: list


def is_origin(cause: object, turn: object) -> bool:
    """Tell whether ``(cause, turn)`` can be an origin: a cause name and a turn index or None."""
    return isinstance(cause, str) and (turn is None or isinstance(turn, int) and not isinstance(turn, bool))


def entry_stamp(value: Entry) -> int:
    """Return a dict queue entry's latest stamp."""
    return value if value.__class__ is int else value[0]


def entry_entered(value: Entry) -> Optional[int]:
    """Return the stamp a dict queue entry entered its queue with (None: restored from a store, unknown)."""
    if value.__class__ is int:
        return value
    ref = value[1]
    return ref if ref.__class__ is int else None


class Queue(dict):
    """Q[entity]: an insertion-ordered dict property -> entry, front (LRU) first.

    Entries are described in the module docstring: a property entering a queue, the
    common encoding, stores one int and builds no per-entry object (measured: a pair
    per entry made rule-3 encodings into 10,000 queues half again as slow).

    ``synced`` is the number of decay ticks this queue has been brought up to (lazy
    decay, :mod:`fsreg_ros.core.memory.decay`).  Keeping it in the queue object
    itself, rather than in a second entity-keyed table, halves the memory touched per
    encoding, which dominates when thousands of distractors are encoded at once (rule
    3).  A plain dict subclass, not an OrderedDict, for the same reason.  ``hits``
    counts encodings per property for LFU displacement (only kept while LFU is in
    force).  ``marked``: the queue is in the buffer's change record already (so
    recording a change is one attribute test on an object just touched, not a store
    into a table).
    """

    __slots__ = ("synced", "hits", "marked")
