"""``fsreg-ctl``: talk to a live fsreg graph from the command line (no ROS install needed beyond the wheels).

    fsreg-ctl [--namespace NS] say TEXT...                 the human says TEXT: who did they mean?
    fsreg-ctl [--namespace NS] describe ENTITY [--context E...]   the robot describes ENTITY
    fsreg-ctl [--namespace NS] assert ENTITY PROP[:C]... [--domain D]   tell a consultant facts
    fsreg-ctl [--namespace NS] status                      readiness, memory per domain
    fsreg-ctl [--namespace NS] set KEY=VALUE...            change memory settings (or NODE:KEY=VALUE)
    fsreg-ctl [--namespace NS] params get|dump [ITEM...]   read parameters back (dump: ros2 param dump's YAML)
    fsreg-ctl [--namespace NS] watch [--events]            each entity's WM, live
    fsreg-ctl [--namespace NS] wm ENTITY                   one entity's WM now (the wm/state that shows every change)
    fsreg-ctl [--namespace NS] clock SECONDS               set a sim-time graph's clock
    fsreg-ctl [--namespace NS] view [--port N] [--host A]  a live web page of the graph's WM
    fsreg-ctl [--namespace NS] record DIR [--duration S]   record every fsreg topic to a rosbag2 folder
    fsreg-ctl [--namespace NS] state reset [--yes]         set the stored state aside, start from the scenario

Every command checks its arguments before anything is sent (numbers finite and in
range, names and messages within the graph's limits, domains among those the graph
announced), waits (``--timeout``) until the graph in the namespace is ready (its WM
Manager's ``wm_manager/ready``), refuses to go on when two graphs share the namespace,
rejects an answer stamped by another graph, and stops with exit 3 within 2 s when the
graph leaves while it waits (its WM Manager stopped or died, or its readiness was lost).
With ``--json`` each prints the answer as one JSON object (``watch``: one per line).
Errors are one line on stderr.  Exit codes: 0 answered, 1 the graph answered with an
error or refused (an unknown entity, a parameter change the node rejected, a clock
earlier than the graph's), 2 bad usage (malformed or out-of-range arguments, a node,
parameter or domain the graph does not have, input over the graph's size limits), 3 no
answer (no graph, not ready, timed out, the graph left, two graphs, another graph's answer).

``set``: a memory setting (``policy``, ``decay_period``, ``capacity``, ...) applies to
every domain's setting; ``DOMAIN.KEY=VALUE`` to one domain's (``inherit`` as the value
makes it follow the node-wide one); ``NODE:KEY=VALUE`` sets a parameter of another node
(``reg:algorithm=greedy``, ``consultant_faces:threshold=0.6``).  Keys, values and
ranges are checked against the node's declared parameters and the settings table (a
node-wide setting a domain overrides, an empty node-wide ``policy`` and ``use_sim_time``
are refused); every node's values are checked before any is set, so a refused command
changes nothing (:meth:`~fsreg_ros.ros.parameter_access.ParameterAccess.set_many`), and
what is printed is read back from the node.  ``assert``: ``PROP`` is certain (1.0), ``PROP:C`` has certainty C.

Commands are a table (:data:`~fsreg_ros.tools.ctl_table.COMMANDS`): adding one is one
function registered with :func:`~fsreg_ros.tools.ctl_table.command` (its arguments, and
what it needs: a ready graph, any graph, or none) in the module of its family:

* :mod:`~fsreg_ros.tools.ctl_table`: the table, the parser, exit codes, :class:`Ctl` (one command's run);
* :mod:`~fsreg_ros.tools.ctl_values`: ``assert``'s facts and ``set``'s assignments checked;
* :mod:`~fsreg_ros.tools.ctl_show`: the answers as text;
* :mod:`~fsreg_ros.tools.ctl_dialogue`: ``say``, ``describe``, ``assert``;
* :mod:`~fsreg_ros.tools.ctl_settings`: ``status``, ``set``, ``params``;
* :mod:`~fsreg_ros.tools.ctl_memory`: ``watch``, ``wm``, ``clock``;
* :mod:`~fsreg_ros.tools.ctl_serve`: ``view``, ``record`` (long-running);
* :mod:`~fsreg_ros.tools.ctl_state`: ``state reset``.

``state reset``: every consultant moves its state database aside (never deleting it)
and serves its scenario afresh (no runtime facts, empty WM), as a new incarnation; it
asks for confirmation on the terminal unless ``--yes``, refuses without a terminal and
without ``--yes`` (exit 2), and exits 1 when not confirmed.  It prints what each domain
set aside and where, and returns once the graph is ready again.
"""

from __future__ import annotations

import os
import sys
from typing import Optional, Sequence

from ..contract import normalise_namespace
from ..contract.naming import check_topic
from ..ros.network import NetworkRefused, enforce_loopback, require_loopback
from . import ctl_dialogue, ctl_settings, ctl_memory, ctl_serve, ctl_state  # noqa: F401 (registered in this order)
from .arguments import undecodable
from .ctl_table import COMMANDS, EXIT_USAGE, PROG, Ctl, UsageError, build_parser, option


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``fsreg-ctl``; return its exit code."""
    require_loopback(PROG)
    bad = undecodable(sys.argv[1:] if argv is None else argv)
    if bad is not None:
        print(f"{PROG}: error: {bad}", file=sys.stderr)
        return EXIT_USAGE
    args = build_parser().parse_args(argv)
    try:
        namespace = normalise_namespace(option(args, "namespace", ""))
        if option(args, "clock", None) is not None:
            try:
                check_topic(args.clock)
            except ValueError as err:
                raise UsageError(f"--clock: {err}") from None
        timeout = float(option(args, "timeout", 10.0))
        spec = COMMANDS[args.command]
        if spec.check is not None:
            spec.check(args)
    except (UsageError, ValueError) as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    try:
        os.environ.update(enforce_loopback(dict(os.environ)))
    except NetworkRefused as err:  # pragma: no cover - require_loopback refused it already
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    return Ctl(args, namespace, timeout).run()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
