"""Make a benchmark script run with the repository's ``.venv`` Python, however it was started.

``python3 scripts/bench_core.py``, ``./scripts/bench_core.py`` and
``.venv/bin/python scripts/bench_core.py`` all end up in ``.venv`` (created or
refreshed by ``scripts/venv.sh`` when missing), so the package and its
dependencies are importable.  Each ``scripts/bench_*.py`` calls :func:`use_venv`
before importing anything of fsreg.
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
        sys.path.insert(0, str(REPO))
        return
    python = VENV / "bin" / "python"
    if not python.exists():
        subprocess.run([str(REPO / "scripts" / "venv.sh")], check=True)
    os.execv(str(python), [str(python), os.path.abspath(sys.argv[0]), *sys.argv[1:]])
