"""The sweep's axes, shared by :mod:`.sweep` (which runs them) and :mod:`.plot` (which draws them).

The grid's memory parameters in column order (a policy reads some of them) and the
outdated-rate bounds of the recommendation table.  A module of its own so that the
plots need not import the sweep, nor the sweep the plots, at import time.
"""

from ..core.forgetting import settings

#: The grid parameters, in column order (a policy reads some of them): the memory settings a
#: rule needs, in the settings table's order (``seed``, which has a fallback, is drawn per game).
GRID = tuple(row.name for row in settings.parameters() if row.fallback is None)
#: The outdated-rate bounds of the recommendation table.
BOUNDS = (0.01, 0.05)
