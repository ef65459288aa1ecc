"""Named presets: the memory settings and REG's WM order for a robot builder's common wishes.

The one table of presets (:data:`PRESETS`), read by ``--preset NAME`` in fsreg-up,
fsreg-sim and fsreg-graph and by the launch argument ``preset:=NAME``.  A preset fills
in the settings it names; every setting given explicitly beside it (a memory option,
``--wm-order``) overrides the preset's value, and the settings it does not name keep
the scenario's or the default.  The paper's reproduction takes no preset.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Mapping, Optional

from .settings import PolicyError


@dataclass(frozen=True)
class Preset:
    """One named preset: memory settings (the settings table's names), REG's WM order, what it is for."""

    name: str
    memory: Mapping[str, Any]
    wm_order: str
    description: str


PRESETS: tuple[Preset, ...] = (
    Preset("paper", MappingProxyType({"policy": "decay+displacement", "decay_period": 10.0, "capacity": 2}),
           "lru-first", "the paper's forgetting: decay (delta = 10 s) and displacement (alpha = 2), LRU order"),
    Preset("human-like", MappingProxyType({"policy": "episodes", "episode_window": 1}), "strength",
           "people's rule: keep what was said in an entity's last reference episode (k = 1), strongest first"),
)


def names() -> tuple[str, ...]:
    """Return every preset's name, in table order."""
    return tuple(p.name for p in PRESETS)


def preset(name: str) -> Preset:
    """Return the preset called ``name``; PolicyError (one line, naming the known ones) if there is none."""
    for row in PRESETS:
        if row.name == name:
            return row
    raise PolicyError(f"unknown preset {name!r} (known: {', '.join(names())})")


def apply(name: Optional[str], memory: Mapping[str, Any], wm_order: Optional[str]) -> tuple[dict, Optional[str]]:
    """Return ``memory`` and ``wm_order`` over preset ``name``'s (None: no preset, both as given).

    ``memory`` holds the settings given explicitly; each overrides the preset's.
    ``wm_order`` None means not given: the preset's order, else None.
    """
    if name is None:
        return dict(memory), wm_order
    row = preset(name)
    return {**row.memory, **memory}, wm_order if wm_order is not None else row.wm_order
