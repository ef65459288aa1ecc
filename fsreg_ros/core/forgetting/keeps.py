"""What a forgetting policy is sure to keep: the stretches of dialogue within which it forgets nothing.

A replay that evaluates a policy over a grid of its settings (``fsreg-eval reference-games``)
plays the same games through one WM buffer per grid point; a grid point under which the
buffer cannot forget anything in a game leaves the buffer of an unmanaged one (same queues,
stamps, episodes and strengths), so that game need not be played again under it.  Whether it
can is a property of each rule, so it is stated here, beside the rules, never by a caller:
:func:`keeps_everything` answers it for a :class:`Span`, what the stretch does to the buffer
when nothing is forgotten, measured from the moment the policy was installed (clock 0).

Per rule (a policy keeps everything when each of its rules does):

* ``decay``: no tick falls due: ``decay_period`` is beyond the span's last time (a tick k is
  due at ``k * decay_period``, docs/semantics.md section 7);
* ``activation``: one presentation alone stays ``exp(-tau / d)`` on the rule's clock
  (:func:`~fsreg_ros.core.memory.trace.lifetime`), and more presentations only raise an
  entry's activation, so an entry outlives the span when that lifetime exceeds it: its
  seconds, or (ages counting from 1 on an entity's own clock) its episodes + 1 or words + 1;
* ``displacement``, ``displacement-lfu``, ``displacement-random``: no queue ever holds more
  than ``capacity``;
* ``global-capacity``: the domain never holds more than ``global_capacity``;
* ``shared-capacity``: the pool never holds more than ``shared_capacity`` (``entries`` then
  counts every domain of the pool);
* ``episodes``: no entity has more than ``episode_window`` episodes (an entry goes only when
  episode n > k begins);
* any other rule (``similarity``, and a rule this module does not know), and a rule that reads
  more parameters than its promise here was written for (a new clock, say): no promise.

Every bound is kept with a margin (:data:`MARGIN`) where a clock's arithmetic is in floating
point, so a promise is never broken by a rounding.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence

from ..memory.limits import Limits
from ..memory.trace import lifetime
from .policies import RULE_PARAMETERS, ForgettingPolicy

#: Relative margin kept on the clock bounds (decay's tick test and activation's crossing are in floats).
MARGIN = 1e-6


@dataclass(frozen=True)
class Span:
    """What a stretch of dialogue does to one WM buffer if nothing is forgotten, from clock 0 on.

    ``seconds``: the clock's last time; ``entries``: the most properties held at once in all
    (for a shared pool: in all its domains); ``per_entity``: the most held at once by one
    entity's queue; ``episodes``: the most reference episodes one entity has; ``words``: the
    most encoding events into one entity's queue (refreshes included; a clock of words counts them).
    """

    seconds: float
    entries: int
    per_entity: int
    episodes: int
    words: int = 0


def _beyond(bound: float, span: Span) -> bool:
    return bound > span.seconds * (1 + MARGIN) + MARGIN


def _value(policy: ForgettingPolicy, rule: str) -> float:
    """Return the one parameter ``rule`` reads (decay's period, the shared pool's capacity: not in :class:`Limits`)."""
    return float(policy.value(RULE_PARAMETERS[rule][0]))  # type: ignore[arg-type]


def _activation(limits: Limits, span: Span) -> bool:
    """One presentation alone stays ``lifetime(d, tau)`` on the rule's clock; ages count from 1 on an entity's own."""
    if limits.episode_activation is not None:  # the episodes clock: at most episodes + 1 old within the span
        d, tau = limits.episode_activation
        return lifetime(d, tau) > (span.episodes + 1) * (1 + MARGIN)
    d, tau = limits.activation  # type: ignore[misc]
    if limits.activation_clock == "words":  # at most words + 1 old
        return lifetime(d, tau) > (span.words + 1) * (1 + MARGIN)
    return limits.activation_clock == "seconds" and _beyond(lifetime(d, tau), span)


#: Per rule: the parameters its promise was written for (a rule that reads others makes none, say a new
#: clock) and whether it forgets nothing within a span (the module docstring's list).
KEEPS: dict[str, tuple[int, Callable[[ForgettingPolicy, Limits, Span], bool]]] = {
    "decay": (1, lambda p, limits, s: _beyond(_value(p, "decay"), s)),
    "activation": (3, lambda p, limits, s: _activation(limits, s)),
    "displacement": (1, lambda p, limits, s: s.per_entity <= limits.capacity),  # type: ignore[operator]
    "displacement-lfu": (1, lambda p, limits, s: s.per_entity <= limits.capacity),  # type: ignore[operator]
    "displacement-random": (2, lambda p, limits, s: s.per_entity <= limits.capacity),  # type: ignore[operator]
    "global-capacity": (1, lambda p, limits, s: s.entries <= limits.global_capacity),  # type: ignore[operator]
    "shared-capacity": (1, lambda p, limits, s: s.entries <= _value(p, "shared-capacity")),
    "episodes": (1, lambda p, limits, s: s.episodes <= limits.episode_window),  # type: ignore[operator]
}


def _keeps(rule: str, policy: ForgettingPolicy, limits: Limits, span: Span) -> bool:
    if rule not in KEEPS:
        return False
    arity, keeps = KEEPS[rule]
    return len(RULE_PARAMETERS[rule]) == arity and keeps(policy, limits, span)


def keeps_everything(policy: ForgettingPolicy, span: Span) -> bool:
    """Return True if ``policy`` is sure to forget nothing within ``span`` (False: it may; ``none`` keeps nothing)."""
    return kept_spans(policy, (span,))[0]


def kept_spans(policy: ForgettingPolicy, spans: Sequence[Span]) -> list[bool]:
    """Return :func:`keeps_everything` of ``policy`` for each span (its limits built once)."""
    return [rest is None for rest in within(policy, spans)]


def within(policy: ForgettingPolicy, spans: Sequence[Span]) -> list[Optional[ForgettingPolicy]]:
    """Return, per span, the policy that forgets what ``policy`` does within it: None if it forgets nothing.

    Rules act on one buffer only by forgetting, so a rule that keeps everything within a span
    leaves the others' WM as if it were not there: the policy of the other rules alone (their
    own parameters) then forgets the same (``decay+displacement`` with a capacity no queue
    reaches is ``decay``); otherwise the policy itself.  ``none`` is itself (it keeps nothing).
    """
    if not policy.retains:
        return [policy] * len(spans)
    limits = policy.limits()
    out: list[Optional[ForgettingPolicy]] = []
    for span in spans:
        rest = tuple(rule for rule in policy.rules if not _keeps(rule, policy, limits, span))
        if not rest:
            out.append(None)
        elif len(rest) == len(policy.rules):
            out.append(policy)
        else:
            read = {param for rule in rest for param in RULE_PARAMETERS[rule]}
            out.append(ForgettingPolicy(rest, **{k: v for k, v in policy.parameters if k in read}))
    return out


__all__ = ["MARGIN", "Span", "KEEPS", "keeps_everything", "kept_spans", "within"]
