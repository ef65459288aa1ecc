"""Installing new limits in a buffer: applied to every queue at once (docs/semantics.md section 7).

:meth:`WMBuffer.set_limits` runs :func:`install_limits` when the WM Manager changes a
domain's :class:`~fsreg_ros.core.memory.limits.Limits`: the column queues are given up
when the new limits are beyond them, displacement and activation are installed, the
LFU counts restart, and what the new limits no longer allow is forgotten now (not
retaining: everything, cause ``reset``; a capacity: each queue trimmed, Algorithm 3; a
global limit: the domain trimmed).  After every later encoding event the limits are
enforced by :mod:`fsreg_ros.core.memory.displacement`.
"""

from __future__ import annotations

from .entity_clock import install_episodes, new_rule
from .host import HostBuffer
from .limits import Limits


def install_limits(wm: HostBuffer, limits: Limits, time: float) -> None:
    """Install ``limits`` in ``wm`` and apply them to every queue at once.

    Similarity applies from the next encoding on.  Queues are trimmed one after the
    other, in no specified order (what each loses depends on itself only; the global
    victims on stamps only).
    """
    limits.check()
    if not wm.store.columns.fits(limits, wm.limits):
        wm.store.drop()
    wm.limits = limits
    wm.interference.install(limits)
    install_activation(wm, limits, time)
    install_episodes(wm, limits)
    for entity, q in wm.store.dict_queues():
        hits = q.hits
        if hits is not None:  # the LFU counts restart: an exported count may change
            if any(hits.get(prop, 1) != 1 for prop in q):
                wm.changes.record(entity, q)
            q.hits = None
    if not limits.retains:
        wm.forget_everything("reset", time, None)
        return
    if limits.capacity is not None:
        wm.flush()
        for entity, q in wm.store.dict_queues():
            wm.interference.displace(entity, q, limits.capacity, "", time, None)
    if limits.global_capacity is not None:
        wm.interference.evict_global(limits.global_capacity, time, None)


def install_activation(wm: HostBuffer, limits: Limits, time: float) -> None:
    """Start, change or stop ``wm``'s activation rule per ``limits``; entries without a trace get one at ``time``.

    On another clock than the old rule's, no trace is kept (their times are another
    clock's): each entry counts as encoded once, now (:mod:`.entity_clock`).
    """
    old = wm.activation
    if limits.activation is None:
        wm.activation = wm.store.keeper = None
        return
    wm.flush()
    act = new_rule(wm, limits, max(time, old.clock) if old is not None else time)
    same = old is not None and old.counting == act.counting
    if same:
        act.carry_clocks(old)  # type: ignore[arg-type]
    for entity in wm.store.holding():
        q = wm.store.get(entity)
        if q is not None:  # a column queue keeps its traces (the limits' d and tau did not change: columns.fits)
            act.adopt(entity, q, time, old.traces_of(entity) if same else None)  # type: ignore[union-attr]
    wm.activation = wm.store.keeper = act
