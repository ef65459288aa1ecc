"""Forgetting policies: the rules of the WM Manager (paper Algorithms 2 and 3, and more).

A policy is ``none`` or one or more rules joined by ``+`` (:func:`parse_rules` is
the one place policy names are parsed and validated):

* ``decay`` (delta = ``decay_period``): every delta seconds of the robot's clock,
  counted from the WM Manager's start, pop the front of every non-empty queue
  (Algorithm 2; the schedule is :mod:`fsreg_ros.core.decay`).
* ``displacement`` (alpha = ``capacity``): after each encoding event, while
  ``len(Q[R]) > alpha`` forget the front of ``Q[R]`` (Algorithm 3, LRU).
* ``displacement-lfu`` (``capacity``): as ``displacement``, but forget the property
  of ``Q[R]`` encoded least often since it entered the queue (not the one just
  encoded; ties to the least recently encoded).
* ``displacement-random`` (``capacity``, ``seed``): as ``displacement``, but forget
  a random property of ``Q[R]`` other than the one just encoded, drawn from a
  generator seeded with ``seed`` (default 0) whenever the policy is installed, so
  runs are reproducible and the graph draws what the simulator draws.
* ``similarity``: encoding a property of an attribute (``colour=red``, or declared
  in the domain's ``attributes``) forgets the entity's other properties of that
  attribute (interference by similarity).
* ``global-capacity``: after each encoding event, while the domain holds more than
  ``global_capacity`` properties, forget the front whose stamp is oldest (global LRU).
* ``shared-capacity`` (``shared_capacity``): one pool shared by every domain whose
  policy has this rule, of the smallest ``shared_capacity`` among them.  Applied by
  the WM Manager when it catches up to a dialogue event's time (``advance`` in the
  simulator, ``/wm_manager/sync`` in the graph; never by a timer), after the decay
  ticks due then, so it trims what earlier events encoded: while the pool holds more,
  the domain holding the most properties (the first in domain order on ties) forgets
  its least recently encoded front (cause ``shared-capacity``).

At most one displacement rule.  The size limits become data on the buffer
(:meth:`ForgettingPolicy.limits`), enforced by :mod:`fsreg_ros.core.memory`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, Optional

from .memory import Limits

#: Victim choice of each displacement rule.
DISPLACEMENT = {"displacement": "lru", "displacement-lfu": "lfu", "displacement-random": "random"}
RULES = (
    "decay",
    "displacement",
    "displacement-lfu",
    "displacement-random",
    "similarity",
    "global-capacity",
    "shared-capacity",
)
#: The parameters each rule needs (``seed`` is optional: default 0).
RULE_PARAMETERS: dict[str, tuple[str, ...]] = {
    "decay": ("decay_period",),
    "displacement": ("capacity",),
    "displacement-lfu": ("capacity",),
    "displacement-random": ("capacity", "seed"),
    "similarity": (),
    "global-capacity": ("global_capacity",),
    "shared-capacity": ("shared_capacity",),
}
#: Every memory parameter, and the settings of a ``memory:`` block.
PARAMETERS = ("decay_period", "capacity", "global_capacity", "seed", "shared_capacity")
SETTINGS = ("policy",) + PARAMETERS
#: Parameters a rule may leave unset, with their default.
DEFAULTS = {"seed": 0}

#: Bounds of ``decay_period``, seconds.  Below 0.01 s a live graph would spend its
#: CPU on decay (a timer and a consultant call per tick, at 100 Hz and more); above
#: 1e6 s (11.6 days) decay never happens in practice, and with the clock bounded by
#: ``decay.MAX_TIME`` (1e12 s) the tick index k = t / delta stays below 2**53, so
#: ``origin + k * delta`` is exact in k and every time fits a ROS Duration.
MIN_DECAY_PERIOD = 0.01
MAX_DECAY_PERIOD = 1e6
#: Bounds of the whole-number parameters (per-queue, per-domain, seed).
BOUNDS: dict[str, tuple[float, float]] = {
    "decay_period": (MIN_DECAY_PERIOD, MAX_DECAY_PERIOD),
    "capacity": (1, 10_000),
    "global_capacity": (1, 1_000_000),
    "seed": (0, 2**31 - 1),
    "shared_capacity": (1, 1_000_000),
}


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
    seed: Optional[int] = None
    shared_capacity: Optional[int] = None

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
        seed: Optional[int] = None,
        shared_capacity: Optional[int] = None,
    ) -> "ForgettingPolicy":
        """Build and validate a policy from its name and parameters."""
        return cls(
            parse_rules(policy),
            decay_period=decay_period,
            capacity=capacity,
            global_capacity=global_capacity,
            seed=seed,
            shared_capacity=shared_capacity,
        ).validated()

    @classmethod
    def from_settings(cls, settings: Mapping[str, object]) -> "ForgettingPolicy":
        """Build and validate a policy from ``{"policy", parameter: value, ...}``.

        That is a ``memory:`` block or a configure request; PolicyError if invalid.
        """
        unknown = sorted(set(settings) - set(SETTINGS))
        if unknown:
            raise PolicyError(f"unknown memory setting '{unknown[0]}' (known: {', '.join(SETTINGS)})")
        values = {k: settings.get(k) for k in PARAMETERS}
        if isinstance(values["decay_period"], int) and not isinstance(values["decay_period"], bool):
            values["decay_period"] = float(values["decay_period"])
        return cls.parse(str(settings.get("policy", "none")), **values)  # type: ignore[arg-type]

    def validated(self) -> "ForgettingPolicy":
        """Return self if every parameter is valid and present where needed."""
        for name in PARAMETERS:
            check_parameter(name, getattr(self, name))
        for rule in self.rules:
            for param in RULE_PARAMETERS[rule]:
                if getattr(self, param) is None and param not in DEFAULTS:
                    raise PolicyError(f"policy '{self.name}' needs '{param}' ({rule}) but it is not set")
        return self

    def with_changes(self, **changes: object) -> "ForgettingPolicy":
        """Return a validated copy with some settings changed (``policy`` is a rule string)."""
        if "policy" in changes:
            changes["rules"] = parse_rules(str(changes.pop("policy")))
        return replace(self, **changes).validated()  # type: ignore[arg-type]

    def value(self, param: str) -> object:
        """Return the effective value of parameter ``param`` (its default if unset)."""
        found = getattr(self, param)
        return DEFAULTS.get(param) if found is None else found

    def to_json(self) -> dict:
        """Return the effective setting as docs/semantics.md section 6 reports it (only what is used)."""
        out: dict = {"policy": self.name}
        for rule in self.rules:
            for param in RULE_PARAMETERS[rule]:
                out[param] = self.value(param)
        return out

    def settings(self) -> dict:
        """Return every setting that is set (what a configure request carries)."""
        out: dict = {"policy": self.name}
        out.update({p: getattr(self, p) for p in PARAMETERS if getattr(self, p) is not None})
        return out

    def limits(self) -> Limits:
        """Return the size limits this policy puts on a buffer (decay is the schedule's)."""
        if not self.rules:
            return Limits(retains=False)
        displacing = [rule for rule in self.rules if rule in DISPLACEMENT]
        return Limits(
            retains=True,
            capacity=self.capacity if displacing else None,
            victim=DISPLACEMENT[displacing[0]] if displacing else "lru",
            similarity="similarity" in self.rules,
            global_capacity=self.global_capacity if "global-capacity" in self.rules else None,
            seed=int(self.value("seed")),  # type: ignore[call-overload]
        )


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
    displacing = [rule for rule in rules if rule in DISPLACEMENT]
    if len(displacing) > 1:
        raise PolicyError(f"policy '{policy}' combines {' and '.join(displacing)}: choose one displacement rule")
    # Canonical order, so "displacement+decay" and "decay+displacement" are one policy.
    return tuple(rule for rule in RULES if rule in rules)


def check_parameter(name: str, value: object) -> None:
    """Raise PolicyError unless ``value`` is acceptable for parameter ``name`` (None = unset).

    The bounds are :data:`BOUNDS`, shared by scenario files, the command line and the
    ``wm_manager`` node's parameter descriptors.
    """
    if value is None:
        return
    if name not in BOUNDS:
        raise PolicyError(f"unknown forgetting parameter '{name}'")
    if name == "decay_period":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise PolicyError(f"decay_period must be a number of seconds, got {value!r}")
        if value <= 0:
            raise PolicyError(f"decay_period must be > 0 seconds (at least {MIN_DECAY_PERIOD:g}), got {value!r}")
        _check_bounds(name, value, " seconds")
        return
    if isinstance(value, bool) or not isinstance(value, int):
        raise PolicyError(f"{name} must be a whole number, got {value!r}")
    _check_bounds(name, value, "")


def _check_bounds(name: str, value: float, unit: str) -> None:
    low, high = BOUNDS[name]
    if value < low:
        raise PolicyError(f"{name} must be >= {low:g}{unit}, got {value!r}")
    if value > high:
        raise PolicyError(f"{name} must be <= {high:g}{unit}, got {value!r}")


def check_setting(name: str, value: object) -> None:
    """Raise PolicyError unless ``value`` is valid for memory setting ``name``.

    ``name`` is ``policy`` or one of the parameters; None means unset.
    """
    if name == "policy":
        if value is not None:
            parse_rules(value)  # type: ignore[arg-type]
    else:
        check_parameter(name, value)


def merge_settings(*layers: Optional[Mapping[str, object]]) -> ForgettingPolicy:
    """Merge ``memory:`` blocks key by key, later layers winning, into a policy.

    Used for scenario defaults <- a domain's own block <- command-line overrides.
    No ``policy`` anywhere means ``none``.
    """
    merged: dict[str, object] = {}
    for layer in layers:
        if layer:
            merged.update({k: v for k, v in layer.items() if v is not None})
    return ForgettingPolicy.from_settings(merged)
