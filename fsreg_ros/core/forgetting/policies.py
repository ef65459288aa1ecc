"""Forgetting policies: the rules of the WM Manager (paper Algorithms 2 and 3, and more).

A policy is ``none`` or one or more rules joined by ``+`` (:func:`parse_rules` is
the one place policy names are parsed and validated):

* ``decay`` (delta = ``decay_period``): every delta seconds of the robot's clock,
  counted from the WM Manager's start, pop the front of every non-empty queue
  (Algorithm 2; the schedule is :mod:`fsreg_ros.core.memory.ticks`).
* ``activation`` (d = ``activation_decay``, default 0.5; tau =
  ``activation_threshold``): ACT-R base-level activation.  An entry's activation is
  ln sum_j (t - t_j)^(-d) over the times its property was encoded for that entity
  since it entered the queue; it is forgotten when that falls below tau, at the
  crossing time, computed once per encoding and applied lazily
  (:mod:`fsreg_ros.core.memory.activation`).  The clock reaches the buffer from the
  WM Manager (:meth:`WMManager.advance`) and from every encoding's own time.
  Not combined with ``decay`` (both are forgetting by time; choose one).
* ``episodes`` (k = ``episode_window``, default 1): when an entity's reference episode begins
  (an act of referring to it: :meth:`WMBuffer.begin_episode`, which the consultant
  calls when REG opens its view of the target, and when RR's view closes with rule 1's
  encoding), before that episode's own
  encodings, every entry of its queue not used in its last k episodes is forgotten
  (cause ``episodes``): during episode n the queue holds what was used in episodes
  n - k ... n (:mod:`fsreg_ros.core.memory.episodes`).
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

At most one displacement rule, and ``decay`` or ``activation``, not both.  The size
limits and the activation parameters become data on the buffer
(:meth:`ForgettingPolicy.limits`), enforced by :mod:`fsreg_ros.core.memory`.

The settings (their types, bounds, defaults and which rule reads which) are the
table of :mod:`fsreg_ros.core.forgetting.settings`; this module holds the rules.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Optional

from . import settings as table
from ..memory import Limits
from .settings import MAX_DECAY_PERIOD, MIN_DECAY_PERIOD, Number, PolicyError

#: Victim choice of each displacement rule.
DISPLACEMENT = {"displacement": "lru", "displacement-lfu": "lfu", "displacement-random": "random"}
#: Every rule, in canonical order (the order a policy name lists them in).
RULES = (
    "decay",
    "activation",
    "episodes",
    "displacement",
    "displacement-lfu",
    "displacement-random",
    "similarity",
    "global-capacity",
    "shared-capacity",
)
#: A policy name as a regular expression (for JSON Schemas; :func:`parse_rules` is the check).
POLICY_PATTERN = "^(none|({rules})(\\+({rules}))*)$".format(rules="|".join(RULES))
#: Every memory parameter (the table's numeric rows), and the settings of a ``memory:`` block.
PARAMETERS = tuple(row.name for row in table.parameters())
SETTINGS = table.names()
#: The parameters each rule reads (from the table's ``rules`` column).
RULE_PARAMETERS: dict[str, tuple[str, ...]] = {
    rule: tuple(row.name for row in table.parameters() if rule in row.rules) for rule in RULES
}
#: Parameters a rule may leave unset, with the value it then uses.
DEFAULTS = {row.name: row.fallback for row in table.parameters() if row.fallback is not None}
#: The parameters that are a choice of text (their fallback is the first choice).
CHOICES = {row.name: row.choices for row in table.parameters() if row.choices}
#: Bounds of every parameter (low, high), inclusive.
BOUNDS: dict[str, tuple[Number, Number]] = {row.name: (row.low, row.high) for row in table.parameters()}

__all__ = ["DISPLACEMENT", "RULES", "POLICY_PATTERN", "PARAMETERS", "SETTINGS", "RULE_PARAMETERS", "DEFAULTS", "BOUNDS",
           "MIN_DECAY_PERIOD", "MAX_DECAY_PERIOD", "NONE", "PolicyError", "ForgettingPolicy", "parse_rules",
           "check_parameter", "check_setting", "merge_settings"]


@dataclass(frozen=True, init=False)
class ForgettingPolicy:
    """One domain's forgetting settings: its rules and the parameters that are set.

    ``rules`` is empty for ``none``.  ``parameters`` holds the set parameters as
    ``(name, value)`` pairs in table order; parameters not needed by a rule may still
    be set (they are kept, so switching rules at run time reuses them).  Build one with
    ``ForgettingPolicy(rules, decay_period=..., ...)``, :meth:`parse` or
    :meth:`from_settings`; read a parameter with :meth:`value`.
    """

    rules: tuple[str, ...] = ()
    parameters: tuple[tuple[str, Number], ...] = field(default=())

    def __init__(self, rules: tuple[str, ...] = (), **parameters: Optional[Number]) -> None:
        unknown = sorted(set(parameters) - set(PARAMETERS))
        if unknown:
            raise PolicyError(f"unknown memory setting '{unknown[0]}' (known: {', '.join(SETTINGS)})")
        values = [(name, parameters[name]) for name in PARAMETERS if parameters.get(name) is not None]
        object.__setattr__(self, "rules", tuple(rules))
        object.__setattr__(self, "parameters", tuple(values))

    @property
    def name(self) -> str:
        return "+".join(self.rules) if self.rules else "none"

    @property
    def retains(self) -> bool:
        return bool(self.rules)

    @property
    def decays(self) -> bool:
        return "decay" in self.rules

    @property
    def activates(self) -> bool:
        """True when forgetting by ACT-R activation is in force (the WM Manager then sends its clock)."""
        return "activation" in self.rules

    @property
    def clock_driven(self) -> bool:
        """True when the WM Manager's catching up can forget something (``WMManager.clock_driven``).

        Decay, rule ``activation`` on the seconds clock, or the shared pool.
        """
        return self.decays or "shared-capacity" in self.rules or (
            self.activates and self.value("activation_clock") == "seconds")

    @classmethod
    def parse(cls, policy: str, **parameters: Optional[Number]) -> "ForgettingPolicy":
        """Build and validate a policy from its name and parameters (None = unset)."""
        return cls(parse_rules(policy), **parameters).validated()

    @classmethod
    def from_settings(cls, settings: Mapping[str, object]) -> "ForgettingPolicy":
        """Build and validate a policy from ``{"policy", parameter: value, ...}``.

        That is a ``memory:`` block or a configure request; PolicyError if invalid.
        A whole number given for a ``float`` parameter becomes a float.
        """
        unknown = sorted(set(settings) - set(SETTINGS))
        if unknown:
            raise PolicyError(f"unknown memory setting '{unknown[0]}' (known: {', '.join(SETTINGS)})")
        values = {}
        for row in table.parameters():
            value = settings.get(row.name)
            if row.kind is float and isinstance(value, int) and not isinstance(value, bool):
                value = _as_float(row.name, value)
            values[row.name] = value
        return cls.parse(str(settings.get("policy", "none")), **values)  # type: ignore[arg-type]

    def validated(self) -> "ForgettingPolicy":
        """Return self if every parameter is valid and present where needed."""
        for name, value in self.parameters:
            check_parameter(name, value)
        for rule in self.rules:
            for param in RULE_PARAMETERS[rule]:
                if self.given(param) is None and param not in DEFAULTS:
                    raise PolicyError(f"policy '{self.name}' needs '{param}' ({rule}) but it is not set")
        return self

    def with_changes(self, **changes: object) -> "ForgettingPolicy":
        """Return a validated copy with some settings changed (``policy`` is a rule string)."""
        rules = parse_rules(str(changes.pop("policy"))) if "policy" in changes else self.rules
        return ForgettingPolicy(rules, **{**dict(self.parameters), **changes}).validated()  # type: ignore[arg-type]

    def given(self, param: str) -> Optional[Number]:
        """Return parameter ``param`` as set (None if unset)."""
        return dict(self.parameters).get(param)

    def value(self, param: str) -> Optional[Number]:
        """Return the effective value of parameter ``param`` (its fallback if unset)."""
        found = self.given(param)
        return DEFAULTS.get(param) if found is None else found

    def to_json(self) -> dict:
        """Return the effective setting as docs/semantics.md section 6 reports it (only what is used)."""
        out: dict = {"policy": self.name}
        for rule in self.rules:
            for param in RULE_PARAMETERS[rule]:
                if param not in CHOICES or self.value(param) != DEFAULTS[param]:  # a choice at its fallback: today's
                    out[param] = self.value(param)
        return out

    def settings(self) -> dict:
        """Return every setting that is set (what a configure request carries)."""
        return {"policy": self.name, **dict(self.parameters)}

    def limits(self) -> Limits:
        """Return the limits this policy puts on a buffer (decay is the schedule's)."""
        if not self.rules:
            return Limits(retains=False)
        displacing = [rule for rule in self.rules if rule in DISPLACEMENT]
        return Limits(
            retains=True,
            capacity=self.given("capacity") if displacing else None,  # type: ignore[arg-type]
            victim=DISPLACEMENT[displacing[0]] if displacing else "lru",
            similarity="similarity" in self.rules,
            global_capacity=self.given("global_capacity") if "global-capacity" in self.rules else None,  # type: ignore
            seed=int(self.value("seed")),  # type: ignore[arg-type]
            activation=_activation_of(self) if self.value("activation_clock") != "episodes" else None,
            activation_clock=str(self.value("activation_clock")) if self.activates else "seconds",
            episode_activation=_activation_of(self) if self.value("activation_clock") == "episodes" else None,
            episode_window=int(self.value("episode_window")) if "episodes" in self.rules else None,  # type: ignore
        )


NONE = ForgettingPolicy()


def _activation_of(policy: ForgettingPolicy) -> Optional[tuple[float, float]]:
    """Return ``(d, tau)`` under rule ``activation``, else None."""
    if not policy.activates:
        return None
    return float(policy.value("activation_decay")), float(policy.value("activation_threshold"))  # type: ignore


def _as_float(name: str, value: int) -> float:
    try:
        return float(value)
    except OverflowError:
        raise PolicyError(f"{name} must be a number, got an integer too large for one") from None


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
    if "decay" in rules and "activation" in rules:
        raise PolicyError(f"policy '{policy}' combines decay and activation: both forget by time, choose one")
    # Canonical order, so "displacement+decay" and "decay+displacement" are one policy.
    return tuple(rule for rule in RULES if rule in rules)


def check_parameter(name: str, value: object) -> None:
    """Raise PolicyError unless ``value`` is acceptable for parameter ``name`` (None = unset).

    The check and bounds are the settings table's (:func:`fsreg_ros.core.forgetting.settings.check_value`),
    shared by scenario files, the command line, node parameters and configure requests.
    """
    if name not in PARAMETERS:
        raise PolicyError(f"unknown memory setting '{name}' (known: {', '.join(SETTINGS)})")
    table.check_value(name, value)


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
