"""Lint the package the way ament packages do (ament_flake8 / ament_pep257).

flake8 (pycodestyle + pyflakes) with a 120-column limit, and pydocstyle with the
pep257 convention (missing docstrings allowed, as ament_pep257's defaults do); the
settings live in ``setup.cfg`` so an editor and this test agree.  Each test names
every offending line, so a failure says exactly what to fix.
"""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
#: Every Python tree of the repository (the venv, build and install trees are not ours).
TREES = ["fsreg_ros", "test", "scripts", "launch", "setup.py"]


def run(tool: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", tool, *TREES], cwd=REPO, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.parametrize("tool", ["flake8", "pydocstyle"])
def test_tree_is_clean(tool):
    result = run(tool)
    assert result.returncode == 0, f"{tool} found problems:\n{result.stdout}{result.stderr}"


def test_the_linters_do_find_problems(tmp_path):
    """Guard against a configuration that checks nothing: a bad file must be reported."""
    bad = tmp_path / "bad.py"
    bad.write_text('import os\n\n\ndef f():\n    """returns nothing"""\n    x = 1\n')
    flake8 = subprocess.run([sys.executable, "-m", "flake8", "--config", str(REPO / "setup.cfg"), str(bad)],
                            capture_output=True, text=True, timeout=60)
    assert "F401" in flake8.stdout and "F841" in flake8.stdout
    pydocstyle = subprocess.run([sys.executable, "-m", "pydocstyle", "--config", str(REPO / "setup.cfg"), str(bad)],
                                capture_output=True, text=True, timeout=60)
    assert "D400" in pydocstyle.stdout and "D403" in pydocstyle.stdout
