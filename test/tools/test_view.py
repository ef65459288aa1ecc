"""The live view (issue 24.3): what its model makes of the graph's messages, and its server.

The model and the HTTP server are tested without ROS; ``test_view_in_a_browser``
drives a real graph with ``fsreg-ctl view`` serving it and reads the page in headless
Chromium (Debian's ``chromium``, installed by scripts/venv.sh where missing).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import subprocess
import sys
import time
import urllib.request

import pytest

from fsreg_ros.tools.view import ViewServer, check_port
from fsreg_ros.tools.view_model import ViewModel, decay_period


def state(domain, t, queues, version=1, incarnation=1):
    return {"domain": domain, "time": t, "queues": queues, "events": 0, "incarnation": incarnation,
            "wm_version": version}


def event(op, entity, prop, cause, t, turn=None, domain="faces"):
    return {"op": op, "domain": domain, "entity": entity, "property": prop, "cause": cause, "time": t, "turn": turn,
            "seq": 1, "incarnation": 1}


def test_queues_carry_origin_and_forget_time_under_decay():
    model = ViewModel()
    model.on_event(event("encode", "face1", "male", "human-speech", 1.0, turn=1))
    model.on_event(event("encode", "face1", "glasses", "rr-affirmed", 1.0, turn=1))
    model.on_state(state("faces", 1.0, {"face1": ["male", "glasses", "hat"]}))
    model.on_status({"time": 1.0, "domains": ["faces"], "memory": {"faces": {"policy": "decay", "decay_period": 10.0}},
                     "configured": {"faces": True}, "running": {}, "incarnation": {"faces": 1},
                     "next_tick": {"faces": 10.0}, "ready": True})
    snap = model.snapshot()
    entries = snap["domains"]["faces"]["entities"]["face1"]
    assert [e["property"] for e in entries] == ["male", "glasses", "hat"]
    assert [e["origin"] for e in entries] == [{"cause": "human-speech", "turn": 1},
                                              {"cause": "rr-affirmed", "turn": 1}, None]
    assert [e["forget_at"] for e in entries] == [10.0, 20.0, 30.0]  # the front pops first, one per tick
    assert snap["domains"]["faces"]["memory"] == {"policy": "decay", "decay_period": 10.0}
    model.on_event(event("forget", "face1", "male", "decay", 10.0))
    model.on_state(state("faces", 10.0, {"face1": ["glasses", "hat"]}, version=2))
    assert [e["property"] for e in model.snapshot()["domains"]["faces"]["entities"]["face1"]] == ["glasses", "hat"]


def test_queue_entries_carry_the_strength_the_consultant_reports():
    """Each WM entry shows how strongly the consultant holds it (its ``open`` reply, read by the view for the
    entities whose WM changed); the panel showed no strength before.  A strength read with another queue than
    the one wm/state shows is not shown (None) until it is read again."""
    model = ViewModel()
    model.on_event(event("encode", "face1", "glasses", "speaker", 3.0, turn=1))
    model.on_state(state("faces", 3.0, {"face1": ["male", "glasses"], "face2": ["female"]}))
    assert model.strength_wanted(1) == [("faces", "face1")]  # its event and its queue: once, in order
    assert model.strength_wanted(8) == [("faces", "face2")] and model.strength_wanted(8) == []
    held = [{"age": 1, "episodes": 1, "activation": None}, {"age": 0, "episodes": 2, "activation": 0.5}]
    model.on_held("faces", "face1", {"queue": ["male", "glasses"], "strength": held})
    entities = model.snapshot()["domains"]["faces"]["entities"]
    assert [(e["property"], e["strength"]) for e in entities["face1"]] == [("male", held[0]), ("glasses", held[1])]
    assert [(e["property"], e["strength"]) for e in entities["face2"]] == [("female", None)]  # not read yet
    model.on_state(state("faces", 4.0, {"face1": ["glasses", "male"], "face2": ["female"]}, version=2))
    assert [e["strength"] for e in model.snapshot()["domains"]["faces"]["entities"]["face1"]] == [None, None]
    assert model.strength_wanted(8) == [("faces", "face1"), ("faces", "face2")]  # face2: never read
    model.on_state(state("faces", 5.0, {"face2": ["female"]}, version=3))
    model.on_event(event("forget", "face1", "male", "decay", 5.0))
    assert model.strength_wanted(8) == [("faces", "face2")]  # face1's queue is empty now: nothing to read


def test_no_forget_time_without_decay():
    assert decay_period({"policy": "displacement", "capacity": 2}) is None
    assert decay_period({"policy": "decay+displacement", "decay_period": 5.0, "capacity": 2}) == 5.0
    assert decay_period({"policy": "bogus"}) is None
    model = ViewModel()
    model.on_state(state("faces", 1.0, {"face1": ["male"]}))
    model.on_status({"time": 1.0, "memory": {"faces": {"policy": "displacement", "capacity": 2}},
                     "next_tick": {"faces": None}})
    assert model.snapshot()["domains"]["faces"]["entities"]["face1"][0]["forget_at"] is None


def test_dialogue_lines_join_utterance_and_answer_and_mark_reg_sources():
    model = ViewModel()
    model.on_human({"id": "u1", "time": 1.0, "turn": 1, "text": "the man with glasses"})
    model.on_rr({"id": "u1", "time": 1.0, "status": "resolved", "resolved": "face1", "candidates": ["face1"],
                 "description": ["male", "glasses"]})
    model.on_expression({"id": "r1", "time": 2.0, "target": "face3", "domain": "faces", "algorithm": "sd-pia",
                         "description": ["glasses", "female"], "sources": ["wm", "ltm"],
                         "origins": [{"cause": "human-speech", "turn": 1}, None], "text": "the woman with glasses",
                         "strengths": [{"age": 1, "episodes": 2, "activation": None}, None]})
    model.on_expression({"id": "r2", "time": 3.0, "target": "nobody", "error": "unknown entity 'nobody'",
                         "kind": "unknown-entity"})
    lines = model.snapshot()["dialogue"]
    assert [(line["speaker"], line.get("resolved"), line.get("text")) for line in lines] == [
        ("human", "face1", "the man with glasses"), ("robot", None, "the woman with glasses"), ("robot", None, "")]
    assert lines[1]["properties"] == [
        {"property": "glasses", "source": "wm", "origin": {"cause": "human-speech", "turn": 1},
         "strength": {"age": 1, "episodes": 2, "activation": None}},
        {"property": "female", "source": "ltm", "origin": None, "strength": None}]
    assert lines[2]["error"] == "unknown entity 'nobody'"


def test_a_restarted_consultant_replaces_its_state():
    model = ViewModel()
    model.on_state(state("faces", 5.0, {"face1": ["male"]}, version=4, incarnation=1))
    model.on_state(state("faces", 6.0, {}, version=0, incarnation=2))
    snap = model.snapshot()["domains"]["faces"]
    assert (snap["incarnation"], snap["entities"]) == (2, {})


def test_the_status_is_wanted_only_when_it_may_have_changed():
    """The view asks the WM Manager's status (each domain's next decay tick) at the start, after a readiness
    message and once the clock reaches a next tick; not otherwise (it used to ask twice a second)."""
    model = ViewModel()
    assert model.status_wanted()  # nothing known yet
    model.on_status({"time": 1.0, "next_tick": {"faces": 10.0}, "memory": {}})
    assert not model.status_wanted()
    model.on_state(state("faces", 9.5, {"face1": ["male"]}))
    assert not model.status_wanted()  # before the tick
    model.on_state(state("faces", 10.0, {"face1": []}, version=2))
    assert model.status_wanted()  # the tick at 10 is reached: the next one is due
    model.on_status({"time": 10.0, "next_tick": {"faces": 20.0}, "memory": {}})
    assert not model.status_wanted()
    model.on_ready({"ready": True, "time": 10.5, "domains": {"faces": {"configured": True, "incarnation": 2}}})
    assert model.status_wanted()  # settings or an incarnation changed
    model.on_status({"time": 10.5, "next_tick": {"faces": None}, "memory": {}})  # decay switched off
    model.on_state(state("faces", 1e6, {}, version=3))
    assert not model.status_wanted()  # no tick to wait for


def test_server_binds_loopback_and_pushes_changes_within_200_ms():
    model = ViewModel()
    server = ViewServer(model, "127.0.0.1", 0)
    server.start()
    try:
        host, port = server.server_address[:2]
        assert host == "127.0.0.1" and port > 0
        page = urllib.request.urlopen(server.url, timeout=5).read().decode()
        assert "<title>fsreg: working memory, live</title>" in page and 'EventSource("events")' in page
        assert json.loads(urllib.request.urlopen(server.url + "snapshot", timeout=5).read())["domains"] == {}
        with urllib.request.urlopen(server.url + "events", timeout=5) as stream:
            first = json.loads(stream.readline().decode().removeprefix("data: "))
            assert first["version"] == 0
            stream.readline()  # the blank line ending the event
            sent = time.monotonic()
            model.on_state(state("faces", 2.0, {"face2": ["female"]}))
            pushed = json.loads(stream.readline().decode().removeprefix("data: "))
            assert time.monotonic() - sent < 0.2
            assert pushed["domains"]["faces"]["entities"]["face2"][0]["property"] == "female"
        with pytest.raises(urllib.error.HTTPError):
            urllib.request.urlopen(server.url + "nothing", timeout=5)
    finally:
        server.stop()


@pytest.mark.parametrize("port, ok", [(None, 8765), (0, 0), (65535, 65535), (-1, None), (70000, None)])
def test_port_option(port, ok):
    if ok is None:
        with pytest.raises(ValueError, match="--port must be between 0 and 65535"):
            check_port(port)
    else:
        assert check_port(port) == ok


def chromium() -> str:
    """Debian's headless Chromium (scripts/test.sh installs it where missing); the test fails without it."""
    import shutil

    path = shutil.which("chromium") or shutil.which("chromium-browser")
    assert path, "chromium is not installed: scripts/test.sh installs it (apt-get install chromium)"
    return path


def page_dom(url: str) -> str:
    """The page as Chromium renders it after its scripts ran (headless, no sandbox as root)."""
    import tempfile

    with tempfile.TemporaryDirectory() as profile:
        result = subprocess.run([chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                                 f"--user-data-dir={profile}", "--timeout=4000", "--dump-dom", url],
                                capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout


def caught_up(url: str, holds, what: str, wait: float = 60.0) -> int:
    """Poll the view's ``/snapshot`` until ``holds(snapshot)``; return that snapshot's version (fail at ``wait`` s).

    A deadline, not a timing: under load the view hears the graph late, never wrongly; a view that
    never hears it fails here, with what it holds, not later in the page.
    """
    deadline = time.monotonic() + wait
    while True:
        snap = json.loads(urllib.request.urlopen(url + "snapshot", timeout=5).read())
        if holds(snap):
            return snap["version"]
        assert time.monotonic() < deadline, f"the view never held {what}: {json.dumps(snap)[:3000]}"
        time.sleep(0.1)


def page_at(url: str, version: int, wait: float = 60.0) -> str:
    """The page as Chromium renders it once it has applied the view's snapshot ``version`` or a later one.

    The page marks what it drew (``<body data-version=N>``, set after each render); a dump taken
    before the page drew (Chromium cut its load short under load) or of an older snapshot is taken
    again.  Each load serves the view's state as of then, so the first dump of a loaded page holds.
    """
    deadline = time.monotonic() + wait
    while True:
        dom = page_dom(url)
        drawn = re.search(r'<body data-version="(\d+)"', dom)
        if drawn and int(drawn.group(1)) >= version:
            return dom
        assert time.monotonic() < deadline, f"the page never drew version {version}: {dom[-3000:]}"


def hears_the_graph(url: str, robot, wait: float = 60.0) -> None:
    """Return once the view has heard RR's ``rr/result`` and REG's ``reg/expression`` writers.

    The view starts serving once *it* has matched those writers; a writer that has not matched
    the view yet (discovery is not symmetric, and under load the gap is seconds) drops what it
    publishes meanwhile, and the view never shows it (seen: a resolution missing after 60 s).
    So each writer is asked something it answers without touching WM -- a property no consultant
    knows (RR's error) and an entity nobody has (REG's) -- again until the view shows both answers.
    """
    deadline = time.monotonic() + wait
    while True:
        said = robot.say(description=["no-such-property"])["id"]
        asked = robot.describe("nobody")["id"]
        for _ in range(20):  # two seconds for this pair's answers, then ask again
            lines = {line.get("id"): line for line in
                     json.loads(urllib.request.urlopen(url + "snapshot", timeout=5).read())["dialogue"]}
            if lines.get(said, {}).get("status") == "error" and lines.get(asked, {}).get("error"):
                return
            time.sleep(0.1)
        assert time.monotonic() < deadline, f"the view never heard RR's and REG's answers: {lines}"


@contextlib.contextmanager
def served_view(robot):
    """``fsreg-ctl view --port 0`` of ``robot``'s graph, as a user starts it, hearing the graph's answers
    (:func:`hears_the_graph`); yields the page's URL and the process."""
    view = subprocess.Popen([sys.executable, "-m", "fsreg_ros.tools.ctl", "view", "--namespace", robot.namespace,
                             "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ))
    try:
        line = view.stdout.readline()
        match = re.search(r"at (http://127\.0\.0\.1:\d+/)", line)
        assert match, line + view.stderr.read() if view.poll() is not None else line
        hears_the_graph(match.group(1), robot)
        yield match.group(1), view
    finally:
        view.terminate()
        view.wait(timeout=10)


@pytest.mark.slow
@pytest.mark.graph
def test_view_in_a_browser(tmp_path):
    """fsreg-ctl view serves a live graph; after a scripted dialogue Chromium shows its WM and REG's sources."""
    from html import unescape
    from pathlib import Path

    from fsreg_ros.testing import LiveGraph

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "guess_who_table1.yaml"
    with LiveGraph(scenario, processes=True, policy="decay", decay_period=10.0) as robot:
        with served_view(robot) as (url, view):
            robot.set_clock(1.0)
            assert robot.say("male, lab-coat, light-hair, glasses")["resolved"] == "face1"
            robot.set_clock(2.0)
            expression = robot.describe("face1")
            expected_wm = robot.wm("face1")

            def heard(snap) -> bool:  # the view holds what the graph did: both lines, face1's WM and strengths
                face1 = snap["domains"].get("faces", {}).get("entities", {}).get("face1") or []
                said, described = ([{}, {}] + snap["dialogue"])[-2:]  # after the probes' lines (hears_the_graph)
                return (said.get("resolved") == "face1" and described.get("properties") is not None
                        and [e["property"] for e in face1] == expected_wm and all(e["strength"] for e in face1)
                        and snap["domains"]["faces"]["next_tick"] is not None)

            dom = page_at(url, caught_up(url, heard, "the dialogue, face1's WM and its strengths"))
    row = re.search(r'<tr class="entity" data-entity="face1">(.*?)</tr>', dom)
    assert row, dom[:3000]
    entries = re.findall(r'<span class="entry" data-property="([^"]+)" data-origin="([^"]+)" data-forget-at="([^"]+)"',
                         row.group(1))
    assert [prop for prop, _, _ in entries] == expected_wm and expected_wm
    assert [origin for _, origin, _ in entries] == ["speaker"] * 4  # the human's own words, encoded at turn 1
    assert [float(f) for _, _, f in entries] == [10.0, 20.0, 30.0, 40.0]  # one pop per decay tick, front first
    strengths = re.findall(r'<span class="entry" data-property="[^"]+" data-origin="[^"]+" data-forget-at="[^"]+" '
                           r'data-strength="([^"]*)"', row.group(1))
    # Each entry's strength as the consultant holds it after REG's close: RR's check (episode 0), the human's
    # description (episode 1) and REG's words (episode 2, which its close began) used lab-coat, light-hair and
    # glasses; "male", which REG did not say, was last used in episode 1.
    assert strengths == ["age 1, 2 episodes"] + ["age 0, 3 episodes"] * 3
    props = re.findall(r'<span class="prop (wm|ltm)" data-property="([^"]+)" data-source="(wm|ltm)"', dom)
    assert [p for _, p, _ in props] == list(expression["description"])
    assert [s for s, _, _ in props] == list(expression["sources"])
    # Each word from WM with its strength when REG looked: RR's check and the human's episode used it (2 episodes),
    # one episode before the one REG's open began (age 1).
    held = re.findall(r'data-source="wm" data-strength="([^"]*)"', dom)
    assert held == ["age 1, 2 episodes"] * list(expression["sources"]).count("wm") and held
    assert unescape(expression["text"]) in unescape(dom)
    assert 'id="ready" class="yes"' in dom
    assert re.search(r'data-resolved="face1"', dom)


@pytest.mark.slow
@pytest.mark.graph
def test_the_view_follows_a_consultant_restart_and_a_clock_jump_in_a_browser(tmp_path):
    """The view keeps serving while the consultant is killed and restarted (its state restored, a new
    incarnation), then the clock jumps two decay ticks at once: Chromium shows incarnation 2, face1's WM
    after both pops with the times of the next ones, and what the human said after the restart."""
    from pathlib import Path

    from fsreg_ros.testing import LiveGraph

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "guess_who_table1.yaml"
    with LiveGraph(scenario, processes=True, policy="decay", decay_period=10.0, state_dir=tmp_path) as robot:
        with served_view(robot) as (url, view):
            robot.set_clock(1.0)
            assert robot.say("male, lab-coat, light-hair, glasses")["resolved"] == "face1"
            robot.restart("consultant_faces")
            robot.set_clock(25.0)  # a jump over the ticks at 10 and 20
            assert robot.say("female, glasses")["resolved"] == "face2"
            expected = {entity: robot.wm(entity) for entity in ("face1", "face2")}
            assert len(expected["face1"]) == 2

            def heard(snap) -> bool:  # the view holds the state the graph holds now
                faces = snap["domains"].get("faces", {})
                shown = {e: [p["property"] for p in faces.get("entities", {}).get(e, [])] for e in expected}
                return faces.get("incarnation") == 2 and shown == expected and snap["dialogue"] and any(
                    line.get("resolved") == "face2" for line in snap["dialogue"])

            version = caught_up(url, heard, f"incarnation 2 and {expected}")
            assert view.poll() is None  # it kept serving throughout
            dom = page_at(url, version)
    assert "faces (incarnation 2)" in dom
    rows = dict(re.findall(r'<tr class="entity" data-entity="(face\d)">(.*?)</tr>', dom))
    entries = {entity: re.findall(r'<span class="entry" data-property="([^"]+)" data-origin="[^"]+" '
                                  r'data-forget-at="([^"]+)"', rows[entity]) for entity in expected}
    assert [p for p, _ in entries["face1"]] == expected["face1"]
    assert [float(t) for _, t in entries["face1"]] == [30.0, 40.0]  # the next two ticks, front first
    assert [p for p, _ in entries["face2"]] == expected["face2"]
    assert re.search(r'data-resolved="face2"', dom)
