"""The models of reuse fitted to reference games: which rules, over which grids, and which baselines.

Models come from the core's rule list (:data:`fsreg_ros.core.forgetting.policies.RULES`) and its
settings table, so a rule added there is fitted without a change here: each rule alone over a
grid of the parameters it reads (:data:`GRIDS`; a parameter without one gets a grid from the
table's bounds), ``decay+displacement`` (the paper's both) over their product, beside the
baselines and the recency regressions.  ``similarity`` is left out (:data:`EXCLUDED`): words
have no attributes, so it forgets nothing.  The random victim's ``seed`` is not fitted
(:data:`NOT_FITTED`).  A parameter that is a choice (``activation_clock``) is not a grid axis
either: each choice is a model of its own, named ``rule@choice`` (``activation@episodes``,
``activation@words``; the fallback keeps the rule's name).  Every model has a *family*
(``rule``, ``baseline`` or ``regression``); the rules whose forgetting runs on seconds
(:func:`needs_clock`) are left out of the fit of a game without times.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product
from typing import Mapping, Optional, Sequence

import numpy as np

from ..core.forgetting import settings as table
from ..core.forgetting.policies import RULE_PARAMETERS, RULES, ForgettingPolicy

#: Grids of the core's parameters (wide enough that the fitted values lie inside them; the
#: report flags any that does not).  A parameter not listed gets :func:`default_grid`.
GRIDS: dict[str, tuple] = {
    "decay_period": (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 240.0,
                     360.0, 480.0, 720.0, 1200.0, 2400.0),
    "capacity": (1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 15, 20, 25, 30, 40, 60, 100),
    "global_capacity": (2, 4, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024),
    "shared_capacity": (2, 4, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024),
    # ACT-R base-level activation (when the core has it): d, and tau, with which one encoding
    # stays exp(-tau / d) seconds (1 s to 6 h at d = 0.8).
    "activation_decay": (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.99),
    "activation_threshold": (-10.0, -9.0, -8.0, -7.0, -6.0, -5.0, -4.0, -3.0, -2.0, -1.0, 0.0),
    # Reference episodes: an entry stays while used in one of its referent's last k episodes.
    "episode_window": (1, 2, 3, 4, 5, 6, 8),
}
#: Parameters held at their table value, not fitted: they are no property of forgetting.
NOT_FITTED = {"seed": "the random victim's seed (its fallback, 0)"}
#: Rules not fitted, and why.
EXCLUDED = {"similarity": "words have no attributes, so it forgets nothing (it is no-forgetting)"}
#: Rule combinations fitted beside the single rules (the paper's both).
COMBINATIONS = (("decay", "displacement"),)
#: A combination's grid takes at most this many values of each parameter (ends kept).
COMBINED_VALUES = 8
BASELINES = ("none", "no-forgetting", "last-description", "said-by-describer", "constant")
RECENCY = {"recency-seconds": ("seconds",), "recency-words": ("words",), "recency-references": ("references",),
           "recency-descriptions": ("descriptions",), "recency-all": ("seconds", "words", "references", "descriptions")}
FOLDS = 10
#: Differences reported beside those from the best model and from ``constant``: the paper's
#: rules against each other and against the referent's last description.
PAIRS = (("displacement", "decay"), ("decay+displacement", "displacement"), ("decay+displacement", "decay"),
         ("last-description", "decay+displacement"), ("last-description", "displacement"))
#: The paper's settings (Williams et al. 2020, Table 1), reported beside the fitted ones.
PAPER = {"decay_period": 10.0, "capacity": 2}


def default_grid(name: str, values: int = 12) -> tuple:
    """Return a grid for a parameter of the settings table without one in :data:`GRIDS`: from its bounds.

    Log-spaced when the bounds are positive and span two decades or more (capped at 1e4 times
    the lower bound), else evenly spaced; whole numbers for an ``int`` parameter.
    """
    row = table.setting(name)
    low, high = float(row.low), float(row.high)  # type: ignore[arg-type]
    if low > 0 and high / low >= 100:
        grid = np.geomspace(low, min(high, low * 1e4), values)
    else:
        grid = np.linspace(low, high, values)
    if row.kind is int:
        return tuple(dict.fromkeys(int(round(v)) for v in grid))
    return tuple(float(f"{v:.4g}") for v in grid)


#: The choices a rule reads (``activation_clock``): one model per choice, not a grid axis.
CHOICES = {row.name: row.choices for row in table.parameters() if row.choices}
#: What joins a rule's name and a choice other than its fallback in a model's name.
VARIANT = "@"


def fitted_parameters(rules: Sequence[str]) -> list[str]:
    """Return the parameters a policy's rules read that are fitted (all but :data:`NOT_FITTED` and the choices)."""
    names = []
    for rule in rules:
        for param in RULE_PARAMETERS[rule.split(VARIANT)[0]]:
            if param not in names and param not in NOT_FITTED and param not in CHOICES:
                names.append(param)
    return names


def variants(rules: Sequence[str]) -> list[tuple[str, dict]]:
    """Return ``(name, choices)`` of each model of a policy: one per value of the choices its rules read.

    The fallback of every choice keeps the policy's name and sets nothing (today's model);
    another is ``activation@episodes``, setting ``{"activation_clock": "episodes"}``.
    """
    name = "+".join(rules)
    read = [p for p in CHOICES if any(p in RULE_PARAMETERS[rule] for rule in rules)]
    out = [(name, {})]
    for param in read:
        out += [(f"{name}{VARIANT}{choice}", {param: choice}) for choice in CHOICES[param][1:]]
    return out


@dataclass(frozen=True)
class Model:
    """A model of reuse: a forgetting policy over its grid, a baseline, or a recency regression."""

    name: str
    kind: str  # "wm" | "baseline" | "recency"
    settings: tuple = ()  # wm: one dict per grid point (policy + parameters)
    parameters: tuple = ()  # wm: the fitted parameter names


def wm_models(grids: Optional[Mapping[str, Sequence]] = None) -> list[Model]:
    """Every WM model: each rule of the core alone, then :data:`COMBINATIONS`; grids from ``grids``/:data:`GRIDS`."""
    grids = {**GRIDS, **(grids or {})}
    policies = [(rule,) for rule in RULES if rule not in EXCLUDED]
    policies += [combo for combo in COMBINATIONS if all(rule in RULES for rule in combo)]
    models = []
    for rules in policies:
        params = fitted_parameters(rules)
        axes = []
        for param in params:
            grid = tuple(grids[param]) if param in grids else default_grid(param)
            if len(rules) > 1 and len(grid) > COMBINED_VALUES:
                keep = np.unique(np.round(np.linspace(0, len(grid) - 1, COMBINED_VALUES)).astype(int))
                grid = tuple(grid[i] for i in keep)
            axes.append(grid)
        for name, chosen in variants(rules):
            settings = tuple({"policy": "+".join(rules), **chosen, **dict(zip(params, values))}
                             for values in product(*axes))
            models.append(Model(name, "wm", settings, tuple(params)))
    return models


def policy_of(setting: Mapping[str, object]) -> ForgettingPolicy:
    """Return the core's policy for a grid point (validated by the core)."""
    return ForgettingPolicy.from_settings(dict(setting))


#: Rules enforced by the buffer after each encoding event (:class:`~fsreg_ros.core.memory.Limits`),
#: which the WM Manager's clock never triggers.
ENCODING_RULES = frozenset(("displacement", "displacement-lfu", "displacement-random", "similarity", "global-capacity"))
#: Rules that count something other than seconds (episodes, encodings; the shared pool: sizes).
#: Any other rule -- decay, activation, and a rule this module does not know -- needs a wall clock.
COUNTING_RULES = ENCODING_RULES | {"shared-capacity", "episodes"}
#: Predictors that read seconds: their regressions are left out of a game without times.
CLOCK_PREDICTORS = frozenset(("seconds",))


def needs_clock(policy: str) -> bool:
    """Whether a policy's forgetting reads the wall clock (so a game without times cannot be replayed under it).

    ``policy`` is a model's name: ``activation@episodes`` and ``activation@words`` count on
    their entity's own clock, not seconds.
    """
    name, _, choice = policy.partition(VARIANT)
    if choice and choice != CHOICES["activation_clock"][0]:
        return any(rule not in COUNTING_RULES | {"activation"} for rule in name.split("+") if rule != "none")
    return any(rule not in COUNTING_RULES for rule in name.split("+") if rule != "none")


#: The family of each model that is not a rule (a rule's family is ``rule``).
FAMILIES = {"none": "baseline", "no-forgetting": "baseline", "last-description": "baseline",
            "said-by-describer": "baseline", "constant": "baseline", **{name: "regression" for name in RECENCY}}
#: Suffixes of a rule's variants: its graded link, and its per-player WM.
GRADED, PLAYER = "/graded", "/player"


def family(name: str) -> str:
    """Return a model's family: ``rule``, ``baseline`` or ``regression``."""
    base = name.split("/")[0]
    return FAMILIES.get(base, "rule")
