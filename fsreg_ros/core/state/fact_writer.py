"""The durable commit of LTM facts, off the thread that answers queries (group commit).

A consultant answers RR and REG on one thread; storing a batch of facts (a SQLite
transaction fsynced with ``synchronous=FULL``) costs a write to disk.  A
:class:`FactWriter` takes that cost on a thread of its own: the serving thread
*prepares* a batch (validates every fact against LTM as the facts already in flight
will leave it: :meth:`ConsultantService.prepare_facts
<fsreg_ros.core.consultant.service.ConsultantService.prepare_facts>`) and submits (:meth:`FactWriter.submit`)
it; the writer commits everything submitted meanwhile in ONE fsynced transaction (group
commit: at high rates one fsync serves many batches) and hands each batch back, in the
order submitted, through :meth:`FactWriter.take_done`; the serving thread then applies
it to memory and answers it (:meth:`ConsultantService.apply_facts
<fsreg_ros.core.consultant.service.ConsultantService.apply_facts>`).  So an acknowledgement goes
out only after its facts are on disk (what was acknowledged survives a restart) and
after they are in memory (a query answered after the acknowledgement sees them), and
queries are served while the disk works.

A commit that fails fails every batch in it, and every batch submitted before the
serving thread learnt of it (prepared against facts that will never be applied): each
comes back with the :class:`~fsreg_ros.core.state.store.StoreError` (nothing of it stored or
applied), so every sender hears a refusal.  Batches carry the ``generation`` of the
previews they were made against (:meth:`ConsultantService.abandon_facts
<fsreg_ros.core.consultant.service.ConsultantService.abandon_facts>` starts a new one); a failure
refuses every later-submitted batch of the failed generation or older.

Pure Python (threading); the node wakes its executor with ``notify`` (a guard
condition's trigger, which is safe to call from another thread).
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any, Callable, Optional, Sequence

from .store import StoreError


class FactWriter:
    """Commit submitted fact batches on a thread of its own, all those waiting in one transaction."""

    def __init__(self, commit: Callable[[Sequence[Any]], None], notify: Callable[[], None] = lambda: None,
                 name: str = "fact-writer") -> None:
        """Start the writer thread.

        ``commit(batches)`` stores the given batches in one transaction (raising
        StoreError, having stored nothing); it runs on the writer thread.  ``notify()``
        is called on the writer thread whenever batches are done (committed or failed).
        """
        self._commit = commit
        self._notify = notify
        self._cond = threading.Condition()
        self._queue: deque = deque()
        self._done: deque = deque()
        self._busy = False  # a commit is under way
        self._closing = False
        self._refused_upto = -1  # batches of this generation or older are refused (a commit of it failed)
        self.commits = 0  # transactions committed (a measure of grouping)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, batch: Any) -> None:
        """Queue ``batch`` (anything with an int ``generation``) for the next commit."""
        with self._cond:
            if self._closing:
                raise RuntimeError("the fact writer is closed")
            self._queue.append(batch)
            self._cond.notify_all()

    def take_done(self, most: Optional[int] = None) -> list[tuple[Any, Optional[StoreError]]]:
        """Return (batch, error or None) for the batches done since the last call, in submission order."""
        with self._cond:
            count = len(self._done) if most is None else min(most, len(self._done))
            return [self._done.popleft() for _ in range(count)]

    def has_done(self) -> bool:
        """Whether batches wait for :meth:`take_done`."""
        with self._cond:
            return bool(self._done)

    def in_flight(self) -> int:
        """Return the batches submitted and not yet taken back (queued, committing or done)."""
        with self._cond:
            return len(self._queue) + len(self._done) + (1 if self._busy else 0)

    def flush(self) -> None:
        """Wait until every batch submitted so far is committed (or failed); they are then in :meth:`take_done`."""
        with self._cond:
            while (self._queue or self._busy) and self._thread.is_alive():
                self._cond.wait()

    def close(self) -> None:
        """Commit what is queued, then stop the thread (idempotent)."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closing:
                    self._cond.wait()
                if not self._queue:
                    return  # closing, nothing left
                group = list(self._queue)
                self._queue.clear()
                self._busy = True
                refused_upto = self._refused_upto
            results = self._write(group, refused_upto)
            with self._cond:
                self._done.extend(results)
                self._busy = False
                self._cond.notify_all()
            try:
                self._notify()
            except Exception:  # noqa: BLE001 - a node shutting down; the batches stay in take_done
                pass

    def _write(self, group: list, refused_upto: int) -> list[tuple[Any, Optional[StoreError]]]:
        """Commit the batches of ``group`` that may be; return (batch, error) for each, in order."""
        earlier = StoreError("an earlier commit of facts failed (this batch was checked against its facts); "
                             "nothing of this one was stored or applied")
        usable = [b for b in group if b.generation > refused_upto]
        error: Optional[StoreError] = None
        if usable:
            try:
                self._commit(usable)
                self.commits += 1
            except StoreError as err:
                error = err
            except Exception as err:  # noqa: BLE001 - whatever SQLite raised: nothing was stored
                error = StoreError(f"{type(err).__name__}: {err}")
        if error is not None:
            with self._cond:
                self._refused_upto = max(self._refused_upto, max(b.generation for b in usable))
        return [(b, error if b.generation > refused_upto else earlier) for b in group]
