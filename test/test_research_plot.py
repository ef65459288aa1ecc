"""fsreg-plot: WM stays from a trace (pure) and the PNG written."""

import json

import pytest

from fsreg_ros.research import cli
from fsreg_ros.research.plot import Segment, divergence_curve, mean_band, turn_times, wm_segments


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


def test_bands_and_divergence_curve():
    assert mean_band([1, 1, 1]) == (1.0, 0.0)
    mean, band = mean_band([0, 1, 0, 1])
    assert mean == 0.5 and band == pytest.approx(1.96 * (1 / 3) ** 0.5 / 2)
    curves = {("decay", 5, 1, 0): [0, 1, 1], ("decay", 5, 1, 1): [0, 0, 1], ("none", None, None, 0): [0, 0, 0],
              ("decay", 5, 2, 0): [0, 1, 1]}  # a copy of seed 0's game: counted once
    assert [(j, m) for j, m, _ in divergence_curve(curves, "decay")] == [(1, 0.0), (2, 0.5), (3, 1.0)]
    assert divergence_curve(curves, "decay")[1][2] == pytest.approx(1.96 * (0.5 / 2) ** 0.5)
    assert [(j, m) for j, m, _ in divergence_curve(curves, "decay", window=2)] == [(2, 0.25), (3, 1.0)]


def test_plot_command_writes_png(tmp_path, capsys):
    trace = tmp_path / "trace.jsonl"
    trace.write_text("".join(json.dumps(e) + "\n" for e in TRACE))
    result = tmp_path / "result.json"
    result.write_text(json.dumps({"turns": [{"turn": 0, "time": 8.0, "speaker": "human"}]}))
    out = tmp_path / "wm.png"
    assert cli.plot_main([str(trace), "-o", str(out), "--result", str(result)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 2000
    assert "3 WM stays from 5 events" in capsys.readouterr().out


@pytest.mark.parametrize(
    "text, message",
    [("{not json\n", "trace.jsonl:1: not JSON"), ('{"op": "paint"}\n', "trace.jsonl:1: not a WM event"),
     ('{"op": "encode", "time": "late"}\n', "'time' must be a number")],
)
def test_bad_trace_is_named(tmp_path, capsys, text, message):
    trace = tmp_path / "trace.jsonl"
    trace.write_text(text)
    assert cli.plot_main([str(trace), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
