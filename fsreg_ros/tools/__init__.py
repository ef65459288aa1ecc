"""fsreg's command-line programs: thin front ends over the core, the contract and the ROS glue.

* :mod:`.sim` (``fsreg-sim``: a scenario through the core's simulator; the options ``fsreg-graph`` shares),
* :mod:`.graph` (``fsreg-graph``: a scenario through the real multi-process node graph),
* :mod:`.up` (``fsreg-up``: start the live graph and keep it up),
* :mod:`.ctl` (``fsreg-ctl``: talk to a live graph),
* :mod:`.figures` (runs every research figure's command; `scripts/figures.sh`), :mod:`.worlds` (seeded random worlds).

The research workbench's programs (``fsreg-eval``, ``fsreg-sweep``, ``fsreg-plot``) live in
:mod:`fsreg_ros.research.cli`.  Top layer: may import every package of fsreg; nothing imports it
but the tests, the benchmarks and the research figures' runner.
"""
