"""The sweep's axes, shared by :mod:`.sweep` (which runs them) and :mod:`.plot` (which draws them).

The grid's memory parameters in column order (a policy reads some of them), the
sweep-only axes (the episode window k, which has a fallback, and REG's WM order) and
the outdated-rate bounds of the recommendation table.  A module of its own so that
the plots need not import the sweep, nor the sweep the plots, at import time.
"""

from typing import Iterable

from ..core.forgetting import settings

#: The grid parameters, in column order (a policy reads some of them): the memory settings a
#: rule needs, in the settings table's order (``seed``, which has a fallback, is drawn per game).
GRID = tuple(row.name for row in settings.parameters() if row.fallback is None)
#: Parameters with a fallback the sweep still runs over when a policy reads them (rule
#: ``episodes``; rule ``activation``'s clock, a text, only when ``--activation-clocks`` is
#: given): their columns appear only in a sweep that has such a policy.
FALLBACK_GRID = ("activation_clock", "episode_window")
#: Every axis a setting may have, in column order (numbers, and the activation clock's text).
NUMERIC = GRID + FALLBACK_GRID
#: REG's order of the target's WM properties; its column appears only in a sweep that runs another one.
WM_ORDER = "wm_order"
DEFAULT_WM_ORDER = "lru-first"
#: The outdated-rate bounds of the recommendation table.
BOUNDS = (0.01, 0.05)


def axes(settings_run: Iterable) -> tuple:
    """Return the setting columns of a sweep's files: :data:`GRID`, then the sweep-only axes its settings use."""
    mine = list(settings_run)
    extra = tuple(p for p in FALLBACK_GRID if any(getattr(s, p) is not None for s in mine))
    if any(s.wm_order != DEFAULT_WM_ORDER for s in mine):
        extra += (WM_ORDER,)
    return GRID + extra
