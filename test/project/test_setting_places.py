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
* ``core/forgetting/settings.py`` (the table) is one place.

A setting may be spelled in at most three places: the table, the core rule that reads
it, the docs.  ``policy`` is not checked: it is also the name of the concept and of
the contract's wire field, spelled wherever a policy travels.

Two kinds of place are allowed beyond that, each listed exactly (a place that stops
spelling a setting must leave its list, a new one fails): :data:`EXPERIMENTS`, the
research modules that define experiments by the settings they vary, as a scenario file
names them (a sweep's grid per setting, the tangram fits' grids and the paper's values,
the figure commands' arguments, the named presets); and :data:`HOMONYMS`, where ``seed`` is another concept
of the same name (a generated game's seed: a ledger record's key, a CSV column).  Every
label of a setting in plots, legends and tables comes from the table's ``symbol``,
``word`` and ``axis`` columns.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

from fsreg_ros.core.forgetting import settings

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "fsreg_ros"
TABLE = "fsreg_ros/core/forgetting/settings.py"
DOCS = "docs"
#: At most this many places per setting: the table, the core rule that reads it, the docs.
MOST = 3
#: The named presets, settings a builder runs by name (as a scenario file names them).
PRESETS = "fsreg_ros/core/forgetting/presets.py"
#: Experiment definitions that name the settings they vary, and the presets (setting -> modules): exact.
EXPERIMENTS: dict[str, set[str]] = {
    "decay_period": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/reuse_models.py", "fsreg_ros/tools/figures.py",
                     PRESETS},
    "capacity": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/reuse_models.py", PRESETS},
    "global_capacity": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/reuse_models.py"},
    "seed": {"fsreg_ros/research/reuse_models.py"},
    "shared_capacity": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/reuse_models.py"},
    "activation_decay": {"fsreg_ros/research/reuse_models.py", "fsreg_ros/tools/figures.py"},
    "activation_threshold": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/reuse_models.py"},
    "activation_clock": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/grid.py",
                         "fsreg_ros/research/reuse_models.py"},
    "episode_window": {"fsreg_ros/research/sweep.py", "fsreg_ros/research/grid.py",
                       "fsreg_ros/research/reuse_models.py", PRESETS},
}
#: Another concept of the same name: a generated game's seed.
HOMONYMS: dict[str, set[str]] = {
    "seed": {"fsreg_ros/research/ledger.py", "fsreg_ros/research/sweep.py", "fsreg_ros/tools/figures.py"},
}


def allowed(name: str) -> set[str]:
    """The places beyond the table, the rule and the docs that may spell setting ``name``."""
    return EXPERIMENTS.get(name, set()) | HOMONYMS.get(name, set())


def _docstrings(tree: ast.AST) -> set[int]:
    """Return the ids of the docstring nodes of a module, its classes and functions."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def constants(source: str) -> frozenset[str]:
    """Return the string constants of ``source``'s code (its docstrings left out)."""
    tree = ast.parse(source)
    skip = _docstrings(tree)
    return frozenset(node.value for node in ast.walk(tree)
                     if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in skip)


def spells(source: str, row: settings.Setting) -> bool:
    """Return True if ``source``'s code spells the setting ``row`` (see the module docstring)."""
    return _spelled(constants(source), row)


def _spelled(texts: frozenset[str], row: settings.Setting) -> bool:
    return any(text in (row.name, row.option) or text.startswith(row.name + "=") for text in texts)


@functools.lru_cache(maxsize=1)
def sources() -> tuple[tuple[str, frozenset[str]], ...]:
    """Every package module's string constants, by path: each module parsed once per run, not once per setting."""
    return tuple((str(p.relative_to(REPO)), constants(p.read_text())) for p in sorted(PACKAGE.rglob("*.py")))


def places(row: settings.Setting) -> set[str]:
    found = {path for path, texts in sources() if _spelled(texts, row)}
    docs = [REPO / "README.md", *(REPO / "docs").glob("*.md")]
    if any(f"`{row.name}`" in p.read_text() for p in docs):
        found.add(DOCS)
    return found


def test_each_setting_is_spelled_in_at_most_three_places():
    over = {}
    for row in settings.parameters():
        found = places(row)
        assert TABLE in found  # the table itself is read
        extra = found - allowed(row.name)
        if len(extra) > MOST:
            over[row.name] = sorted(extra)
    assert over == {}


def test_the_allowed_places_are_exact():
    """Every listed place still spells its setting (so the lists only shrink), and every name is a setting."""
    names = {row.name for row in settings.parameters()}
    assert set(EXPERIMENTS) <= names and set(HOMONYMS) <= names
    stale = {name: sorted(allowed(name) - places(settings.setting(name))) for name in names}
    assert {name: where for name, where in stale.items() if where} == {}


def test_every_setting_has_its_labels():
    """Plots, legends and sweep labels name a setting by the table's columns: none may be empty."""
    for row in settings.parameters():
        assert row.symbol and row.word and row.axis, row.name
        assert row.word.isascii() and " " not in row.word, row.name
