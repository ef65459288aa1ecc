"""The memory settings table: every forgetting setting, declared once.

One row per setting of a ``memory:`` block (docs/semantics.md section 5): its name,
type, bounds, the WM Manager node's default, the per-domain "inherit" marker, help
text and the forgetting rules that read it.  Everything that names a memory setting
is generated from :data:`TABLE`:

* the policy itself, :class:`fsreg_ros.core.forgetting.policies.ForgettingPolicy` (which
  parameters each rule needs, their checks, what is reported);
* the scenario file schema (:mod:`fsreg_ros.core.scenario.schema`, ``MemoryBlock``);
* the command-line options of ``fsreg-sim`` / ``fsreg-graph`` (:mod:`fsreg_ros.tools.sim`);
* the ``wm_manager`` node's parameters and their descriptors
  (:mod:`fsreg_ros.nodes.wm_manager`);
* the graph definition and the launch file's arguments (:mod:`fsreg_ros.ros.graph_spec`,
  ``launch/fsreg.launch.py``);
* the contract's policy object, sent by the WM Manager to a consultant's ``configure``
  (:mod:`fsreg_ros.contract.policy`).

Adding a setting is one row here plus the rule that reads it (docs/design.md, "Add a
memory setting"); ``test/core/test_settings.py`` checks every consumer against the table.
The one check of a value is :func:`check_value`; the ``policy`` row's value is a rule
string, checked by :func:`fsreg_ros.core.forgetting.policies.parse_rules`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Union

from ..memory.entity_clock import CLOCKS

Number = Union[int, float]


class PolicyError(ValueError):
    """An invalid forgetting policy or memory setting; the message says which and why."""


@dataclass(frozen=True)
class Setting:
    """One memory setting: what it is, what values it takes, who reads it.

    ``kind`` is ``str`` (the policy, or a choice among ``choices``), ``float`` (a number;
    whole numbers accepted) or ``int`` (a whole number).  ``low``/``high`` bound a number
    (inclusive).  A choice's ``fallback`` is its first choice, today's behaviour, and a
    policy's report leaves a choice out while it is at its fallback
    (:meth:`ForgettingPolicy.to_json <fsreg_ros.core.forgetting.policies.ForgettingPolicy.to_json>`).
    ``default`` is the ``wm_manager`` node's value when none is given; ``inherit`` the
    per-domain parameter value meaning "use the node-wide one" (outside the bounds, so
    it cannot be a real value).  ``rules`` are the forgetting rules that read the
    setting; a rule needs it unless ``fallback`` is set (the value used when unset).
    ``symbol`` names the setting in figures and tables (``δ``), ``word`` in plain-text
    labels such as a sweep's (``delta``), ``axis`` on a plot's axis.
    """

    name: str
    kind: type
    default: Any
    inherit: Any
    help: str
    low: Optional[Number] = None
    high: Optional[Number] = None
    rules: tuple[str, ...] = ()
    fallback: Optional[Union[Number, str]] = None
    unit: str = ""
    metavar: str = "N"
    symbol: str = ""
    word: str = ""
    axis: str = ""
    choices: tuple[str, ...] = ()

    @property
    def option(self) -> str:
        """The command-line option: ``--decay-period``."""
        return "--" + self.name.replace("_", "-")

    @property
    def is_parameter(self) -> bool:
        """True for the values a rule reads (every row but ``policy``): numbers and choices."""
        return self.kind is not str or bool(self.choices)

    @property
    def kind_text(self) -> str:
        """The type in words: ``a number``, ``one of seconds, episodes, words``."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        return {str: "text", float: "a number", int: "a whole number"}[self.kind]

    @property
    def bounds_text(self) -> str:
        """The type and bounds in words: ``a number in [0.01, 1e+06] seconds`` ('' for the policy)."""
        if not self.is_parameter or self.choices:
            return self.kind_text if self.choices else ""
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.kind_text} in [{number(self.low)}, {number(self.high)}]{unit}"

    @property
    def description(self) -> str:
        """Help and bounds, for schemas, options and parameter descriptors."""
        return f"{self.help}; {self.bounds_text}" if self.is_parameter else self.help

    def json_schema_extra(self, policy_pattern: str) -> dict:
        """Return the JSON Schema keywords of the setting's value: bounds, or the policy's pattern."""
        if not self.is_parameter:
            return {"pattern": policy_pattern}
        if self.choices:
            return {"enum": list(self.choices)}
        return {"minimum": self.low, "maximum": self.high}


#: ``decay_period`` bounds, seconds.  Below 0.01 s a live graph would spend its CPU on
#: decay (a timer and a consultant call per tick, at 100 Hz and more); above 1e6 s
#: (11.6 days) decay never happens in practice, and with the clock bounded by
#: ``decay.MAX_TIME`` (1e12 s) the tick index k = t / delta stays below 2**53, so
#: ``origin + k * delta`` is exact in k and every time fits a ROS Duration.
MIN_DECAY_PERIOD = 0.01
MAX_DECAY_PERIOD = 1e6

#: ``activation_decay`` bounds: ACT-R's d, in (0, 1) (Petrov's approximation of older
#: presentations needs d < 1; the architecture's customary value is 0.5).
MIN_ACTIVATION_DECAY = 0.01
MAX_ACTIVATION_DECAY = 0.99
#: ``activation_threshold`` bounds (|tau|): with d >= 0.01 a single encoding then stays
#: between exp(-20) s and far beyond any clock (the crossing is then "never").
MAX_ACTIVATION_THRESHOLD = 20.0

#: Every memory setting.  ``policy`` first, then the parameters in report order.
TABLE: tuple[Setting, ...] = (
    Setting("policy", str, "none", "",
            "none, or rules joined by + (decay, activation, episodes, displacement, displacement-lfu, "
            "displacement-random, similarity, global-capacity, shared-capacity); at most one displacement rule, "
            "and decay or activation, not both", metavar="P"),
    Setting("decay_period", float, 10.0, 0.0,
            "decay: seconds between ticks (delta); a tick at time T is applied before any turn stamped T",
            MIN_DECAY_PERIOD, MAX_DECAY_PERIOD, rules=("decay",), unit="seconds", metavar="S",
            symbol="δ", word="delta", axis="decay period δ (s)"),
    Setting("capacity", int, 2, 0, "displacement rules: at most this many properties per entity's WM queue (alpha)",
            1, 10_000, rules=("displacement", "displacement-lfu", "displacement-random"),
            symbol="α", word="alpha", axis="capacity α (properties per entity)"),
    Setting("global_capacity", int, 6, 0, "global-capacity: at most this many properties in the domain's WM",
            1, 1_000_000, rules=("global-capacity",), symbol="global", word="global",
            axis="global capacity (properties per domain)"),
    Setting("seed", int, 0, -1, "displacement-random: seed of the random victim choice", 0, 2**31 - 1,
            rules=("displacement-random",), fallback=0, symbol="seed", word="seed", axis="seed"),
    Setting("shared_capacity", int, 12, 0,
            "shared-capacity: at most this many properties in the pool of every domain with that rule "
            "(the smallest value wins), trimmed before each turn", 1, 1_000_000, rules=("shared-capacity",),
            symbol="pool", word="pool", axis="shared pool (properties, all domains)"),
    Setting("activation_decay", float, 0.5, 0.0,
            "activation: decay rate d of a property's ACT-R base-level activation ln sum_j (t - t_j)^-d",
            MIN_ACTIVATION_DECAY, MAX_ACTIVATION_DECAY, rules=("activation",), fallback=0.5, metavar="D",
            symbol="d", word="d", axis="activation decay d (ACT-R)"),
    Setting("activation_threshold", float, -1.0, -1000.0,
            "activation: a property leaves WM when its activation falls below this threshold (tau; one encoding "
            "stays exp(-tau/d) seconds)", -MAX_ACTIVATION_THRESHOLD, MAX_ACTIVATION_THRESHOLD,
            rules=("activation",), metavar="TAU", symbol="τ", word="tau",
            axis="activation threshold τ (ACT-R; d = activation_decay)"),
    Setting("activation_clock", str, CLOCKS[0], "",
            "activation: the clock t counts on: seconds (the robot's), or each entity's own: episodes (its reference "
            "episodes) or words (the properties encoded for it); on those, ages count from 1 and other entities "
            "do not age it", rules=("activation",), fallback=CLOCKS[0], metavar="CLOCK", symbol="clock",
            word="clock", axis="activation clock", choices=CLOCKS),
    Setting("episode_window", int, 1, 0,
            "episodes: when an entity's reference episode begins, its properties not used in its last k episodes "
            "are forgotten (k = 1 keeps what was said in the previous episode and the current one)",
            1, 1_000_000, rules=("episodes",), fallback=1, metavar="K", symbol="k", word="k",
            axis="episode window k (episodes)"),
)


def names() -> tuple[str, ...]:
    """Every setting's name, ``policy`` first (the keys of a ``memory:`` block)."""
    return tuple(s.name for s in TABLE)


def parameters() -> tuple[Setting, ...]:
    """Return the rows of the numeric settings (every row but the policy)."""
    return tuple(s for s in TABLE if s.is_parameter)


def setting(name: str) -> Setting:
    """Return the row of ``name``; PolicyError if there is none."""
    for row in TABLE:
        if row.name == name:
            return row
    raise PolicyError(f"unknown memory setting '{name}' (known: {', '.join(names())})")


def check_value(name: str, value: object) -> Optional[Union[Number, str]]:
    """Return ``value`` if it is valid for parameter ``name`` (None = unset), else raise PolicyError.

    A ``float`` setting takes any finite number, an ``int`` one a whole number (never
    true/false); both within the row's bounds.  A choice takes one of its choices.  The one check of a memory parameter:
    scenario files, the command line, node parameters and configure requests use it.
    """
    row = setting(name)
    if value is None:
        return None
    if not row.is_parameter:
        raise PolicyError(f"'{name}' is not a numeric parameter")
    if row.choices:
        if not isinstance(value, str) or value not in row.choices:
            raise PolicyError(f"{name} must be {row.kind_text}, got {_show(value)}")
        return value
    unit = f" {row.unit}" if row.unit else ""
    if row.kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value):
            raise PolicyError(f"{name} must be a number{' of ' + row.unit if row.unit else ''}, got {_show(value)}")
        if value <= 0 < row.low:  # type: ignore[operator]
            raise PolicyError(f"{name} must be > 0{unit} (at least {number(row.low)}), got {_show(value)}")
    elif isinstance(value, bool) or not isinstance(value, int):
        raise PolicyError(f"{name} must be a whole number, got {_show(value)}")
    if value < row.low:  # type: ignore[operator]
        raise PolicyError(f"{name} must be >= {number(row.low)}{unit}, got {_show(value)}")
    if value > row.high:  # type: ignore[operator]
        raise PolicyError(f"{name} must be <= {number(row.high)}{unit}, got {_show(value)}")
    return value


def _show(value: object) -> str:
    """``repr(value)``, but an integer too long to print is described (``repr`` raises on it)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 1000:
        return f"an integer of {value.bit_length()} bits"
    return repr(value)


def _finite(value: Number) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer too large for a float
        return False


def number(value: Optional[Union[Number, str]]) -> str:
    """Return a bound as people write it: whole numbers in digits (``2147483647``), others as ``%g`` (text as is)."""
    if isinstance(value, (int, str)):
        return str(value)
    return f"{value:g}"


def markdown_table() -> list[str]:
    """Return the rows of the docs' settings table (docs/scenario-format.md keeps it equal)."""
    rows = ["| key | meaning | value | when not set |", "|---|---|---|---|"]
    for row in TABLE:
        if not row.is_parameter:
            value, unset = "text", "`none`"
        else:
            value = row.bounds_text
            readers = ", ".join(f"`{r}`" for r in row.rules)
            unset = f"{number(row.fallback)}" if row.fallback is not None else f"required by {readers}"
        rows.append(f"| `{row.name}` | {row.help} | {value} | {unset} |")
    return rows
