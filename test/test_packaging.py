"""Packaging: the core is ROS-free, colcon installs every node where `ros2 run` looks,
and the launch file names only real executables with their parameters."""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
NODES = ["parser", "reference_resolution", "consultant", "wm_manager", "reg", "dialogue_player"]


def setup_entry_points() -> dict[str, str]:
    text = (REPO / "setup.py").read_text()
    return dict(re.findall(r'"([\w-]+)": "(fsreg_ros[\w.]*:\w+)"', text))


def test_core_imports_no_ros():
    """Importing every core module pulls in neither rclpy nor any ROS message package."""
    code = (
        "import sys, pkgutil, importlib, fsreg_ros.core as core\n"
        "for m in pkgutil.iter_modules(core.__path__): importlib.import_module('fsreg_ros.core.' + m.name)\n"
        "bad = sorted(n for n in sys.modules if n.split('.')[0] in "
        "('rclpy', 'std_msgs', 'diagnostic_msgs', 'rosgraph_msgs', 'rcl_interfaces', 'ament_index_python'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == ""


def test_core_sources_never_mention_rclpy():
    for path in (REPO / "fsreg_ros" / "core").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                assert not any(n.split(".")[0] == "rclpy" for n in names), path


def test_every_node_is_a_console_script_with_a_main():
    entry = setup_entry_points()
    for node in NODES:
        assert node in entry, node
        module, func = entry[node].split(":")
        mod = __import__(module, fromlist=[func])
        assert callable(getattr(mod, func))


def test_launch_file_names_declared_executables_with_their_parameters():
    tree = ast.parse((REPO / "launch" / "fsreg.launch.py").read_text())
    constants = {
        t.id: ast.literal_eval(n.value)
        for n in tree.body
        if isinstance(n, ast.Assign)
        for t in n.targets
        if isinstance(t, ast.Name) and isinstance(n.value, ast.Constant)
    }

    def value(node):
        return constants[node.id] if isinstance(node, ast.Name) else ast.literal_eval(node)

    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "Node"]
    assert calls
    seen = {}
    for call in calls:
        kwargs = {k.arg: k.value for k in call.keywords}
        assert value(kwargs["package"]) == "fsreg_ros"
        exe = value(kwargs["executable"])
        params = set()
        for d in ast.walk(kwargs["parameters"]):
            if isinstance(d, ast.Dict):
                params |= {ast.literal_eval(k) for k in d.keys if k is not None}
        seen[exe] = params
    assert set(seen) == {"consultant", "wm_manager", "parser", "reference_resolution", "reg"}
    assert set(seen) <= set(setup_entry_points())
    assert {"domain", "kb"} <= seen["consultant"]
    assert {"domains", "policy", "decay_period", "capacity", "global_capacity"} <= seen["wm_manager"]
    assert {"domains", "algorithm", "wm_order"} <= seen["reg"]
    assert {"domains"} <= seen["reference_resolution"]
    assert {"kb"} <= seen["parser"]


def test_params_files_name_real_nodes():
    import yaml

    known = set(NODES) | {"consultant_faces"}
    for path in (REPO / "config").glob("*.yaml"):
        data = yaml.safe_load(path.read_text())
        if not isinstance(data, dict) or not all(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
            continue  # not a params file (lexicon, expectations)
        assert set(data) <= known, path


@pytest.mark.slow
def test_colcon_build_installs_every_executable(tmp_path):
    colcon = Path(sys.executable).parent / "colcon"
    if not colcon.exists():
        colcon = Path(shutil.which("colcon") or "")
    assert colcon.is_file(), "colcon not installed (requirements-dev.txt)"
    src = tmp_path / "src" / "fsreg_ros"
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".venv", ".git", "build", "install", "log", "__pycache__", "*.egg-info"))
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.run(
        [str(colcon), "build", "--base-paths", "src", "--event-handlers", "console_direct-"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300, env=env,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    lib = tmp_path / "install" / "fsreg_ros" / "lib" / "fsreg_ros"
    for node in NODES:
        exe = lib / node
        assert exe.is_file() and os.access(exe, os.X_OK), f"{exe} missing"
    share = tmp_path / "install" / "fsreg_ros" / "share"
    assert (share / "fsreg_ros" / "config" / "lexicon.yaml").is_file()
    assert (share / "fsreg_ros" / "launch" / "fsreg.launch.py").is_file()
    assert (share / "ament_index" / "resource_index" / "packages" / "fsreg_ros").is_file()
    # `ros2 run fsreg_ros consultant` stand-in: the installed executable starts and
    # refuses a missing KB with one clear line and exit code 2.
    prefix = tmp_path / "install" / "fsreg_ros"
    site = next(prefix.glob("lib/python3*/site-packages"))
    assert (site / "fsreg_ros" / "nodes" / "consultant.py").is_file()
    run_env = dict(env, AMENT_PREFIX_PATH=str(prefix), PYTHONPATH=f"{site}{os.pathsep}{env.get('PYTHONPATH', '')}")
    run = subprocess.run(
        [str(lib / "consultant"), "--ros-args", "-p", "domain:=faces", "-p", f"kb:={tmp_path}/none.yaml"],
        capture_output=True, text=True, timeout=60, env=run_env,
    )
    assert run.returncode == 2, run.stdout + run.stderr
    assert "none.yaml" in run.stdout + run.stderr
    assert "Traceback" not in run.stdout + run.stderr
