"""Forgetting: the WM Manager's policies (paper Algorithms 2 and 3).

Where is decay?  Here: :class:`DecayClock` says how many decay ticks are due at a
time (Algorithm 2's schedule), and :meth:`WMManager.advance` applies them to every
domain whose policy has ``decay``.  Where is displacement?  Here too:
:func:`displace` (Algorithm 3, LRU) and :func:`evict_global` (the global limit) run
through :func:`enforce_limits` after every single encoding event.

A policy is ``none`` or one or more rules joined by ``+``:

* ``decay`` (delta = ``decay_period``): every delta seconds of the robot's clock,
  counted from t = 0, pop the front of every non-empty queue.
* ``displacement`` (alpha = ``capacity``): after each encoding event, while
  ``len(Q[R]) > alpha`` pop the front of ``Q[R]``.
* ``global-capacity``: after each encoding event, while the domain holds more than
  ``global_capacity`` properties, pop the front whose stamp is oldest (global LRU).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Optional

from .memory import WMBuffer

RULES = ("decay", "displacement", "global-capacity")
#: The parameter each rule needs.
RULE_PARAMETER = {
    "decay": "decay_period",
    "displacement": "capacity",
    "global-capacity": "global_capacity",
}
#: Slack when comparing tick times with event times (SPEC section 2).
TIME_EPSILON = 1e-9


class PolicyError(ValueError):
    """An invalid forgetting policy or parameter; the message says which and why."""


@dataclass(frozen=True)
class ForgettingPolicy:
    """One domain's forgetting settings.

    ``rules`` is empty for ``none``.  Parameters not needed by a rule may still be
    set (they are kept, so switching rules at run time reuses them).
    """

    rules: tuple[str, ...] = ()
    decay_period: Optional[float] = None
    capacity: Optional[int] = None
    global_capacity: Optional[int] = None

    @property
    def name(self) -> str:
        return "+".join(self.rules) if self.rules else "none"

    @property
    def retains(self) -> bool:
        return bool(self.rules)

    @property
    def decays(self) -> bool:
        return "decay" in self.rules

    @classmethod
    def parse(
        cls,
        policy: str,
        decay_period: Optional[float] = None,
        capacity: Optional[int] = None,
        global_capacity: Optional[int] = None,
    ) -> "ForgettingPolicy":
        """Build and validate a policy from its name and parameters."""
        return cls(
            parse_rules(policy),
            decay_period=decay_period,
            capacity=capacity,
            global_capacity=global_capacity,
        ).validated()

    def validated(self) -> "ForgettingPolicy":
        """Return self if every parameter is valid and present where needed."""
        for name in RULE_PARAMETER.values():
            check_parameter(name, getattr(self, name))
        for rule in self.rules:
            param = RULE_PARAMETER[rule]
            if getattr(self, param) is None:
                raise PolicyError(f"policy '{self.name}' needs '{param}' ({rule}) but it is not set")
        return self

    def with_changes(self, **changes: object) -> "ForgettingPolicy":
        """A validated copy with some settings changed (``policy`` is a rule string)."""
        if "policy" in changes:
            changes["rules"] = parse_rules(str(changes.pop("policy")))
        return replace(self, **changes).validated()  # type: ignore[arg-type]

    def to_json(self) -> dict:
        """The effective setting as SPEC section 6 reports it (only what is used)."""
        out: dict = {"policy": self.name}
        for rule in self.rules:
            param = RULE_PARAMETER[rule]
            out[param] = getattr(self, param)
        return out


NONE = ForgettingPolicy()


def parse_rules(policy: str) -> tuple[str, ...]:
    """``"decay+displacement"`` -> ``("decay", "displacement")``; ``"none"`` -> ``()``."""
    if not isinstance(policy, str) or not policy.strip():
        raise PolicyError(f"policy must be a non-empty string, got {policy!r}")
    text = policy.strip()
    if text == "none":
        return ()
    rules = tuple(part.strip() for part in text.split("+"))
    for rule in rules:
        if rule not in RULES:
            allowed = ", ".join(("none",) + RULES)
            raise PolicyError(f"unknown forgetting rule '{rule}' in policy '{policy}' (known: {allowed}, joined by +)")
    if len(set(rules)) != len(rules):
        raise PolicyError(f"policy '{policy}' names a rule twice")
    # Canonical order, so "displacement+decay" and "decay+displacement" are one policy.
    return tuple(rule for rule in RULES if rule in rules)


def check_parameter(name: str, value: object) -> None:
    """Raise PolicyError unless ``value`` is acceptable for parameter ``name`` (None = unset)."""
    if value is None:
        return
    if name == "decay_period":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise PolicyError(f"decay_period must be a number of seconds, got {value!r}")
        if value <= 0:
            raise PolicyError(f"decay_period must be > 0 seconds, got {value!r}")
    elif name in ("capacity", "global_capacity"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise PolicyError(f"{name} must be a whole number, got {value!r}")
        if value < 1:
            raise PolicyError(f"{name} must be >= 1, got {value!r}")
    else:
        raise PolicyError(f"unknown forgetting parameter '{name}'")


def check_setting(name: str, value: object) -> None:
    """Raise PolicyError unless ``value`` is valid for memory setting ``name``
    (``policy`` or one of the parameters; None = unset)."""
    if name == "policy":
        if value is not None:
            parse_rules(value)  # type: ignore[arg-type]
    else:
        check_parameter(name, value)


# ---------------------------------------------------------------- size limits
def displace(buffer: WMBuffer, entity: str, capacity: int, time: float, turn: Optional[int]) -> None:
    """Algorithm 3 (interference by displacement): keep |Q[entity]| <= alpha, LRU out."""
    while buffer.length(entity) > capacity:
        buffer.pop_front(entity, "displacement", time, turn)


def evict_global(buffer: WMBuffer, limit: int, time: float, turn: Optional[int]) -> None:
    """Global LRU: while the domain holds more than ``limit`` properties, forget the
    front property with the oldest encoding stamp (possibly in the queue just encoded).

    Queues are sorted by stamp, so this is the oldest property in the whole domain.
    The domain never holds more than ``limit + 1`` properties here, so the scan over
    non-empty queues costs O(limit), independent of the number of entities.
    """
    while len(buffer) > limit:
        victim = min(buffer.nonempty_entities(), key=buffer.front_stamp)
        buffer.pop_front(victim, "global-capacity", time, turn)


def enforce_limits(
    buffer: WMBuffer, entity: str, policy: ForgettingPolicy, time: float, turn: Optional[int]
) -> None:
    """Run after each encoding event: displacement first, then the global limit."""
    if "displacement" in policy.rules:
        displace(buffer, entity, policy.capacity, time, turn)  # type: ignore[arg-type]
    if "global-capacity" in policy.rules:
        evict_global(buffer, policy.global_capacity, time, turn)  # type: ignore[arg-type]


def trim_all(buffer: WMBuffer, policy: ForgettingPolicy, time: float) -> None:
    """Apply a (new) policy's limits to every queue at once (SPEC section 7)."""
    if not policy.retains:
        buffer.clear("reset", time)
        return
    if "displacement" in policy.rules:
        for entity in buffer.nonempty_entities():
            displace(buffer, entity, policy.capacity, time, None)  # type: ignore[arg-type]
    if "global-capacity" in policy.rules:
        evict_global(buffer, policy.global_capacity, time, None)  # type: ignore[arg-type]


# ---------------------------------------------------------------------- decay
@dataclass
class DecayClock:
    """Algorithm 2's schedule: ticks at ``origin + k * period`` for k = 1, 2, ...

    One clock per domain, shared by the whole buffer (SPEC section 8), not one timer
    per queue.  :meth:`due` is idempotent: it derives the number of elapsed periods
    from the clock and subtracts those already applied, so a timer that fires late,
    or once for several periods, and a barrier that asks again, never apply a tick
    twice or miss one.
    """

    period: float
    origin: float = 0.0
    applied: int = 0

    def due(self, now: float) -> list[float]:
        """Times of the ticks at or before ``now`` not yet applied; marks them applied."""
        limit = now + TIME_EPSILON
        elapsed = math.floor((limit - self.origin) / self.period)
        # The rounded quotient can be one off right at the slack's edge; settle on the
        # SPEC's own test, tick k is due iff origin + k * period <= now + 1e-9.
        while self.origin + (elapsed + 1) * self.period <= limit:
            elapsed += 1
        while elapsed > 0 and self.origin + elapsed * self.period > limit:
            elapsed -= 1
        times = [self.origin + k * self.period for k in range(self.applied + 1, elapsed + 1)]
        self.applied = max(self.applied, elapsed)
        return times

    def next_tick(self) -> float:
        return self.origin + (self.applied + 1) * self.period

    def restart(self, period: float, now: float) -> None:
        """A new period restarts the schedule: next tick one new period after ``now``."""
        self.period, self.origin, self.applied = period, now, 0


@dataclass
class WMManager:
    """The WM Manager: the one place that decides what each domain forgets.

    It owns each domain's policy and decay clock, installs the size limits into the
    domain's buffer (enforced after every encoding event), and applies decay ticks
    when the robot's clock advances.  In the ROS graph the ``wm_manager`` node wraps
    the same logic, with the buffers living in the consultant processes.
    """

    buffers: dict[str, WMBuffer] = field(default_factory=dict)
    policies: dict[str, ForgettingPolicy] = field(default_factory=dict)
    clocks: dict[str, DecayClock] = field(default_factory=dict)

    def manage(self, buffer: WMBuffer, policy: ForgettingPolicy, now: float = 0.0) -> None:
        """Take a domain's buffer under management with its initial policy."""
        self.buffers[buffer.domain] = buffer
        self.set_policy(buffer.domain, policy, now)

    def set_policy(self, domain: str, policy: ForgettingPolicy, now: float) -> None:
        """Change a domain's policy; it takes effect at once (limits trim every queue,
        ``none`` empties the domain, a new decay period restarts the schedule)."""
        policy = policy.validated()
        old = self.policies.get(domain)
        buffer = self.buffers[domain]
        self.policies[domain] = policy
        buffer.policy = policy
        if policy.decays:
            clock = self.clocks.get(domain)
            if clock is None:
                # Decay switched on: ticks stay on the k * delta grid from the time
                # origin t = 0; ticks before now are not owed.
                self.clocks[domain] = DecayClock(policy.decay_period, origin=0.0)  # type: ignore[arg-type]
                self.clocks[domain].due(now)
            elif old is not None and old.decay_period != policy.decay_period:
                clock.restart(policy.decay_period, now)  # type: ignore[arg-type]
        else:
            self.clocks.pop(domain, None)
        trim_all(buffer, policy, now)

    def advance(self, now: float) -> None:
        """Apply every decay tick due at or before ``now``, in every decaying domain."""
        for domain, clock in self.clocks.items():
            self.buffers[domain].decay(clock.due(now))

    def effective(self) -> dict[str, dict]:
        """Each domain's effective setting, keyed by domain (SPEC section 6 ``memory``)."""
        return {d: self.policies[d].to_json() for d in sorted(self.policies)}


def merge_settings(*layers: Optional[Mapping[str, object]]) -> ForgettingPolicy:
    """Merge ``memory:`` blocks key by key, later layers winning, into a policy.

    Used for scenario defaults <- a domain's own block <- command-line overrides.
    No ``policy`` anywhere means ``none``.
    """
    merged: dict[str, object] = {}
    for layer in layers:
        if layer:
            merged.update({k: v for k, v in layer.items() if v is not None})
    return ForgettingPolicy.parse(
        str(merged.get("policy", "none")),
        decay_period=_maybe_float(merged.get("decay_period")),
        capacity=merged.get("capacity"),  # type: ignore[arg-type]
        global_capacity=merged.get("global_capacity"),  # type: ignore[arg-type]
    )


def _maybe_float(value: object) -> object:
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value

