"""Each memory setting is spelled in few places: the settings table generates the rest.

What counts (issue 26.5):

* a *place* is a module under ``fsreg_ros/`` whose code spells the setting: a string
  constant equal to its name (``"decay_period"``), to its command-line option
  (``"--decay-period"``), or starting with ``<name>=`` (``"decay_period=10"``).
  Docstrings and comments are documentation, not places; identifiers (a dataclass
  field ``WMLimits.capacity``, a keyword argument) are the code's structure, not a
  spelling of the setting as data;
* the documentation (``README.md`` and ``docs/*.md``, wherever they name the setting in
  backticks) counts as one place;
* ``core/settings.py`` (the table) is one place.

A setting may be spelled in at most three places: the table, the core rule that reads
it, the docs.  ``policy`` is not checked: it is also the name of the concept and of
the contract's wire field, spelled wherever a policy travels.

:data:`KNOWN` lists the places beyond that not fixed yet, exactly (a place fixed must
leave the list, a new one fails): the research modules' axis labels and short names
(``research/plot.py``, ``research/sweep.py``, ``tools/figures.py``) still key their
own dicts by the setting names (the labels would be columns of the table; other work
was editing those modules); ``research/tangrams.py`` keys its fitting grids, the
parameters it holds and the paper's values by the setting names (research data, not
the table's: a fitting grid is no property of the setting); and ``seed`` is also the
name of the sweep's game seed (``research/ledger.py`` keys a game's record by it).
"""

from __future__ import annotations

import ast
from pathlib import Path

from fsreg_ros.core import settings

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "fsreg_ros"
TABLE = "fsreg_ros/core/settings.py"
DOCS = "docs"
#: At most this many places per setting: the table, the core rule that reads it, the docs.
MOST = 3
#: Places beyond the limit, not fixed yet (setting -> modules): must be exact.
KNOWN: dict[str, set[str]] = {
    "decay_period": {"fsreg_ros/research/plot.py", "fsreg_ros/research/sweep.py", "fsreg_ros/research/tangrams.py",
                     "fsreg_ros/tools/figures.py"},
    "capacity": {"fsreg_ros/research/plot.py", "fsreg_ros/research/sweep.py", "fsreg_ros/research/tangrams.py",
                 "fsreg_ros/tools/figures.py"},
    "global_capacity": {"fsreg_ros/research/plot.py", "fsreg_ros/research/sweep.py",
                        "fsreg_ros/research/tangrams.py", "fsreg_ros/tools/figures.py"},
    # also the games' seed (a CSV column, a ledger record's key)
    "seed": {"fsreg_ros/research/ledger.py", "fsreg_ros/research/sweep.py", "fsreg_ros/research/tangrams.py",
             "fsreg_ros/tools/figures.py"},
    "shared_capacity": {"fsreg_ros/research/plot.py", "fsreg_ros/research/sweep.py",
                        "fsreg_ros/research/tangrams.py", "fsreg_ros/tools/figures.py"},
    "activation_decay": {"fsreg_ros/research/tangrams.py"},
    "activation_threshold": {"fsreg_ros/research/plot.py", "fsreg_ros/research/sweep.py",
                             "fsreg_ros/research/tangrams.py"},
}


def _docstrings(tree: ast.AST) -> set[int]:
    """Return the ids of the docstring nodes of a module, its classes and functions."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def spells(source: str, row: settings.Setting) -> bool:
    """Return True if ``source``'s code spells the setting ``row`` (see the module docstring)."""
    tree = ast.parse(source)
    skip = _docstrings(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in skip:
            text = node.value
            if text in (row.name, row.option) or text.startswith(row.name + "="):
                return True
    return False


def places(row: settings.Setting) -> set[str]:
    found = {str(p.relative_to(REPO)) for p in PACKAGE.rglob("*.py") if spells(p.read_text(), row)}
    docs = [REPO / "README.md", *(REPO / "docs").glob("*.md")]
    if any(f"`{row.name}`" in p.read_text() for p in docs):
        found.add(DOCS)
    return found


def test_each_setting_is_spelled_in_at_most_three_places():
    over = {}
    for row in settings.parameters():
        found = places(row)
        assert TABLE in found  # the table itself is read
        extra = found - KNOWN[row.name]
        if len(extra) > MOST:
            over[row.name] = sorted(extra)
    assert over == {}


def test_the_known_offenders_are_exact():
    """A place fixed leaves :data:`KNOWN` (so the list only shrinks)."""
    assert set(KNOWN) == {row.name for row in settings.parameters()}
    assert {name: sorted(KNOWN[name] - places(settings.setting(name))) for name in KNOWN} == {n: [] for n in KNOWN}


def test_the_check_finds_a_spelling_and_ignores_docstrings():
    row = settings.setting("decay_period")
    assert spells('x = {"decay_period": 1}', row) and spells('argv = ["--decay-period", "5"]', row)
    assert spells('args = ["decay_period=10"]', row)
    assert not spells('"""Reads ``decay_period``."""\nx = 1  # decay_period', row)
    assert not spells("limits.decay_period = 3", row)
