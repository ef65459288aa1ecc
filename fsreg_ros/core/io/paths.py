"""Where fsreg finds its default config files (lexicon, params).

``pip install -e .`` does not install ``data_files`` and colcon installs them under
``share/fsreg_ros``; a source checkout has them in ``config/``.  Look in that order
of specificity, without importing anything from ROS.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

PACKAGE = "fsreg_ros"


def config_dirs() -> list[Path]:
    """Candidate config directories, most specific first."""
    dirs = []
    if os.environ.get("FSREG_CONFIG_DIR"):
        dirs.append(Path(os.environ["FSREG_CONFIG_DIR"]))
    dirs.append(Path(__file__).resolve().parents[3] / "config")  # source tree / editable
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share" / PACKAGE / "config")
    dirs.append(Path(sys.prefix) / "share" / PACKAGE / "config")
    return dirs


def config_path(name: str) -> Path:
    """Return the first existing ``name`` among :func:`config_dirs`; FileNotFoundError if none."""
    for directory in config_dirs():
        candidate = directory / name
        if candidate.is_file():
            return candidate
    searched = ", ".join(str(d) for d in config_dirs())
    raise FileNotFoundError(f"config file '{name}' not found (searched: {searched})")
