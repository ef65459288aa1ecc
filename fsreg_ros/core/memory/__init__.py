"""Working memory: one buffer of per-entity property queues per domain (the paper's WM).

What lives where (one module per job; each docstring says what it owns):

===================  ==============================================================
``buffer``           :class:`WMBuffer`: Encode (Algorithm 1), reads, the forgetting
                     primitives (pop a front, forget an entry, forget everything),
                     and the listeners (event sink, :class:`EntryWatcher` side logs)
``queues``           :class:`QueueStore`: the state. Every queue in dict or column
                     form, the size, the non-empty set, the stamp counter and each
                     queue's synced tick count, kept true by its own methods (put,
                     remove, drop fronts, column operations, moves between forms);
                     the quiet fast path of rules 2 and 3 (``encode_quiet``)
``queue``            :class:`Queue` (Q[entity]) and its entries, :class:`WMEvent`,
                     :class:`QueueItem`, origins, the event causes
``columns``          the column form (numpy) of rule 2 and 3 encodings' queues in a
                     large domain: the arrays (:class:`QueueColumns`) and which
                     entity's queue lives in which row (``ColumnQueues``)
``column_encoding``  the column paths of Encode and of reading (many rows at once,
                     rule 1 in a row), the same steps as the dict paths
``host``             the protocols the collaborators see each other and the buffer
                     by (:class:`~.host.HostBuffer`; none imports ``buffer``)
``limits``           :class:`Limits`: what the WM Manager lets a buffer hold
``install``          installing new limits: applied to every queue at once
``decay``            decay's pops (Algorithm 2): lazy catch-up, flush, eager ticks
``ticks``            decay's clock: the tick schedule and tick arithmetic
``displacement``     interference: displacement (Algorithm 3) and its victims,
                     similarity, the global limit, the shared pool's eviction
``activation``       rule ``activation``: the clock, each entry's trace, lazy pops
``entity_clock``     rule ``activation`` on each entity's own clock (its episodes,
                     decided at its boundaries; the words encoded for it, per
                     encoding) and those clocks' persistence
``trace``            one entry's ACT-R trace and its crossing time (arithmetic)
``trace_columns``    the traces of column queues' entries, one per slot (numpy), and
                     each row's own clock (words)
``crossings``        deciding many column entries' crossings at once (Newton, numpy)
``origins``          the origin log: which encoding made each entry enter its queue
``episodes``         reference episodes: each entity's episode counter, the episodes
                     its entries were used in (:class:`Strength`), rule ``episodes``
``changes``          the change record: which queues changed since they were persisted
``persistence``      export of queues and restore from a store; the snapshot of all queues
``bitset``           sets of a domain's entities as int bitsets over entity indices
===================  ==============================================================

Imports run one way, bottom to top: ``queue``, ``limits``, ``ticks``, ``bitset``,
``trace`` -> ``crossings`` -> ``trace_columns`` -> ``columns`` -> ``queues`` ->
``host`` -> the rules and records (``decay``, ``activation``, ``displacement``,
``origins``, ``episodes``, ``changes``, ``entity_clock``, ``install``, ``persistence``,
``column_encoding``) ->
``buffer`` -> this package.

**Adding a rule or a side log.**  A forgetting rule is one module over the store's
interface, seeing the buffer as :class:`~.host.HostBuffer`: it decides what goes and
forgets it with :meth:`WMBuffer.forget_entry` (or :meth:`WMBuffer.pop_entry`), which
keeps the store, the records and the listeners in step; a setting of the rule is a row
in :mod:`fsreg_ros.core.forgetting.settings` and a field of :class:`Limits`.  A
*side log* kept per entry (for instance reference episodes: which episodes each entry
was used in) is attached with :meth:`WMBuffer.watch` and hears, in event order, every
encoding (:meth:`EntryWatcher.encoded`: entity, property, cause, time, turn, refresh or not;
:attr:`QueueStore.stamp` is the stamp just given) and every forgetting, whatever the
cause (:meth:`EntryWatcher.forgot`, decay's lazy pops included).  A watcher may be a
forgetting rule itself, evaluated lazily as activation is: :meth:`EntryWatcher.sync`
is called on a queue before it is read or encoded into (after decay and activation
caught it up), :meth:`EntryWatcher.flush` before WM is read whole, and it forgets with
:meth:`WMBuffer.forget_entry` (``test/core/test_queue_store.py`` has a 30-line one).
While a watcher is attached the buffer takes its general paths, as with an event sink
(the quiet fast path and the column form are off), so the log needs no column code; a
per-call log (as the origin log: one run per encoding call) is called where
:meth:`WMBuffer.encode_each` and :mod:`.column_encoding` call
:meth:`OriginLog.log <.origins.OriginLog.log>`.  A
log that must survive a restart exports beside :meth:`WMBuffer.export_queue` (as
:class:`~.queue.TracedItem` carries activation's traces) and is rebuilt in
:func:`.persistence.restore`.

*What* is forgotten, and when, is decided by the WM Manager
(:mod:`fsreg_ros.core.forgetting.wm_manager`, with the policies of
:mod:`fsreg_ros.core.forgetting.policies`): it sets the buffer's :class:`Limits` (data) and
gives it decay ticks; the buffer enforces them.  This package imports neither of
those (dependencies run one way), nor anything else of the core.
"""

from .buffer import EntryWatcher, WMBuffer
from .episodes import Strength
from .columns import COLUMN_MAX_SLOTS, COLUMN_MAX_WIDTH, COLUMN_MIN, QueueColumns
from .limits import UNLIMITED, VICTIMS, Limits, attribute_of
from .queues import QueueStore
from .queue import (
    ENCODE_CAUSES, FORGET_CAUSES, UNKNOWN_ORIGIN, EventSink, Origin, Queue, QueueItem, WMEvent,
)

__all__ = [
    "WMBuffer", "EntryWatcher", "QueueStore",
    "Limits", "UNLIMITED", "VICTIMS", "attribute_of", "WMEvent", "EventSink", "Origin", "UNKNOWN_ORIGIN",
    "QueueItem", "Queue", "ENCODE_CAUSES", "FORGET_CAUSES", "COLUMN_MIN", "COLUMN_MAX_WIDTH", "COLUMN_MAX_SLOTS",
    "QueueColumns", "Strength",
]
