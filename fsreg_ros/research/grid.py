"""The sweep's axes, shared by :mod:`.sweep` (which runs them) and :mod:`.plot` (which draws them).

The grid's memory parameters in column order (a policy reads some of them) and the
outdated-rate bounds of the recommendation table.  A module of its own so that the
plots need not import the sweep, nor the sweep the plots, at import time.
"""

#: The grid parameters, in column order (a policy reads some of them).
GRID = ("decay_period", "capacity", "global_capacity", "shared_capacity")
#: The outdated-rate bounds of the recommendation table.
BOUNDS = (0.01, 0.05)
