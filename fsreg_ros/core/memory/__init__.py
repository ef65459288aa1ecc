"""Working memory: one buffer of per-entity property queues per domain (the paper's WM).

What lives where (one module per job; each docstring says what it owns):

=================  ================================================================
``buffer``         :class:`WMBuffer`: the queues, Encode (Algorithm 1), reads, the
                   forgetting primitives (pop a front, remove, forget everything)
``queue``          :class:`Queue` (Q[entity]) and its entries, :class:`WMEvent`,
                   :class:`QueueItem`, origins, the event causes
``limits``         :class:`Limits`: what the WM Manager lets a buffer hold
``install``        installing new limits: applied to every queue at once
``decay``          decay's pops (Algorithm 2): lazy catch-up, flush, eager ticks, and
                   the column queues' pops
``ticks``          decay's clock: the tick schedule and tick arithmetic (when tick n was)
``bitset``         sets of a domain's entities as int bitsets over entity indices
``displacement``   interference: displacement (Algorithm 3) and its victims,
                   similarity, the global limit, the shared pool's eviction
``origins``        the origin log: which encoding made each entry enter its queue
``episodes``       reference episodes: each entity's episode counter, the episodes its
                   entries were used in (:class:`Strength`), rule ``episodes``
``changes``        the change record: which queues changed since they were persisted
``columns``        column queues (numpy) for rule 2 and 3 encodings in a large domain
                   (with ``activation``'s traces, :class:`~.activation.TraceColumns`)
``persistence``    export of queues and restore from a store; the snapshot of all queues
``host``           :class:`HostBuffer`: what the collaborators above use of the buffer
                   (a protocol, so that none imports ``buffer``)
=================  ================================================================

*What* is forgotten, and when, is decided by the WM Manager
(:mod:`fsreg_ros.core.forgetting.wm_manager`, with the policies of
:mod:`fsreg_ros.core.forgetting.policies`): it sets the buffer's :class:`Limits` (data) and
gives it decay ticks; the buffer enforces them.  This package imports neither of
those (dependencies run one way), nor anything else of the core.
"""

from .buffer import WMBuffer
from .episodes import Strength
from .columns import COLUMN_MAX_SLOTS, COLUMN_MAX_WIDTH, COLUMN_MIN, QueueColumns
from .limits import UNLIMITED, VICTIMS, Limits, attribute_of
from .queue import (
    ENCODE_CAUSES, FORGET_CAUSES, UNKNOWN_ORIGIN, EventSink, Origin, Queue, QueueItem, WMEvent,
)

__all__ = [
    "WMBuffer", "Limits", "UNLIMITED", "VICTIMS", "attribute_of", "WMEvent", "EventSink", "Origin", "UNKNOWN_ORIGIN",
    "QueueItem", "Queue", "ENCODE_CAUSES", "FORGET_CAUSES", "COLUMN_MIN", "COLUMN_MAX_WIDTH", "COLUMN_MAX_SLOTS",
    "QueueColumns", "Strength",
]
