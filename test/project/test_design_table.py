"""docs/design.md's concept-to-file table names only what exists.

Every backticked name in the table's "where" column is checked:

* a path (it holds a ``/``) exists under ``fsreg_ros/`` or the repository root
  (``core/algorithms/port.py``, ``core/lexicon/``, ``launch/fsreg.launch.py``); a ROS message type
  (``std_msgs/String``) is left alone;
* ``Name.member`` names a class with that member (a method, property or field), or a
  module (``memory.COLUMN_MIN``) or package (``contract.PolicySettings``) defining it;
* a bare name is a class, function or constant defined in some module of the package,
  a method of some class, or a module's name; a forgetting rule's name
  (``shared-capacity``) is one of :data:`fsreg_ros.core.forgetting.policies.RULES`.

The definitions are read from the source (ast), so nothing is imported.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

from fsreg_ros.core.forgetting.policies import RULES

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "fsreg_ros"
DESIGN = REPO / "docs" / "design.md"
HEADER = "| paper concept | where |"


def table_names(text: str) -> list[str]:
    """Return every backticked name in the table's second column, in order."""
    start = text.index(HEADER)
    end = text.index("\n\n", start)
    names = []
    for line in text[start:end].splitlines()[2:]:
        cells = line.split("|")
        names += re.findall(r"`([^`]+)`", cells[2])
    return names


class Index:
    """What the package defines: classes and their members, each module's top-level names."""

    def __init__(self) -> None:
        self.members: dict[str, set[str]] = defaultdict(set)  # class -> members
        self.top: dict[str, set[str]] = defaultdict(set)  # module or package name -> its top-level names
        self.methods: set[str] = set()
        self.modules: set[str] = set()
        for path in PACKAGE.rglob("*.py"):
            module = path.parent.name if path.name == "__init__.py" else path.stem
            self.modules.add(module)
            tree = ast.parse(path.read_text(), str(path))
            names = self._top_names(tree)
            self.top[module] |= names
            for package in path.relative_to(PACKAGE).parts[:-1]:
                self.top[package] |= names
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef):
                    body = self._top_names(node)
                    self.members[node.name] |= body
                    self.methods |= body

    @staticmethod
    def _top_names(tree: ast.AST) -> set[str]:
        names = set()
        for node in tree.body:  # type: ignore[attr-defined]
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, ast.Assign):
                names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                names.add(node.target.id)
        return names

    def problem(self, name: str) -> str | None:
        """Return why ``name`` names nothing that exists (None: it does)."""
        if "/" in name:
            if re.match(r"[a-z_]+_msgs/", name):
                return None
            exists = (PACKAGE / name).exists() or (REPO / name).exists()
            return None if exists else f"`{name}`: no such path under fsreg_ros/ or the repository"
        if name in RULES:
            return None
        if "." in name and not name.endswith(".py"):
            owner, member = name.split(".", 1)
            if owner in self.members:
                return None if member in self.members[owner] else f"`{name}`: class {owner} has no {member}"
            if owner in self.top:
                return None if member in self.top[owner] else f"`{name}`: module {owner} defines no {member}"
            return f"`{name}`: no class or module {owner}"
        if name.endswith(".py"):
            return None if any(PACKAGE.rglob(name)) else f"`{name}`: no such file"
        known = name in self.modules or name in self.methods or any(name in names for names in self.top.values())
        return None if known else f"`{name}`: defined nowhere in fsreg_ros"


def test_every_name_in_the_design_table_exists():
    names = table_names(DESIGN.read_text())
    assert len(names) > 100  # the table was found and read
    index = Index()
    assert [p for p in map(index.problem, names) if p] == []


def test_the_table_check_finds_what_does_not_exist():
    """Guard against a check that passes anything: each kind of stale name is reported."""
    index = Index()
    assert index.problem("core/algorithms/port.py") is None and index.problem("WMBuffer.decay_now") is None
    assert index.problem("memory.COLUMN_MIN") is None and index.problem("contract.PolicySettings") is None
    assert index.problem("nodes/manage_link.py") is not None  # moved to ros/
    assert index.problem("WMBuffer.decay_later") is not None
    assert index.problem("memory.NO_SUCH") is not None
    assert index.problem("apply_ticks") is not None  # gone
    assert index.problem("nosuch.py") is not None


def test_the_docs_index_lists_every_document():
    """docs/README.md links every page of docs/, and nothing else there."""
    index = (REPO / "docs" / "README.md").read_text()
    linked = set(re.findall(r"\]\(([a-z-]+\.md)\)", index))
    pages = {p.name for p in (REPO / "docs").glob("*.md") if p.name != "README.md"}
    assert linked == pages
