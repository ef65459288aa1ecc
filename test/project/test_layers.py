"""The package's layers, read off the source: no import circle, and no arrow pointing up.

Every module under ``fsreg_ros/`` is parsed and every import statement it holds is read
(at module level, inside a function, under ``if TYPE_CHECKING``: all of them), including
``importlib.import_module`` calls: with a literal name, that name; with a computed one
(a table of lazy exports), every relative module name written as a string in the module.
An import names a *module*: ``from .x import y`` imports ``x`` and, when ``x`` is a
package holding a module ``y``, ``x.y`` too; importing a package means its ``__init__``.
A submodule's parent ``__init__`` (which Python runs first) is not counted as an import,
so a package may import its own modules.

The layers, bottom to top, as ``fsreg_ros/ros/__init__.py`` documents them:
``core`` -> ``contract`` -> ``ros`` -> ``nodes`` -> ``tools`` and ``testing``; ``research``
sits on ``core`` alone, and only ``tools`` (and ``research`` itself) may import it.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path
from typing import Callable, Iterator, Optional

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "fsreg_ros"
#: The layers by rank: a module may import modules of its own layer or of a lower rank.
RANK = {"core": 0, "contract": 1, "ros": 2, "nodes": 3, "tools": 4, "testing": 4}
#: Layers apart from the stack: what each may import, and who may import it.
RESEARCH_MAY_IMPORT = {"core", "research"}
MAY_IMPORT_RESEARCH = {"tools", "research"}
#: A relative module name written as a string (``".live"``, ``"..ros.client"``).
RELATIVE = re.compile(r"\.+[a-z_]+(\.[a-z_]+)*")


def module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    """Every module of the package, by dotted name (a package by its ``__init__``)."""
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _resolve(importer: str, is_package: bool, level: int, module: Optional[str]) -> str:
    if level == 0:
        return module or ""
    base = importer.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """Return the modules of the package that ``name`` (at ``path``) imports, anywhere in its source."""
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    dynamic = False  # import_module with a computed name

    def add(target: str) -> None:
        while target and target not in known:  # ``a.b.Name`` -> the module ``a.b``
            target = target.rpartition(".")[0]
        if target and target != name:
            found.add(target)

    def add_dynamic(target: str) -> None:  # import_module(target, __name__)
        if target.startswith("."):
            level = len(target) - len(target.lstrip("."))
            add(_resolve(name, is_package, level, target.lstrip(".") or None))
        else:
            add(target)

    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(name, is_package, node.level, node.module)
            for alias in node.names:
                if f"{base}.{alias.name}" in known:
                    add(f"{base}.{alias.name}")
                else:
                    add(base)
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module":
            if node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
                add_dynamic(node.args[0].value)
            else:
                dynamic = True
    if dynamic:
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and RELATIVE.fullmatch(node.value):
                add_dynamic(node.value)
    return {m for m in found if m.startswith("fsreg_ros")}


def import_graph() -> dict[str, set[str]]:
    """Return every module's imports (a fresh copy of the graph read once per run)."""
    return {name: set(targets) for name, targets in _import_graph().items()}


@functools.lru_cache(maxsize=1)
def _import_graph() -> dict[str, frozenset[str]]:
    known = modules()
    names = set(known)
    return {name: frozenset(imports_of(name, path, names)) for name, path in known.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Return the strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def layer(module: str) -> Optional[str]:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None  # None: the top package's __init__


def arrows(graph: dict[str, set[str]], part: Callable[[str], Optional[str]]) -> Iterator[tuple[str, str, str, str]]:
    """Yield ``(importer, target, its part, the target's)`` for each import between two parts (``part``: None, none)."""
    for importer, targets in sorted(graph.items()):
        mine = part(importer)
        for target in sorted(targets):
            theirs = part(target)
            if mine is not None and theirs is not None and mine != theirs:
                yield importer, target, mine, theirs


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    bad = []
    for importer, target, mine, theirs in arrows(graph, layer):
        if mine == "research":
            allowed = theirs in RESEARCH_MAY_IMPORT
        elif theirs == "research":
            allowed = mine in MAY_IMPORT_RESEARCH
        else:
            allowed = RANK[theirs] < RANK[mine] or (mine, theirs) == ("testing", "tools")
        if not allowed:
            bad.append(f"{importer} imports {target} ({mine} may not import {theirs})")
    return bad


def test_every_package_is_a_known_layer():
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert packages == set(RANK) | {"research"}


def test_the_import_graph_is_read():
    """Guard against a reader that reads nothing: known arrows of each kind are found."""
    graph = import_graph()
    assert "fsreg_ros.core.algorithms.port" in graph["fsreg_ros.core.algorithms.generation"]  # from .port import ...
    assert "fsreg_ros.core.state.journal" in graph["fsreg_ros.core.consultant.service"]  # from . import journal
    assert "fsreg_ros.core.consultant.service" in graph["fsreg_ros.core.consultant.local_port"]
    assert "fsreg_ros.testing.live" in graph["fsreg_ros.testing"]  # importlib.import_module(".live", __name__)
    assert "fsreg_ros.nodes.consultant" in graph["fsreg_ros.testing.live"]  # inside a function


def test_no_module_imports_itself_through_others():
    assert cycles(import_graph()) == []


def test_no_import_points_up_a_layer():
    assert layer_violations(import_graph()) == []


def test_the_checks_find_a_circle_and_an_upward_arrow():
    graph = {"fsreg_ros.core.a": {"fsreg_ros.core.b"}, "fsreg_ros.core.b": {"fsreg_ros.core.a"},
             "fsreg_ros.core.c": {"fsreg_ros.ros.x"}, "fsreg_ros.research.r": {"fsreg_ros.contract.y"},
             "fsreg_ros.nodes.n": {"fsreg_ros.research.r"}}
    assert cycles(graph) == [["fsreg_ros.core.a", "fsreg_ros.core.b"]]
    assert layer_violations(graph) == [
        "fsreg_ros.core.c imports fsreg_ros.ros.x (core may not import ros)",
        "fsreg_ros.nodes.n imports fsreg_ros.research.r (nodes may not import research)",
        "fsreg_ros.research.r imports fsreg_ros.contract.y (research may not import contract)",
    ]


#: The core's sub-packages by rank, as ``fsreg_ros/core/__init__.py`` lists them: a module
#: of one may import its own package's modules and those of a lower rank only.
CORE_RANK = {"io": 0, "memory": 0, "lexicon": 1, "forgetting": 1, "algorithms": 2, "state": 2,
             "consultant": 3, "scenario": 4, "simulation": 5}


def core_package(name: str) -> Optional[str]:
    """Return the core sub-package a module belongs to (None: not in one)."""
    parts = name.split(".")
    return parts[2] if len(parts) > 2 and parts[:2] == ["fsreg_ros", "core"] else None


def core_violations(graph: dict[str, set[str]]) -> list[str]:
    """Return every import between two core sub-packages that points up (or sideways) a rank."""
    return [f"{importer} imports {target} (core.{mine} may not import core.{theirs})"
            for importer, target, mine, theirs in arrows(graph, core_package) if CORE_RANK[theirs] >= CORE_RANK[mine]]


def test_every_core_package_has_a_rank_and_says_what_it_owns():
    core = PACKAGE / "core"
    packages = {p.name for p in core.iterdir() if (p / "__init__.py").exists()}
    assert packages == set(CORE_RANK)
    assert sorted(p.name for p in core.glob("*.py")) == ["__init__.py"]  # no module left on the floor
    listing = (core / "__init__.py").read_text()
    for name in CORE_RANK:
        assert f"``{name}``" in listing
        assert ast.get_docstring(ast.parse((core / name / "__init__.py").read_text()))


def test_no_core_import_points_up_a_rank():
    assert core_violations(import_graph()) == []


def test_the_core_check_finds_an_upward_arrow():
    graph = {"fsreg_ros.core.memory.buffer": {"fsreg_ros.core.forgetting.policies", "fsreg_ros.core.memory.queue"},
             "fsreg_ros.core.simulation.simulator": {"fsreg_ros.core.io.paths"},
             "fsreg_ros.core.state.store": {"fsreg_ros.core.algorithms.port"}}
    assert core_violations(graph) == [
        "fsreg_ros.core.memory.buffer imports fsreg_ros.core.forgetting.policies"
        " (core.memory may not import core.forgetting)",
        "fsreg_ros.core.state.store imports fsreg_ros.core.algorithms.port (core.state may not import core.algorithms)",
    ]


#: What the contract may not use of the core: the consultant service, its sessions (views) and
#: its persistence -- running an op is core/consultant/ops.py's, dispatched from ros/ (issue 35.4).
NOT_FOR_THE_CONTRACT = {"fsreg_ros.core.consultant.service", "fsreg_ros.core.consultant.views",
                        "fsreg_ros.core.consultant.persistence", "fsreg_ros.core.consultant.local_port"}


def test_the_contract_is_names_schemas_and_codecs_only():
    graph = import_graph()
    used = sorted(f"{m} imports {t}" for m, targets in graph.items() if layer(m) == "contract"
                  for t in targets if t in NOT_FOR_THE_CONTRACT)
    assert used == []
