"""The consultant port: what reference resolution and REG may ask of a domain's consultant.

The algorithms (:mod:`~fsreg_ros.core.algorithms.resolution`, :mod:`~fsreg_ros.core.algorithms.generation`)
talk to consultants only through the small asynchronous :class:`ConsultantPort`
interface, so one implementation of each algorithm serves both worlds: in-process,
:class:`~fsreg_ros.core.consultant.local_port.LocalPort` answers at once and :func:`run_sync`
drives the algorithm without an event loop; in the ROS graph,
:class:`~fsreg_ros.ros.remote.RemotePort` awaits service calls to consultant nodes.

This module owns the port protocol and what travels through it: a request opens a
:class:`View` (the consultant keeps the candidate or distractor set), narrows it
(:class:`Step`, :class:`Narrowed`) or walks it (:class:`WalkStep`, :class:`Walked`),
and closes it.  :class:`Walk` is the incremental walk's rules (the loop SD-PIA's two
phases and RR's description run, docs/semantics.md section 4): the consultant runs it
in one call, :func:`walk_by_narrowing` over any port as one narrowing per step.

It also owns :class:`KnowledgeError`, what a consultant raises for a query or update it
cannot answer.  It imports nothing but the WM types it reports (:mod:`~fsreg_ros.core.memory`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Coroutine, Optional, Protocol, Sequence, TypeVar

from ..memory import Origin, Strength


class KnowledgeError(ValueError):
    """A query or update names something the domain does not know, or is malformed.

    The message says what and where; the consultant's state is unchanged.  Raised by a
    consultant and by the algorithms over the port alike, so it lives with the port.
    """

    def __init__(self, message: str = "", kind: Optional[str] = None) -> None:
        super().__init__(message)
        #: The ``kind`` an error reply on a topic carries (``unknown-entity``, ...); None: the class name.
        self.kind = kind


@dataclass
class View:
    """One RR or REG request's open candidate (or distractor) set at a consultant.

    ``handle`` names the set to the port (a :class:`CandidateSet` in-process, a
    session id over the graph); ``size`` is how many members it had when opened;
    ``queue`` is Q[target] at that moment (REG's ``wm_before``; empty without a
    target); ``retains`` whether the domain's WM retains anything (policy not
    ``none``), which is what lets REG choose between SD-PIA and DIST-PIA;
    ``holding`` the properties that hold for the target (None without one), so REG
    asks nothing about a property it would skip; ``origins`` the ``(cause, turn)``
    of the encoding that made each property of ``queue`` enter Q[target], parallel
    to ``queue`` (:meth:`~fsreg_ros.core.memory.WMBuffer.origins`; empty without a target);
    ``strength`` how strongly each entry of ``queue`` is held, parallel to it
    (:meth:`~fsreg_ros.core.memory.WMBuffer.strength`; empty without a target).
    """

    handle: Any
    size: int
    queue: list[str]
    retains: bool
    holding: Optional[frozenset[str]] = None
    first: Optional["Narrowed"] = None  # what the first step given to open did
    origins: list[Origin] = field(default_factory=list)
    strength: list[Strength] = field(default_factory=list)


@dataclass(frozen=True)
class Step:
    """One narrowing step: a property, its encoding cause (None: none), when and in which turn."""

    prop: str
    cause: Optional[str]
    time: float = 0.0
    turn: Optional[int] = None


@dataclass(frozen=True)
class Reference:
    """REG's act of referring to a view's target, begun when the view opens (docs/semantics.md section 2).

    The target's next reference episode begins at ``time`` in ``turn``, before the view
    reads Q[target].  ``id`` names the act: an open whose ``id`` began the target's current
    episode begins no other (a retried request); None: every such open begins one.
    """

    time: float = 0.0
    turn: Optional[int] = None
    id: Optional[str] = None


@dataclass(frozen=True)
class Narrowed:
    """What one :meth:`ConsultantPort.narrow` did: whether the target holds, members left."""

    target_holds: bool
    size: int


@dataclass(frozen=True)
class WalkStep:
    """One property a :class:`Walk` may narrow by; ``group`` (its attribute) is skipped once a step of it was taken."""

    prop: str
    group: Optional[str] = None


@dataclass(frozen=True)
class Walked:
    """What a walk did: the indices of the steps taken (in order), members left, and steps narrowed by."""

    taken: tuple[int, ...]
    size: int
    narrowed: int


class Walk:
    """The incremental walk: narrow a view by candidate properties in order until no member is left.

    The loop of the Incremental Algorithm as SD-PIA runs it over a consultant (its Phase 1
    and Phase 2 are one walk over WM's properties, then LTM's in preference order) and as
    reference resolution runs it over a heard description.  A step is *taken* when the
    target holds (always, without one) and it left fewer members; a step whose ``group``
    was taken already is skipped, asking nothing (a description never holds two values of
    one attribute); nothing is asked once no member is left.  The walk only decides; its
    driver narrows (:meth:`~fsreg_ros.core.consultant.service.ConsultantService.walk` in the
    consultant, :func:`walk_by_narrowing` over any port), so both run the same rules.
    """

    def __init__(self, steps: Sequence[WalkStep], size: int) -> None:
        self.steps = steps
        self.size = size
        self._next = 0
        self._taken: list[int] = []
        self._groups: set[str] = set()
        self._narrowed = 0

    def next(self) -> Optional[WalkStep]:
        """Return the next step to narrow by, or None when the walk is over."""
        while self.size and self._next < len(self.steps):
            step = self.steps[self._next]
            if step.group is None or step.group not in self._groups:
                return step
            self._next += 1
        return None

    def record(self, narrowed: Narrowed) -> None:
        """Take in what narrowing by the step :meth:`next` returned did."""
        step = self.steps[self._next]
        if narrowed.target_holds and narrowed.size < self.size:
            self._taken.append(self._next)
            if step.group is not None:
                self._groups.add(step.group)
        self.size = narrowed.size
        self._narrowed += 1
        self._next += 1

    def result(self) -> Walked:
        return Walked(tuple(self._taken), self.size, self._narrowed)


async def walk_by_narrowing(
    port: "ConsultantPort", view: View, steps: Sequence[WalkStep], cause: Optional[str], time: float,
    turn: Optional[int], size: Optional[int] = None,
) -> Walked:
    """Run a :class:`Walk` as one :meth:`ConsultantPort.narrow` per step (ports without a walk of their own).

    ``size``: the view's members now (default: when it was opened).
    """
    walk = Walk(steps, view.size if size is None else size)
    while (step := walk.next()) is not None:
        walk.record(await port.narrow(view, step.prop, cause, time, turn))
    return walk.result()


class ConsultantPort(Protocol):
    """What reference resolution and REG may ask of a domain's consultant.

    A request opens a :class:`View` (the consultant keeps the candidate or
    distractor set), narrows it by the properties it considers, and closes it; no
    entity list travels per call.  :meth:`walk` narrows by several properties in one
    call (the graph's consultant runs the :class:`Walk` itself), so a request costs
    three calls however many properties it considers.
    """

    domain: str

    async def preference(self) -> list[str]:
        """Return the domain's preference order, most preferred first."""

    async def open(
        self, target: Optional[str] = None, context: Optional[Sequence[str]] = None, first: Optional[Step] = None,
        refer: Optional[Reference] = None,
    ) -> View:
        """Open a view: every entity (RR), or the target's distractors (REG).

        See :meth:`~fsreg_ros.core.consultant.consultant.Consultant.open_set`.

        With ``first``, narrow it by that step at once (RR's first property: one call
        opens the view and checks it); the view's ``first`` says what that did.  With
        ``refer`` (REG; needs a target), the target's next reference episode begins
        before the view reads Q[target], and its close begins none (:class:`Reference`).
        """

    async def narrow(self, view: View, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> Narrowed:
        """Keep the members ``prop`` holds for, encoding it for each (``cause`` None: no encoding).

        With a target, only if ``prop`` holds for the target (see
        :meth:`~fsreg_ros.core.consultant.consultant.Consultant.narrow`).
        """

    async def walk(self, view: View, steps: Sequence[WalkStep], cause: Optional[str], time: float,
                   turn: Optional[int], size: Optional[int] = None) -> Walked:
        """Run a :class:`Walk` over ``steps`` (each narrowing as :meth:`narrow` does); ``size``: members now."""

    async def rule_out(self, view: View) -> tuple[list[str], list[int]]:
        """Return each property holding for the target and the members it rules out (by member rank)."""

    async def close(
        self, view: View, encode: Sequence[str] = (), time: float = 0.0, turn: Optional[int] = None
    ) -> list[str]:
        """Close the view; return its members (entity order).

        With ``encode``: Encode(x, encode) with cause ``speaker`` (rule 1) first, where x
        is the view's target, or, without one, its only member.
        """


T = TypeVar("T")


def run_sync(coroutine: Coroutine[Any, Any, T]) -> T:
    """Run an algorithm coroutine whose ports answer at once (e.g. :class:`~.local_port.LocalPort`).

    No event loop is needed: a coroutine that never suspends finishes on its first
    step.  One that does suspend was given a port that does real I/O; that is a
    programming error, reported as such.
    """
    try:
        coroutine.send(None)
    except StopIteration as done:
        return done.value
    coroutine.close()
    raise RuntimeError("run_sync: the algorithm awaited real I/O; use an event loop or executor")
