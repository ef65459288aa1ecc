"""Run a repository script with the repository's own Python when the current one lacks fsreg's dependencies."""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
VENV_PYTHON = REPO / ".venv" / "bin" / "python"
#: Set on the re-run, so that a venv that cannot import the modules either stops with an error.
GUARD = "FSREG_SCRIPT_REEXEC"


def use_project_python(script: str, modules: tuple[str, ...] = ("yaml", "pydantic")) -> None:
    """Return if ``modules`` import here; else re-run ``script`` with ``.venv``'s Python, or exit with a message."""
    sys.path.insert(0, str(REPO))
    try:
        for module in modules:
            importlib.import_module(module)
        return
    except ImportError as err:
        missing = err.name or str(err)
    if VENV_PYTHON.exists() and not os.environ.get(GUARD):
        os.environ[GUARD] = "1"
        os.execv(str(VENV_PYTHON), [str(VENV_PYTHON), script, *sys.argv[1:]])
    sys.exit(f"{Path(script).name}: cannot import {missing} with {sys.executable}; run scripts/venv.sh first")
