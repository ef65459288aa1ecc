"""The scripts' start-up, written once: the repository's ``.venv`` Python, the import path, loopback ROS.

``python3 scripts/bench_core.py``, ``./scripts/bench_core.py`` and
``.venv/bin/python scripts/bench_core.py`` all end up in ``.venv`` (created or
refreshed by ``scripts/venv.sh`` when missing), so the package and its
dependencies are importable.  Every script under ``scripts/`` starts with one
import and one call, before it imports anything of fsreg::

    from venv_python import prepare  # noqa: E402
    REPO = prepare("bench_graph.py", loopback=True)  # .venv, import path, loopback ROS

(Python puts the running script's folder, ``scripts/``, first on the import path, so
this module is found however the script was started.)
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
VENV = REPO / ".venv"


def use_venv() -> None:
    """Re-execute the running script with ``.venv/bin/python`` unless it already runs there."""
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    python = VENV / "bin" / "python"
    if not python.exists():
        subprocess.run([str(REPO / "scripts" / "venv.sh")], check=True)
    os.execv(str(python), [str(python), os.path.abspath(sys.argv[0]), *sys.argv[1:]])


def prepare(prog: str, *, venv: bool = True, loopback: bool = False, support: bool = False) -> Path:
    """Start a script: run it in ``.venv`` (``venv``), make the repository importable, set up ROS; return the repo.

    ``loopback``: give the process fsreg's loopback-only ROS environment before rclpy loads,
    or refuse a widening one with one line naming ``prog`` (exit 2,
    :func:`fsreg_ros.ros.network.use_loopback_environment`).  ``support``: the test helpers
    (``test/support``: the naive references, the fuzzer) importable too.
    """
    if venv:
        use_venv()
    for path in (REPO / "scripts", REPO, *([REPO / "test" / "support"] if support else [])):
        if str(path) not in sys.path:
            sys.path.insert(0, str(path))
    if loopback:
        from fsreg_ros.ros.network import use_loopback_environment

        use_loopback_environment(prog)
    return REPO
