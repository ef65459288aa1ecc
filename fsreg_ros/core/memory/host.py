"""What the buffer's collaborators use of it: :class:`HostBuffer`, a protocol.

:class:`~fsreg_ros.core.memory.buffer.WMBuffer` holds its collaborators (lazy decay and
activation, interference, the origin log, the change record, the column queues) and
hands each itself; persistence's functions take it too.  They annotate it with this
protocol rather than with ``WMBuffer``, so that no collaborator imports the module that
imports them all (the package's import graph has no circle; ``test/project/test_layers.py``
checks).  The buffer's own state and primitives are typed here; the collaborators it
holds are typed ``Any`` for the same reason, their comments naming the class.
"""

from __future__ import annotations

from typing import Any, Mapping, Optional, Protocol

from .ticks import TickLedger
from .limits import Limits
from .queue import EventSink, Queue


class HostBuffer(Protocol):
    """A domain's WM buffer as its collaborators see it (:class:`~.buffer.WMBuffer` is the one)."""

    domain: str
    sink: Optional[EventSink]
    attributes: dict[str, str]  # property -> attribute (similarity)
    limits: Limits
    column_min: int
    _queues: dict[str, Queue]  # the dict queues
    _nonempty: dict[str, None]  # queues that may hold something (insertion-ordered set)
    _stamp: int
    _size: int
    lazy_decay: Any  # LazyDecay (.decay)
    activation: Any  # Optional[LazyActivation] (.activation)
    interference: Any  # Interference (.displacement)
    origin_log: Any  # OriginLog (.origins)
    changes: Any  # ChangeRecord (.changes)
    columns: Any  # ColumnQueues (.columns)

    @property
    def ticks(self) -> TickLedger:
        """Every decay tick given so far."""

    def front_stamp(self, entity: str) -> int:
        """Stamp of Q[entity]'s front."""

    def flush(self) -> None:
        """Bring every queue up to date with the ticks and the clock."""

    def _readable(self, entity: str) -> Optional[Mapping]: ...

    def _new_queue(self, entity: str) -> Queue: ...

    def _pop(self, entity: str, cause: str, time: float, turn: Optional[int]) -> Optional[str]: ...

    def _forget_all(self, cause: str, time: float, turn: Optional[int]) -> None: ...

    def _forget(self, entity: str, q: Queue, prop: str, cause: str, time: float, turn: Optional[int]) -> None: ...
