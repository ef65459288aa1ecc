"""The WM Manager: the one place that decides what each domain forgets, I/O-free.

It owns each domain's :class:`~fsreg_ros.core.forgetting.policies.ForgettingPolicy` and
:class:`~fsreg_ros.core.memory.ticks.DecaySchedule` and decides what to send, through a
small :class:`MemoryPort` (as :class:`~fsreg_ros.core.algorithms.port.ConsultantPort`
does for the algorithms):

* ``configure(domain, policy, time)``: install a policy in the domain's buffer (its
  limits apply at once: trims, ``none`` empties WM);
* ``decay(domain, ticks)``: apply a :class:`~fsreg_ros.core.memory.ticks.TickRun`;
* ``advance(domain, time)``: the clock reached ``time`` (rule ``activation``: its
  entries below the threshold are forgotten at their crossing times).

:class:`BufferPort` applies them in-process to :class:`~fsreg_ros.core.memory.WMBuffer`
objects (the simulator; decay lazily, ``WMBuffer.decay``); the ``wm_manager`` node's
port sends them to the consultants' manage services, where :func:`configure_buffer`
and :meth:`~fsreg_ros.core.consultant.service.ConsultantService.decay_now` (eagerly,
``WMBuffer.decay_now``, which gives the same queues) apply them.

Time: the decay grid's origin is the manager's clock when it starts managing
(``origin``; 0 for the simulator, and for a sim-time graph before the first
``/clock``), so ticks fall at ``origin + k * delta``.  A new decay period restarts
the grid at the change.  Ticks due before a domain's consultant is first attached
are not owed (its WM was empty).  A consultant that goes away is detached; the
ticks that fall due meanwhile are kept (as a few runs, never a list of ticks) and
sent when it is attached again (:meth:`WMManager.attach`), after which it is
configured.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Optional, Protocol, Sequence

from ..memory.ticks import TIME_EPSILON, DecaySchedule, TickError, TickRun, check_time
from .policies import ForgettingPolicy
from ..memory import WMBuffer

#: How far ahead of the manager's own clock a sync time may be, seconds (one day):
#: a scripted replay jumps from turn to turn, but a time further out is a fault.
SYNC_AHEAD = 86_400.0


class MemoryPort(Protocol):
    """What the WM Manager sends to the buffer of a domain."""

    def configure(self, domain: str, policy: ForgettingPolicy, time: float) -> None:
        """Install ``policy`` in the domain's buffer at ``time``."""

    def decay(self, domain: str, ticks: TickRun) -> None:
        """Apply decay ticks to the domain's buffer."""

    def advance(self, domain: str, time: float) -> None:
        """Tell the domain's buffer the clock reached ``time`` (rule ``activation``: entries below tau go)."""

    def evict(self, domain: str, count: int, time: float) -> None:
        """Forget the domain's ``count`` least recently encoded fronts (shared pool)."""

    def sizes(self, domains: Sequence[str]) -> Optional[dict[str, int]]:
        """Return how many properties each domain holds, or None if that needs I/O.

        On None the caller asks the buffers and calls :meth:`WMManager.share` itself.
        """


def configure_buffer(buffer: WMBuffer, policy: ForgettingPolicy, time: float) -> None:
    """Install a policy's limits in a buffer; they apply to every queue at once."""
    buffer.set_limits(policy.validated().limits(), time)


def unapplied(ticks: TickRun, applied_until: float) -> Optional[TickRun]:
    """Return the part of ``ticks`` later than ``applied_until`` (the last tick applied), or None.

    Tick times only grow, so a run sent again (after a consultant restart or a lost
    reply) is applied at most once: O(1), whatever the run's length.
    """
    if ticks.last <= applied_until + TIME_EPSILON:
        return None
    if ticks.time(0) > applied_until + TIME_EPSILON:
        return ticks
    skip = int((applied_until + TIME_EPSILON - ticks.origin) / ticks.period) - ticks.first + 1
    while skip > 0 and ticks.time(skip - 1) > applied_until + TIME_EPSILON:  # float rounding
        skip -= 1
    while skip < ticks.count and ticks.time(skip) <= applied_until + TIME_EPSILON:
        skip += 1
    return ticks.tail(max(skip, 0))


class BufferPort:
    """A :class:`MemoryPort` over in-process buffers (decay applied lazily)."""

    def __init__(self) -> None:
        self.buffers: dict[str, WMBuffer] = {}

    def configure(self, domain: str, policy: ForgettingPolicy, time: float) -> None:
        configure_buffer(self.buffers[domain], policy, time)

    def decay(self, domain: str, ticks: TickRun) -> None:
        self.buffers[domain].decay(ticks)

    def advance(self, domain: str, time: float) -> None:
        self.buffers[domain].advance(time)

    def evict(self, domain: str, count: int, time: float) -> None:
        self.buffers[domain].evict_oldest(count, "shared-capacity", time)

    def sizes(self, domains: Sequence[str]) -> Optional[dict[str, int]]:
        return {d: len(self.buffers[d]) for d in domains}


@dataclass
class ManagedDomain:
    """The WM Manager's view of one domain."""

    policy: ForgettingPolicy
    schedule: Optional[DecaySchedule] = None
    attached: bool = False  # the buffer's owner is configured (or being configured)
    ever_attached: bool = False
    incarnation: object = None
    owed: list[TickRun] = field(default_factory=list)  # ticks due while detached


class WMManager:
    """Forgetting policies and decay schedules of every managed domain."""

    def __init__(self, port: Optional[MemoryPort] = None, origin: float = 0.0) -> None:
        self.port: MemoryPort = port if port is not None else BufferPort()
        self.origin = check_time("origin", origin)
        self.domains: dict[str, ManagedDomain] = {}

    @property
    def policies(self) -> dict[str, ForgettingPolicy]:
        return {d: s.policy for d, s in self.domains.items()}

    # ------------------------------------------------------------ management
    def manage(self, buffer: WMBuffer, policy: ForgettingPolicy, now: float = 0.0) -> None:
        """Take an in-process buffer under management (the port must be a BufferPort)."""
        self.port.buffers[buffer.domain] = buffer  # type: ignore[attr-defined]
        self.manage_domain(buffer.domain, policy, now)
        self.attach(buffer.domain, None, now)

    def manage_domain(self, domain: str, policy: ForgettingPolicy, now: float) -> None:
        """Take a domain under management, detached (nothing is sent until :meth:`attach`)."""
        self.domains[domain] = ManagedDomain(policy.validated())
        self._install_schedule(self.domains[domain], None, now)

    def attach(self, domain: str, incarnation: object, now: float) -> None:
        """Attach a domain whose buffer is (again) reachable.

        Send the ticks owed since it was detached, then its policy.  ``incarnation``
        identifies the buffer's owner (e.g. a restarted consultant's).
        """
        state = self.domains[domain]
        self.advance_domain(domain, now)
        state.attached = state.ever_attached = True
        state.incarnation = incarnation
        owed, state.owed = state.owed, []
        for ticks in owed:
            self.port.decay(domain, ticks)
        self.port.configure(domain, state.policy, now)

    def owe(self, domain: str, ticks: TickRun) -> None:
        """Keep ``ticks`` sent but not acknowledged (the consultant went away): send them again on attach.

        The owed runs stay in time order; the consultant skips ticks it had applied.
        """
        state = self.domains[domain]
        state.owed.append(ticks)
        state.owed.sort(key=lambda run: run.time(0))

    def detach(self, domain: str) -> None:
        """Detach a domain whose buffer is unreachable: keep the ticks due until it is back."""
        self.domains[domain].attached = False

    def set_policy(self, domain: str, policy: ForgettingPolicy, now: float) -> None:
        """Change a domain's policy; it takes effect at once.

        Limits trim every queue, ``none`` empties the domain, a new decay period
        restarts the schedule.
        """
        policy = policy.validated()
        state = self.domains[domain]
        self.advance_domain(domain, now)  # ticks due under the old schedule happen first
        old, state.policy = state.policy, policy
        self._install_schedule(state, old, now)
        if state.attached:
            self.port.configure(domain, policy, now)

    # ------------------------------------------------------------------ time
    def check_sync_time(self, t: object, now: float) -> float:
        """Return a time a caller asks the manager to catch up to, checked.

        TickError if it is not a finite number within :data:`SYNC_AHEAD` of the
        manager's clock ``now``.
        """
        t = check_time("time", t)
        if t > now + SYNC_AHEAD:
            raise TickError(f"time {t!r} is more than {SYNC_AHEAD:g} s ahead of the WM Manager's clock ({now!r})")
        return t

    def advance(self, now: float) -> dict[str, int]:
        """Catch up to a dialogue event at ``now``: decay ticks, then the shared pool.

        Apply every decay tick due at or before ``now`` in every decaying domain,
        then trim the shared pool (if the port can tell sizes at once; otherwise the
        caller does, with :meth:`share`).  Return how many ticks fell due per domain.
        """
        applied = {domain: self.advance_domain(domain, now) for domain in self.domains}
        sharing = self.sharing()
        if sharing:
            sizes = self.port.sizes(sharing)
            if sizes is not None:
                self.share(sizes, now)
        return applied

    @property
    def clock_driven(self) -> bool:
        """Tell whether :meth:`advance` can forget anything in a managed domain.

        True when one decays (its ticks), forgets by rule ``activation`` on the seconds
        clock, or is in the shared pool (trimmed when the manager catches up).  Otherwise
        catching up changes nothing a read of WM sees (on an entity's own clock, rule
        ``activation`` forgets only when that clock moves; the seconds it is told only
        stamp those forgettings, and every encoding tells its own), so a caller may skip it.
        """
        return any(state.policy.clock_driven for state in self.domains.values())

    def sharing(self) -> list[str]:
        """Return the domains in the shared pool (policy ``shared-capacity``), in domain order."""
        return [d for d, state in self.domains.items() if "shared-capacity" in state.policy.rules]

    def share(self, sizes: Mapping[str, int], now: float) -> dict[str, int]:
        """Trim the shared pool, given each member domain's size; return the evictions.

        While the pool holds more than the smallest ``shared_capacity`` of its
        members, the domain holding the most (the first in domain order on ties)
        forgets its least recently encoded front.
        """
        sharing = self.sharing()
        if not sharing:
            return {}
        limit = min(self.domains[d].policy.value("shared_capacity") for d in sharing)  # type: ignore[type-var]
        left = {d: int(sizes.get(d, 0)) for d in sharing}
        evictions: dict[str, int] = {}
        excess = sum(left.values()) - limit  # type: ignore[operator]
        while excess > 0:
            domain = max(sharing, key=left.__getitem__)
            left[domain] -= 1
            evictions[domain] = evictions.get(domain, 0) + 1
            excess -= 1
        for domain, count in evictions.items():
            if self.domains[domain].attached:
                self.port.evict(domain, count, now)
        return evictions

    def advance_domain(self, domain: str, now: float) -> int:
        """Send the domain's ticks due at or before ``now`` not sent yet; how many.

        Under rule ``activation`` (no ticks), send the clock instead, so entries whose
        activation fell below the threshold are gone before the event at ``now``.
        """
        state = self.domains[domain]
        if state.policy.activates:
            if state.attached:
                self.port.advance(domain, now)
            return 0
        ticks = state.schedule.take(now) if state.schedule is not None else None
        if ticks is None:
            return 0
        if state.attached:
            self.port.decay(domain, ticks)
        elif state.ever_attached:  # WM may hold something: owed when it is back
            if state.owed and ticks.continues(state.owed[-1]):
                last = state.owed[-1]
                state.owed[-1] = TickRun(last.origin, last.period, last.first, last.count + ticks.count)
            else:
                state.owed.append(ticks)
        return ticks.count

    def next_tick(self, domain: str) -> Optional[float]:
        schedule = self.domains[domain].schedule
        return schedule.next_tick() if schedule is not None else None

    def effective(self) -> dict[str, dict]:
        """Each domain's effective setting, keyed by domain (docs/semantics.md section 6 ``memory``)."""
        return {d: self.domains[d].policy.to_json() for d in sorted(self.domains)}

    # ------------------------------------------------------------- internals
    def _install_schedule(self, state: ManagedDomain, old: Optional[ForgettingPolicy], now: float) -> None:
        policy = state.policy
        if not policy.decays:
            state.schedule = None
        elif state.schedule is None:
            # Decay switched on: ticks on the origin + k * delta grid; ticks before
            # now are not owed.
            state.schedule = DecaySchedule(policy.value("decay_period"), origin=self.origin)  # type: ignore[arg-type]
            state.schedule.skip(now)
        elif old is not None and old.value("decay_period") != policy.value("decay_period"):
            state.schedule.restart(policy.value("decay_period"), now)  # type: ignore[arg-type]
