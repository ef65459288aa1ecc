"""The research figures a paper can print: labelled axes, every setting drawn, legends off the data, PNG and PDF."""

import pytest

from fsreg_ros.research import plot
from fsreg_ros.research.listener import ListenerOptions
from fsreg_ros.research.sweep import SweepConfig, metrics, summarise_runs, sweep


@pytest.fixture(scope="module")
def swept():
    config = SweepConfig(("decay", "decay+displacement", "none"), (5.0, 10.0, 80.0), (1, 2), (0, 1), 8,
                         changes=20.0, retraction=(True, False), listener=ListenerOptions(missing=0.1))
    rows, curves, _, _ = sweep(config, progress=False)
    return summarise_runs(rows, metrics(config)), curves


@pytest.fixture
def drawn(monkeypatch):
    """Keep every figure a plot function saves (instead of only writing it)."""
    figures = {}
    real = plot._save

    def keep(fig, out, name):
        figures[name] = fig
        fig.canvas.draw()
        return real(fig, out, name)

    monkeypatch.setattr(plot, "_save", keep)
    return figures


def _metric(title: str) -> str:
    return next(m for m, t, _ in plot.LISTENER_PANELS if t == title)


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


@pytest.mark.slow  # plays a small sweep (bootstrap over every metric)
def test_policy_plots_label_every_axis_say_the_log_scale_and_keep_the_legend_off_the_panels(swept, drawn, tmp_path):
    summary, _ = swept
    none = next(e for e in summary if e["setting"].policy == "none")
    entries = [e for e in summary if e["setting"].policy == "decay+displacement"]
    files = plot.policy_plot("decay+displacement", entries, none, tmp_path, dynamic=True)
    assert files == ["policy-decay+displacement.png", "policy-decay+displacement.pdf"]
    assert all((tmp_path / f).stat().st_size > 1000 for f in files)
    fig = drawn["policy-decay+displacement.png"]
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == len(plot.PANELS) + 1
    assert [ax.get_ylabel() for ax in axes] == [label for _, _, label in plot.PANELS + plot.DYNAMIC_PANELS]
    for ax in axes:
        assert ax.get_xscale() == "log" and ax.get_xlabel() == "decay period δ (s), log scale"
    (legend,) = fig.legends
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == ["α = 1", "α = 1 (WM not told)", "α = 2", "α = 2 (WM not told)"]
    box = legend.get_window_extent()
    assert not any(_overlaps(box, ax.get_window_extent()) for ax in axes)
    assert fig.get_size_inches()[0] == plot.PAGE_WIDTH


@pytest.mark.slow  # plays a small sweep (bootstrap over every metric)
def test_units_on_each_panel(swept, drawn, tmp_path):
    summary, _ = swept
    entries = [e for e in summary if e["setting"].policy == "decay"]
    plot.policy_plot("decay", entries, None, tmp_path, dynamic=False)
    fig = drawn["policy-decay.png"]
    ylabels = [ax.get_ylabel() for ax in fig.axes if ax.get_visible()]
    assert ylabels == [label for _, _, label in plot.PANELS]
    assert [ax.get_xlabel() for ax in fig.axes if ax.get_visible()] == ["decay period δ (s), log scale"] * 4


@pytest.mark.slow  # plays a small sweep (bootstrap over every metric)
def test_divergence_plot_draws_every_setting_with_legends_outside_and_bands_under_the_lines(swept, drawn, tmp_path):
    _, curves = swept
    files = plot.divergence_plot(curves, tmp_path)
    assert files == ["divergence_by_turn.png", "divergence_by_turn.pdf"]
    fig = drawn["divergence_by_turn.png"]
    axes = [ax for ax in fig.axes if ax.get_visible()]
    # decay, and decay+displacement once per capacity: 3 panels.
    assert [ax.get_title() for ax in axes] == ["decay", "decay+displacement: α = 1", "decay+displacement: α = 2"]
    settings = {s for s, _ in curves if s.policy != "none"}
    drawn_lines = sum(len(ax.get_lines()) for ax in axes)
    assert drawn_lines == len(settings) == 18  # 3 periods x (1 + 2 capacities) x told or not
    for ax in axes:
        assert ax.get_ylabel() == "share of descriptions\ndiffering from none" and ax.get_xlabel()
        legend = ax.get_legend()
        assert legend.get_window_extent().x0 >= ax.get_window_extent().x1  # outside, to the right
        assert [t.get_text() for t in legend.get_texts()] == ["δ = 5", "δ = 10", "δ = 80"]  # dashed: not told
        bands = ax.collections
        assert bands and max(b.get_zorder() for b in bands) < min(line.get_zorder() for line in ax.get_lines())


@pytest.mark.slow  # plays a small sweep (bootstrap over every metric)
def test_listener_plot_shows_success_turns_length_and_entrainment(swept, drawn, tmp_path):
    summary, _ = swept
    assert plot.listener_plot(summary, tmp_path) == ["listener.png", "listener.pdf"]
    fig = drawn["listener.png"]
    assert [ax.get_title() for ax in fig.axes] == ["success", "turns to success", "length said", "entrainment"]
    assert [t.get_text() for t in fig.axes[0].get_yticklabels()] == [e["setting"].label() for e in summary]
    for ax in fig.axes:
        assert ax.get_xlabel() == dict((m, x) for m, _, x in plot.LISTENER_PANELS)[_metric(ax.get_title())]


def test_timeline_names_the_humans_words_human_speech_as_the_alignment_table_does(tmp_path):
    events = [
        {"op": "encode", "domain": "faces", "entity": "face1", "property": "glasses", "cause": "rr", "time": 1.0,
         "turn": 0},
        {"op": "encode", "domain": "faces", "entity": "face2", "property": "glasses", "cause": "rr", "time": 1.0,
         "turn": 0},
        {"op": "encode", "domain": "faces", "entity": "face1", "property": "glasses", "cause": "speaker",
         "time": 1.0, "turn": 0},
        {"op": "encode", "domain": "faces", "entity": "face2", "property": "male", "cause": "speaker", "time": 2.0,
         "turn": 1},
    ]
    result = {"turns": [{"turn": 0, "time": 1.0, "speaker": "human", "target": "face1", "description": ["glasses"]},
                        {"turn": 1, "time": 2.0, "speaker": "robot", "target": "face2", "description": ["male"]}]}
    for given in (result, None):  # from the result, or from the events alone
        names = [(s.entity, s.property, s.encoded_by) for s in plot.named_segments(events, given)]
        assert names == [("face1", "glasses", "human-speech"), ("face2", "glasses", "rr"),
                         ("face2", "male", "robot-speech")]
    out = tmp_path / "wm.png"
    segments = plot.wm_timeline(events, out, result)
    assert [s.encoded_by for s in segments] == ["human-speech", "rr", "robot-speech"]
    assert "speaker" not in plot.CAUSE_COLOURS and {"human-speech", "robot-speech"} <= set(plot.CAUSE_COLOURS)
    assert out.stat().st_size > 1000 and (tmp_path / "wm.pdf").stat().st_size > 1000
