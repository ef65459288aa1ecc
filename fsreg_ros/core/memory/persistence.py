"""A buffer's state as a store keeps it: exported queues, counters, and the restore; the snapshot of all queues.

A consultant persists the queues :meth:`WMBuffer.take_changes` names, each as
:meth:`WMBuffer.export_queue` returns it (:class:`QueueItem`: property, stamp, LFU
hits and origin), beside :meth:`WMBuffer.counters`; :meth:`WMBuffer.restore` takes
them back (:mod:`fsreg_ros.core.state.store`, :mod:`fsreg_ros.core.state.journal`).
"""

from __future__ import annotations

from bisect import bisect_right
from typing import Mapping, Optional, Sequence

from .entity_clock import install_episodes, new_rule
from .episodes import Strength
from .host import HostBuffer
from .limits import Limits
from .queue import UNKNOWN_ORIGIN, Origin, Queue, QueueItem, TracedItem, is_origin
from .trace import Trace, activation


def snapshot(wm: HostBuffer) -> dict[str, list[str]]:
    """Return every non-empty queue, LRU first, keyed by entity (insertion order; :meth:`WMBuffer.snapshot`)."""
    wm.flush()
    store = wm.store
    get = store.get
    if not store.columns.entities:
        return {e: list(get(e)) for e in store.holding()}
    return {e: list(store.row_of(e)) if store.in_columns(e) else list(get(e)) for e in store.holding()}


def export_queue(wm: HostBuffer, entity: str) -> list[QueueItem]:
    """Return Q[entity] as :class:`QueueItem` items, LRU first.

    ``hits`` is the LFU count (1 when LFU is not in force); ``cause`` and ``turn``
    the entry's origin (:meth:`WMBuffer.origins`).  Under rule ``activation`` each
    item is a :class:`TracedItem`, with the entry's encoding history.
    """
    q = wm.readable(entity)
    if not q:
        return []
    if wm.activation is not None:
        traces = entry_traces(wm, entity)
        return [TracedItem(*item, traces[item[0]].to_json()) for item in _items(wm, q)]
    return _items(wm, q)


def entry_traces(wm: HostBuffer, entity: str) -> dict:
    """Return each entry of Q[entity]'s encoding history (:class:`Trace`) under rule ``activation``.

    The queue must be caught up (read through :meth:`WMBuffer.readable`); dict or column form alike.
    """
    store = wm.store
    return store.columns.traces_of(entity) if store.in_columns(entity) else wm.activation.traces_of(entity)


def strengths(wm: HostBuffer, entity: str) -> list[Strength]:
    """Return how strongly each entry of Q[entity] is held, LRU first (:meth:`WMBuffer.strength`).

    Its episode age and count (:mod:`.episodes`) and, under rule ``activation``, its
    activation on the rule's own clock (the entity's under ``episodes`` or ``words``).
    """
    stamps = wm.entry_stamps(entity)
    counted = wm.episodes.strength(entity, stamps)
    if wm.episode_activation is not None and counted:
        return [Strength(age, n, a) for (age, n), a in zip(counted, wm.episode_activation.strength(entity, stamps))]
    if wm.activation is None or not counted:
        return [Strength(age, n) for age, n in counted]
    d, clock = wm.limits.activation[0], wm.activation.now_of(entity)  # type: ignore[index]
    traces = entry_traces(wm, entity)  # the rule's own traces, not copies through JSON
    return [Strength(age, n, activation(traces[entry.property], clock, d)) for (age, n), entry in zip(counted, stamps)]


def _items(wm: HostBuffer, q: Mapping) -> list[QueueItem]:
    hits = ((q.hits if q.__class__ is Queue else None) or {}).get  # a column queue's copy has none (LRU)
    starts, runs = wm.origin_log.starts, wm.origin_log.runs
    items = []
    for prop, value in q.items():  # OriginLog.of and QueueItem(...) inlined: a store exports thousands
        if value.__class__ is int:
            stamp = ref = value
        else:
            stamp, ref = value
        origin = runs[bisect_right(starts, ref) - 1] if ref.__class__ is int else ref
        items.append(tuple.__new__(QueueItem, (prop, stamp, hits(prop, 1), origin[0], origin[1])))
    return items


def restore(wm: HostBuffer, queues: Mapping[str, Sequence[Sequence]], stamp: int, ticks: int, limits: Limits) -> None:
    """Replace ``wm``'s state with a stored one (queues LRU first, no events, no changes).

    Items are :class:`QueueItem` (or tuples of its five fields) or
    :class:`TracedItem`; items of only ``(property, stamp, hits)``, from a store that
    kept no origins, get origin :data:`UNKNOWN_ORIGIN`.  Under rule ``activation`` an
    entry stored without a trace counts as encoded once, at the latest time any
    stored trace names (0 if none does).  The queues are taken as up to date with ``ticks`` decay
    ticks; ``limits`` are installed without trimming (the stored queues already
    respect them).  The change record is cleared: the state now equals the stored one.
    ValueError, changing nothing, for a malformed queue or limits.
    """
    limits.check()
    traces: dict[tuple[str, str], Trace] = {}
    for entity, items in queues.items():  # all checked before anything changes
        if not isinstance(entity, str):
            raise ValueError(f"queue of {entity!r}: an entity is named by a string")
        for item in items:
            if len(item) not in (3, 5, 6) or len(item) >= 5 and not is_origin(item[3], item[4]):
                raise ValueError(f"queue of {entity!r}: item {item!r} is not (property, stamp, hits, cause, turn)")
            if len(item) == 6:
                traces[(entity, item[0])] = Trace.from_json(item[5])  # ValueError if malformed
    wm.limits = limits
    wm.interference.install(limits)
    store = wm.store
    store.reset(stamp)
    wm.changes.clear()
    wm.lazy_decay.reset(ticks)
    wm.origin_log.clear()
    shared: dict[Origin, Origin] = {}  # one origin object per distinct (cause, turn)
    for entity, items in queues.items():
        entries: dict[str, tuple] = {}
        counts: Optional[dict[str, int]] = {} if limits.victim == "lfu" and len(items) else None
        for item in items:
            prop, prop_stamp, hits = item[0], item[1], item[2]
            origin = (item[3], item[4]) if len(item) >= 5 else UNKNOWN_ORIGIN
            entries[prop] = (prop_stamp, shared.setdefault(origin, origin))
            if counts is not None:
                counts[prop] = hits
        store.load(entity, entries, counts, ticks)
    wm.activation = store.keeper = None
    install_episodes(wm, limits, fresh=True)
    if limits.activation is not None:
        latest = max((t.recent[-1] for t in traces.values()), default=0.0)  # (on the rule's own clock)
        act = wm.activation = store.keeper = new_rule(wm, limits, latest if limits.activation_clock == "seconds"
                                                      else 0.0)
        for entity in store.holding():
            act.adopt(entity, store.get(entity), latest, {p: t for (e, p), t in traces.items() if e == entity})
