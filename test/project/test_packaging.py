"""Packaging: colcon installs every node where `ros2 run` looks (the core's purity: test_core_is_pure.py),
and the launch file builds the graph of :mod:`fsreg_ros.ros.graph_spec`."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
NODES = ["parser", "reference_resolution", "consultant", "wm_manager", "reg", "dialogue_player"]


def setup_entry_points() -> dict[str, str]:
    text = (REPO / "setup.py").read_text()
    return dict(re.findall(r'"([\w-]+)": "(fsreg_ros[\w.]*:\w+)"', text))


def test_every_node_is_a_console_script_with_a_main():
    entry = setup_entry_points()
    for node in NODES:
        assert node in entry, node
        module, func = entry[node].split(":")
        mod = __import__(module, fromlist=[func])
        assert callable(getattr(mod, func))


class _Recorded:
    """Stand-in for a launch / launch_ros class: records its arguments."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


class _Config(_Recorded):
    def perform(self, context) -> str:
        return context[self.args[0]]


def _launch_nodes(monkeypatch, given: dict) -> list:
    """Run launch/fsreg.launch.py with stand-ins for launch/launch_ros; return its Node objects."""
    import types

    modules = {
        "launch": types.SimpleNamespace(LaunchDescription=lambda entities: entities),
        "launch.actions": types.SimpleNamespace(DeclareLaunchArgument=_Recorded, OpaqueFunction=_Recorded),
        "launch.substitutions": types.SimpleNamespace(LaunchConfiguration=_Config),
        "launch_ros": types.SimpleNamespace(),
        "launch_ros.actions": types.SimpleNamespace(Node=_Recorded),
    }
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    namespace: dict = {}
    exec(compile((REPO / "launch" / "fsreg.launch.py").read_text(), "fsreg.launch.py", "exec"), namespace)
    entities = namespace["generate_launch_description"]()
    context = {a.args[0]: a.kwargs["default_value"] for a in entities if isinstance(a, _Recorded) and a.args}
    context.update(given)
    opaque = [e for e in entities if isinstance(e, _Recorded) and "function" in e.kwargs]
    assert len(opaque) == 1
    return opaque[0].kwargs["function"](context)


#: A KB with two domains, for the launch file's tests.
TWO_DOMAINS = """\
domains:
  faces:
    preference: [male, female, glasses]
    entities: {face1: [male, glasses], face2: [female]}
  objects:
    preference: [large, red]
    entities: {cup: [red], ball: [large, red]}
"""


def test_launch_file_builds_the_graph_spec(monkeypatch, tmp_path):
    from fsreg_ros.core.forgetting import settings
    from fsreg_ros.core.forgetting.policies import ForgettingPolicy
    from fsreg_ros.ros.graph_spec import node_specs, policy_settings

    kb = tmp_path / "kb.yaml"
    kb.write_text(TWO_DOMAINS)
    given = {"kb": str(kb), "domains": "faces, objects", "policy": "displacement", "capacity": "3",
             "namespace": "robot1", "use_sim_time": "true"}
    nodes = _launch_nodes(monkeypatch, given)
    defaults = {row.name: row.default for row in settings.TABLE}  # the launch arguments' defaults
    policy = policy_settings(ForgettingPolicy.from_settings({**defaults, "policy": "displacement", "capacity": 3}))
    expected = node_specs(str(kb), ["faces", "objects"], {"faces": policy, "objects": policy},
                          use_sim_time=True, algorithm="auto", wm_order="lru-first")
    got = [(n.kwargs["executable"], n.kwargs["name"], n.kwargs["parameters"]) for n in nodes]
    assert got == [(s.executable, s.name, [s.parameters]) for s in expected]
    assert {n.kwargs["package"] for n in nodes} == {"fsreg_ros"}
    assert {n.kwargs["executable"] for n in nodes} <= set(setup_entry_points())
    assert {n.kwargs["namespace"] for n in nodes} == {"/robot1"}
    assert all(n.kwargs["remappings"] == [("/clock", "/robot1/clock")] for n in nodes)
    assert got[2][2][0]["policy"] == "displacement" and got[2][2][0]["capacity"] == 3  # every domain's: node-wide
    assert not [k for k in got[2][2][0] if k.startswith(("faces.", "objects."))]


def test_launch_file_takes_a_state_dir_a_fresh_start_and_a_lexicon_as_fsreg_up_does(monkeypatch, tmp_path):
    from fsreg_ros.core.forgetting import settings
    from fsreg_ros.core.forgetting.policies import ForgettingPolicy
    from fsreg_ros.ros.graph_spec import node_specs, policy_settings

    monkeypatch.chdir(tmp_path)
    (tmp_path / "kb.yaml").write_text(TWO_DOMAINS)
    (tmp_path / "words.yaml").write_text((REPO / "config" / "lexicon.yaml").read_text())
    kb = str(tmp_path / "kb.yaml")
    given = {"kb": "kb.yaml", "policy": "decay", "state_dir": "state", "lexicon": "words.yaml", "fresh": "true"}
    nodes = {n.kwargs["name"]: n.kwargs["parameters"][0] for n in _launch_nodes(monkeypatch, given)}
    policy = ForgettingPolicy.from_settings({**{row.name: row.default for row in settings.TABLE}, "policy": "decay"})
    expected = {s.name: s.parameters for s in node_specs(
        kb, ["faces"], {"faces": policy_settings(policy)}, use_sim_time=False,
        algorithm="auto", lexicon=str(tmp_path / "words.yaml"), state_dir=str(tmp_path / "state"))}
    expected["consultant_faces"]["reset_state"] = True  # fresh: the database moved aside, as fsreg-up --fresh
    assert nodes == expected
    assert nodes["consultant_faces"]["state_dir"] == str(tmp_path / "state")
    assert nodes["parser"]["lexicon"] == nodes["reg"]["lexicon"] == str(tmp_path / "words.yaml")
    again = {n.kwargs["name"]: n.kwargs["parameters"][0] for n in _launch_nodes(monkeypatch, {"kb": kb})}
    assert "reset_state" not in again["consultant_faces"] and "state_dir" not in again["consultant_faces"]
    with pytest.raises(ValueError, match=r"^launch argument fresh:='yes': expected true or false$"):
        _launch_nodes(monkeypatch, {"kb": kb, "fresh": "yes"})


def test_launch_file_refuses_a_bad_argument_in_one_line_before_any_node_starts(monkeypatch, tmp_path):
    """``ros2 launch`` with a missing or bad KB, an unknown domain, a missing lexicon or a bad REG setting
    started every node and left the others running when one died (checked with the real CLI: h7's
    scripts/check_ros2_cli.sh); each is now one error naming the argument, and no node."""
    kb = tmp_path / "kb.yaml"
    kb.write_text(TWO_DOMAINS)
    missing = tmp_path / "none.yaml"
    refusals = {
        (): "launch argument kb:='': required: the scenario/KB YAML file with every domain's LTM",
        (("kb", str(missing)),): f"launch argument kb:={str(missing)!r}: {missing}: file not found",
        (("domains", "faces,places"),):
            f"launch argument domains:='faces,places': {kb} has no domain 'places' (its domains: faces, objects)",
        (("domains", "faces,faces"),): "launch argument domains:='faces,faces': 'faces' given twice",
        (("domains", " , "),): "launch argument domains:=' , ': expected at least one domain",
        (("lexicon", str(missing)),): f"launch argument lexicon:={str(missing)!r}: {missing}: file not found",
        (("algorithm", "foo"),):
            "launch argument algorithm:='foo': expected auto, sd-pia, dist-pia, full-brevity or greedy",
        (("wm_order", "lifo"),):
            "launch argument wm_order:='lifo': expected lru-first, mru-first, preference or strength",
        (("use_sim_time", "maybe"),): "launch argument use_sim_time:='maybe': expected true or false",
        (("decay_period", "abc"),): "launch argument decay_period:='abc': expected a number",
        (("policy", "decay"), ("decay_period", "0")): "decay_period must be > 0 seconds (at least 0.01), got 0.0",
        (("namespace", "bad-ns!"),):
            "namespace 'bad-ns!': each part must be ASCII letters, digits and '_', not starting with a digit",
    }
    for given, message in refusals.items():
        arguments = {"kb": str(kb), **dict(given)} if given else {}
        with pytest.raises(ValueError) as err:
            _launch_nodes(monkeypatch, arguments)
        assert str(err.value) == message, given


def test_launch_file_takes_a_preset_as_fsreg_up_does(monkeypatch, tmp_path):
    """``preset:=NAME`` fills in the memory settings and REG's WM order it names, as ``--preset``; an
    argument given beside it overrides the preset's; an unknown preset is one line naming the argument and
    the known presets, before any node starts (the launch file had no ``preset:=``)."""
    from fsreg_ros.core.forgetting import settings
    from fsreg_ros.core.forgetting.policies import ForgettingPolicy
    from fsreg_ros.ros.graph_spec import node_specs, policy_settings

    kb = tmp_path / "kb.yaml"
    kb.write_text(TWO_DOMAINS)
    defaults = {row.name: row.default for row in settings.TABLE}

    def graph(**given) -> dict:
        nodes = _launch_nodes(monkeypatch, {"kb": str(kb), **given})
        return {n.kwargs["name"]: n.kwargs["parameters"][0] for n in nodes}

    def expected(wm_order: str, **memory) -> dict:
        policy = policy_settings(ForgettingPolicy.from_settings({**defaults, **memory}))
        return {s.name: s.parameters for s in node_specs(str(kb), ["faces"], {"faces": policy}, use_sim_time=False,
                                                         algorithm="auto", wm_order=wm_order)}

    human = graph(preset="human-like")
    assert human == expected("strength", policy="episodes", episode_window=1)
    assert (human["wm_manager"]["policy"], human["wm_manager"]["episode_window"]) == ("episodes", 1)
    assert human["reg"]["wm_order"] == "strength"
    assert graph(preset="human-like", episode_window="2", wm_order="lru-first") == expected(
        "lru-first", policy="episodes", episode_window=2)  # given beside the preset: theirs win
    assert graph(preset="paper") == expected("lru-first", policy="decay+displacement", decay_period=10.0, capacity=2)
    assert graph() == expected("lru-first")  # no preset: the WM Manager's defaults and the paper's order
    for bad in ("nonsense", "Human-like"):
        with pytest.raises(ValueError) as err:
            graph(preset=bad)
        assert str(err.value) == f"launch argument preset:={bad!r}: unknown preset {bad!r} (known: paper, human-like)"


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
    ignore = shutil.ignore_patterns(".venv", ".git", "build", "install", "log", "__pycache__", "*.egg-info")
    shutil.copytree(REPO, src, ignore=ignore)
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


def test_the_docs_message_table_is_the_contracts():
    from fsreg_ros import contract

    text = (REPO / "docs" / "design.md").read_text()
    section = text[text.index("## Messages"):text.index("## Forgetting without races")]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    assert rows == contract.message_table()
    assert any("`wm/state`" in row and "`events`" in row for row in rows)


def test_the_contract_and_codec_import_no_ros_package():
    """A tool that only needs names, schemas or the JSON codec imports no ROS package."""
    code = ("import sys, fsreg_ros.contract, fsreg_ros.contract.codec, fsreg_ros.ros.graph_spec; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'rclpy', 'std_msgs', 'rosidl_parser', "
            "'diagnostic_msgs', 'rcl_interfaces', 'rosgraph_msgs'}))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=REPO)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"


def test_no_topic_or_service_literal_outside_the_contract():
    names = [t.name for t in __import__("fsreg_ros.contract", fromlist=["TOPICS"]).TOPICS]
    names += ["wm_manager/sync", "wm_manager/status"]
    for path in (REPO / "fsreg_ros").rglob("*.py"):
        if path == REPO / "fsreg_ros" / "contract" / "endpoints.py":
            continue
        text = path.read_text()
        for name in names:
            assert f'"{name}"' not in text and f'"/{name}"' not in text, f"{path}: {name}"


def test_documented_topic_pub_examples_fit_the_contract():
    """Every ``ros2 topic pub`` line of docs/deployment.md publishes a valid message with a fresh id."""
    import shlex

    import yaml

    from fsreg_ros import contract

    topics = {"/" + t.name: t for t in contract.TOPICS}
    ids = []
    lines = [line for line in (REPO / "docs" / "deployment.md").read_text().splitlines()
             if line.startswith("ros2 topic pub") and "std_msgs/String" in line]
    assert lines
    for line in lines:
        words = shlex.split(line)
        assert "--once" in words and "-w" in words  # waits for a subscriber, so the message is not lost
        topic = next(w for w in words if w.startswith("/"))
        data = yaml.safe_load(words[-1])["data"]
        import json

        message = json.loads(data)
        schema = topics[topic].schema
        models = getattr(schema, "__args__", None) or (schema,)
        contract.check(models[0], message)
        ids.append(message["id"])
    assert len(ids) == len(set(ids))


def _documented_topic_pubs() -> list[list[str]]:
    """Every ``ros2 topic pub`` command of docs/deployment.md, in code blocks and tables, as its words."""
    import shlex

    text = (REPO / "docs" / "deployment.md").read_text()
    commands = [line for line in text.splitlines() if line.startswith("ros2 topic pub")]
    commands += re.findall(r"`(ros2 topic pub [^`]*)`", text)
    return [shlex.split(command) for command in commands if " /" in command]  # not the prose's bare command


@pytest.mark.graph
def test_documented_topic_pubs_wait_for_every_reader_of_the_topic(table1_path):
    """``ros2 topic pub --once`` implies ``-w 1``: a documented command says ``-w N`` with N the topic's readers in
    the graph the docs start (one domain, sim time), counted on a live graph."""
    from fsreg_ros.testing import LiveGraph

    documented = _documented_topic_pubs()
    assert len(documented) >= 7
    with LiveGraph(table1_path) as graph:
        node = graph.nodes["reg"]
        for words in documented:
            topic = next(w for w in words[3:] if not w.startswith("-") and not w.isdigit())
            assert "--once" in words, words
            waits = int(words[words.index("-w") + 1]) if "-w" in words else 1
            readers = node.count_subscribers(graph.namespace + topic)
            assert readers >= 1 and waits == readers, (" ".join(words[:6]), waits, readers)


def test_every_script_the_docs_run_is_executable():
    """``scripts/x`` in the README or docs/ runs as written: the file exists, has a shebang and is executable
    (``rosenv.sh``, which says it is sourced, excepted)."""
    text = "\n".join(p.read_text() for p in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))])
    named = sorted(set(re.findall(r"(?<![\w/.])scripts/([\w.-]+\.(?:py|sh))", text)))
    assert "bench_store.py" in named and "table1.sh" in named
    for name in named:
        path = REPO / "scripts" / name
        assert path.is_file(), name
        if path.read_text().startswith("# Sourced"):
            continue
        assert path.read_text().startswith("#!"), name
        assert os.access(path, os.X_OK), f"scripts/{name} is not executable"


def test_package_xml_names_every_runtime_requirement():
    """``rosdep install`` on a colcon workspace installs what ``pip install`` would: each of setup.py's
    install_requires has its rosdep key in package.xml, or a comment there saying pip installs it."""
    import ast
    import xml.etree.ElementTree as ET

    keys = {"pyyaml": "python3-yaml", "pydantic": "python3-pydantic", "numpy": "python3-numpy",
            "rosbags": "python3-rosbags-pip"}
    setup = ast.parse((REPO / "setup.py").read_text())
    call = next(n for n in ast.walk(setup) if isinstance(n, ast.keyword) and n.arg == "install_requires")
    required = {re.split(r"[<>=\[]", ast.literal_eval(e))[0] for e in call.value.elts} - {"setuptools"}
    text = (REPO / "package.xml").read_text()
    depends = {e.text for e in ET.fromstring(text).iter("exec_depend")}
    for name in sorted(required):
        assert keys.get(name) in depends or f"{name} " in text and "no rosdep key" in text, name


def test_the_ros2_cli_check_refuses_in_one_line_without_ros2():
    """scripts/check_ros2_cli.sh (the docs' ``ros2`` promises, end to end) needs the real CLI: without
    ``ros2`` on PATH it says so in one line and exits 2, before anything else."""
    script = REPO / "scripts" / "check_ros2_cli.sh"
    run = subprocess.run(["/bin/bash", str(script)], capture_output=True, text=True, timeout=60,
                         env={"PATH": str(REPO / "launch"), "HOME": os.environ.get("HOME", "/")})
    assert (run.returncode, run.stdout) == (2, "")
    assert run.stderr == ("check_ros2_cli: error: no 'ros2' on PATH: source a ROS 2 Jazzy install and this "
                          "package's colcon workspace first (docs/testing.md)\n")
