"""fsreg-plot: WM stays from a trace (pure) and the PNG written."""

import json

import pytest

from fsreg_ros.research import cli
from fsreg_ros.research.plot import (
    CAUSE_COLOURS,
    TURN_STYLE,
    Segment,
    divergence_curve,
    empty_reason,
    select_lanes,
    turn_times,
    wm_segments,
)
from fsreg_ros.research.stats import bootstrap_ci
from fsreg_ros.research.sweep import Setting


def ev(op, entity, prop, cause, time, turn=None):
    return {"op": op, "domain": "faces", "entity": entity, "property": prop, "cause": cause, "time": time,
            "turn": turn}


TRACE = [
    ev("encode", "face1", "glasses", "rr", 8.0, 0),
    ev("encode", "face1", "glasses", "speaker", 8.0, 0),  # refresh: same stay
    ev("encode", "face2", "glasses", "reg-distractor", 11.0, 1),
    ev("forget", "face1", "glasses", "decay", 20.0),
    ev("encode", "face1", "glasses", "speaker", 25.0, 3),
]


def test_segments_are_stays_with_their_causes():
    assert wm_segments(TRACE) == [
        Segment("faces", "face1", "glasses", 8.0, 20.0, "rr", "decay"),
        Segment("faces", "face2", "glasses", 11.0, None, "reg-distractor", None),
        Segment("faces", "face1", "glasses", 25.0, None, "speaker", None),
    ]


def test_turn_times_from_events_or_result():
    assert turn_times(TRACE) == [(8.0, 0, None), (11.0, 1, None), (25.0, 3, None)]
    result = {"turns": [{"turn": 0, "time": 8.0, "speaker": "human"}, {"turn": 1, "time": 11.0, "speaker": "robot"}]}
    assert turn_times(TRACE, result) == [(8.0, 0, "human"), (11.0, 1, "robot")]


def test_divergence_curve_by_blocks_with_bootstrap_bands():
    decay, other = Setting("decay", 5.0), Setting("decay", 10.0)
    curves = {(decay, 0): [0, 1, 1], (decay, 1): [0, 0, 1], (other, 0): [1, 1, 1], (Setting("none"), 0): [0, 0, 0]}
    curve = divergence_curve(curves, decay)
    assert [(j, m) for j, m, _, _ in curve] == [(1, 0.0), (2, 0.5), (3, 1.0)]
    assert curve[1][2:] == (bootstrap_ci([1.0, 0.0]).low, bootstrap_ci([1.0, 0.0]).high)
    assert [(j, m) for j, m, _, _ in divergence_curve(curves, decay, window=2)] == [(2, 0.25), (3, 1.0)]


def test_lane_selection_and_empty_reason():
    segments = wm_segments(TRACE)
    assert {s.entity for s in select_lanes(segments, entities=["face2"])} == {"face2"}
    # face1/glasses was in WM 8-20 and 25-30 (17 s), face2/glasses 11-30 (19 s): the top lane is face2's.
    assert [(s.entity, s.start) for s in select_lanes(segments, top=1, until=30.0)] == [("face2", 11.0)]
    assert len(select_lanes(segments, top=5, until=30.0)) == 3
    assert "policy none retains nothing" in empty_reason({"memory": {"faces": {"policy": "none"}}})
    assert "No property entered" in empty_reason({"memory": {"faces": {"policy": "decay"}}})


def test_colours_mean_one_thing_each():
    assert len(set(CAUSE_COLOURS.values())) == len(CAUSE_COLOURS)
    assert not {c for c, _ in TURN_STYLE.values()} & set(CAUSE_COLOURS.values())


def test_plot_command_writes_png(tmp_path, capsys):
    trace = tmp_path / "trace.jsonl"
    trace.write_text("".join(json.dumps(e) + "\n" for e in TRACE))
    result = tmp_path / "result.json"
    result.write_text(json.dumps({"turns": [{"turn": 0, "time": 8.0, "speaker": "human"}]}))
    out = tmp_path / "wm.png"
    assert cli.plot_main([str(trace), "-o", str(out), "--result", str(result)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 2000
    assert "3 WM stays from 5 events" in capsys.readouterr().out
    assert cli.plot_main([str(trace), "-o", str(out), "--entities", "face2", "--top", "1"]) == 0
    assert "1 WM stays from 5 events" in capsys.readouterr().out


@pytest.mark.parametrize(
    "text, message",
    [("{not json\n", "trace.jsonl: line 1, column 2: not JSON"),
     ('{"op": "paint"}\n', "trace.jsonl: line 1: not a WM event"),
     ('{"op": "encode", "time": "late"}\n', "'time' must be a number"),
     ('{"op": "encode", "time": 1}\n', "trace.jsonl: line 1: 'domain' must be a string (a WM event names its "
      "domain, entity, property, cause)"),
     ('{"op": "forget", "time": 1, "domain": "faces", "entity": ["face1"], "property": "male", "cause": "decay"}\n',
      "trace.jsonl: line 1: 'entity' must be a string")],
)
def test_bad_trace_is_named(tmp_path, capsys, text, message):
    trace = tmp_path / "trace.jsonl"
    trace.write_text(text)
    assert cli.plot_main([str(trace), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.parametrize("extra, message", [(["--entities", "face9"], "--entities: no event names face9"),
                                            (["--top", "0"], "--top must be at least 1")])
def test_bad_lane_selection_is_one_line(tmp_path, capsys, extra, message):
    trace = tmp_path / "trace.jsonl"
    trace.write_text("".join(json.dumps(e) + "\n" for e in TRACE))
    assert cli.plot_main([str(trace), "-o", str(tmp_path / "x.png"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_empty_none_timeline_says_why(tmp_path):
    from fsreg_ros.research.plot import wm_timeline

    out = tmp_path / "none.png"
    result = {"memory": {"faces": {"policy": "none"}}, "turns": [{"turn": 0, "time": 1.0, "speaker": "human"}]}
    assert wm_timeline([], out, result) == [] and out.stat().st_size > 2000
