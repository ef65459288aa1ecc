"""The core is pure Python: no module under ``fsreg_ros/core/`` imports ROS, at any depth.

Two checks, so neither can pass by accident: every module of the package (sub-packages
``scenario`` and ``lexicon`` included) is imported in a fresh interpreter and no ROS
package may end up loaded; and every source file under ``core/`` is parsed and no import
statement may name a ROS package (an import inside a function is caught too).
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "fsreg_ros" / "core"
#: Packages of a ROS installation (client library, messages, launch, index).
ROS_PACKAGES = ("rclpy", "rcl_interfaces", "std_msgs", "diagnostic_msgs", "rosgraph_msgs", "builtin_interfaces",
                "rosidl_parser", "rosidl_runtime_py", "ament_index_python", "launch", "launch_ros")

IMPORT_ALL = f"""
import json, pkgutil, importlib, sys
import fsreg_ros.core as core
names = [m.name for m in pkgutil.walk_packages(core.__path__, "fsreg_ros.core.")]
for name in names:
    importlib.import_module(name)
ros = sorted({{m.split(".")[0] for m in sys.modules}} & set({list(ROS_PACKAGES)!r}))
print(json.dumps({{"modules": names, "ros": ros}}))
"""


def core_sources() -> list[Path]:
    return sorted(CORE.rglob("*.py"))


def test_importing_every_core_module_loads_no_ros_package():
    run = subprocess.run([sys.executable, "-c", IMPORT_ALL], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout)
    assert found["ros"] == []
    expected = {".".join(("fsreg_ros",) + p.relative_to(REPO / "fsreg_ros").with_suffix("").parts)
                for p in core_sources() if p.name != "__init__.py"}
    assert expected <= set(found["modules"])  # every file, in every sub-package, was imported
    assert {"fsreg_ros.core.scenario.schema", "fsreg_ros.core.lexicon.words"} <= set(found["modules"])


def imported_packages(path: Path) -> set[str]:
    """Return the top-level package of every import statement in ``path`` (relative imports excluded)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_no_core_source_imports_a_ros_package():
    sources = core_sources()
    assert any(p.parent.name == "scenario" for p in sources) and any(p.parent.name == "lexicon" for p in sources)
    offenders = {str(p.relative_to(REPO)): sorted(imported_packages(p) & set(ROS_PACKAGES)) for p in sources}
    assert {p: bad for p, bad in offenders.items() if bad} == {}


def test_the_source_check_finds_a_ros_import(tmp_path):
    """Guard against a check that checks nothing: a nested import in a function is found."""
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from rclpy.node import Node\n    import std_msgs.msg\n")
    assert imported_packages(bad) & set(ROS_PACKAGES) == {"rclpy", "std_msgs"}
