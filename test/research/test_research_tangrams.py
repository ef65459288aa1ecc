"""fsreg-eval tangrams: forgetting rules fitted to people's reuse (Hawkins, Frank & Goodman 2020).

Exact events, candidates, outcomes, WM membership and held-out log-likelihoods on small hand-made
games; the command line's validation; the corpus run through ``$FSREG_TANGRAMS_DIR``.
"""

import csv
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from fsreg_ros.core.forgetting.policies import RULES, ForgettingPolicy
from fsreg_ros.research import cli
from fsreg_ros.research import tangrams as T
from fsreg_ros.research.stats import ratio_bootstrap_ci

# (game, ms, trial, repetition, role, tangram, text)
GAME_ONE = [
    ("g1", 0, 1, 1, "director", "A", "the red ghost"),
    ("g1", 1_000, 1, 1, "matcher", "A", "ghost?"),
    ("g1", 5_000, 2, 1, "director", "B", "a tall man"),
    ("g1", 25_000, 3, 2, "matcher", "A", "ready"),
    ("g1", 30_000, 3, 2, "director", "A", "The ghost"),
    ("g1", 32_000, 3, 2, "director", "A", "red!"),
    ("g1", 40_000, 4, 2, "director", "B", "man"),
]
GAME_TWO = [
    ("g2", 100_000, 1, 1, "director", "A", "blue bird"),
    ("g2", 110_000, 2, 2, "director", "A", "bird"),
]


def write(path: Path, rows, header=T.COLUMNS) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    with (path / T.FILE).open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)
    return path


@pytest.fixture
def corpus(tmp_path) -> Path:
    # Rows out of time order across games: the reader sorts each game by time.
    return write(tmp_path / "corpus", GAME_TWO + GAME_ONE)


@pytest.fixture
def events(corpus) -> T.Events:
    return T.build_events(T.load_games(corpus))


def member(events: T.Events, setting) -> list:
    return T.memberships(events, [setting])[0].tolist()


# ------------------------------------------------------------------ tokenisation and events
def test_tokenisations_are_exact():
    text = "This one's like a Ghost, with arms RAISED up... kneeling? 2 ghosts"
    assert T.TOKENISATIONS["content"](text) == ("like", "ghost", "arms", "raised", "kneeling", "ghosts")
    assert T.TOKENISATIONS["stems"](text) == ("like", "ghost", "arm", "rais", "kneel", "ghost")
    assert T.TOKENISATIONS["all"](text) == ("this", "one's", "like", "a", "ghost", "with", "arms", "raised", "up",
                                            "kneeling", "ghosts")


def test_events_candidates_outcomes_and_recency_are_exact(events):
    assert events.games == ["g1", "g2"]  # sorted by id
    assert events.events == 3 and events.candidates == 7
    # g1, trial 3 (A, at 30 s, after the matcher's "ready"): every word said about A before, first-said order.
    assert events.words == ["red", "ghost", "ready", "tall", "man", "blue", "bird"]
    assert events.event.tolist() == [0, 0, 0, 1, 1, 2, 2]
    assert events.game.tolist() == [0, 0, 0, 0, 0, 1, 1]
    assert events.repetition.tolist() == [2, 2, 2, 2, 2, 2, 2]
    # The director says "ghost" and "red" in trial 3 (two messages), "man" in trial 4, "bird" in g2.
    assert events.used.tolist() == [True, True, False, False, True, False, True]
    assert events.seconds.tolist() == [30.0, 29.0, 5.0, 35.0, 35.0, 10.0, 10.0]
    # Content words said in the game since (red=1, ghost=2, ghost=3, tall=4, man=5, ready=6, ghost, red).
    assert events.words_since.tolist() == [5, 3, 0, 4, 3, 1, 0]
    assert events.references.tolist() == [2, 2, 0, 2, 2, 1, 1]
    assert events.descriptions.tolist() == [1, 1, 0, 1, 1, 1, 1]
    assert events.last.tolist() == [True, True, False, True, True, True, True]
    d = events.descriptives
    assert d["by_repetition"][1] == {"descriptions": 3, "words_per_description": 2.0, "share_said_earlier": 0.0}
    assert d["by_repetition"][2]["descriptions"] == 3 and d["by_repetition"][2]["words_per_description"] == 4 / 3
    assert d["by_repetition"][2]["share_said_earlier"] == 1.0  # ghost, red; man; bird
    # From a trial's first message (either player) to the first of the tangram's next trial.
    assert d["_gap_seconds"].tolist() == [25.0, 35.0, 10.0]
    assert d["_gap_references"].tolist() == [1, 1, 0]


def test_a_director_reference_without_an_earlier_word_is_no_event(tmp_path):
    rows = [("g", 0, 1, 1, "director", "A", "the"), ("g", 1_000, 2, 2, "director", "A", "ghost")]
    events = T.build_events(T.load_games(write(tmp_path, rows)))
    assert events.events == 0 and events.candidates == 0


# ------------------------------------------------------------------ WM membership through the core's buffer
@pytest.mark.parametrize("setting, expected", [
    # Ticks at 12, 24, 36: A loses red, then ghost; "ready" (25 s) is held at 30 s; B is empty by 40 s.
    ({"policy": "decay", "decay_period": 12.0}, [False, False, True, False, False, True, True]),
    # Ticks at 20 and 40 (a tick at a turn's time comes first): A keeps ghost, ready; B loses both.
    ({"policy": "decay", "decay_period": 20.0}, [False, True, True, False, False, True, True]),
    ({"policy": "decay", "decay_period": 50.0}, [True, True, True, True, True, True, True]),
    # Ticks at 10, 20, 30: the one at 30 s pops "ready" before the re-reference at 30 s (g2: "blue" at 10 s).
    ({"policy": "decay", "decay_period": 10.0}, [False, False, False, False, False, False, True]),
    ({"policy": "displacement", "capacity": 1}, [False, False, True, False, True, False, True]),
    ({"policy": "displacement", "capacity": 2}, [False, True, True, True, True, True, True]),
    # One pool of 3 over the domain: the least recently encoded front goes (after each encoding) ...
    ({"policy": "global-capacity", "global_capacity": 3}, [False, False, True, False, False, True, True]),
    # ... or before each message, when the WM Manager catches up (here the same choices).
    ({"policy": "shared-capacity", "shared_capacity": 3}, [False, False, True, False, False, True, True]),
    ({"policy": "decay+displacement", "decay_period": 20.0, "capacity": 1},
     [False, False, True, False, False, False, True]),
    ({"policy": "none"}, [False] * 7),
    (None, [True] * 7),  # an unmanaged buffer: no forgetting
])
def test_wm_membership_at_each_re_reference(events, setting, expected):
    assert member(events, setting) == expected


def test_replays_in_processes_equal_replays_in_this_one(events):
    settings = [{"policy": "decay", "decay_period": 12.0}, {"policy": "displacement", "capacity": 1}, None]
    assert T.memberships(events, settings, jobs=2).tolist() == T.memberships(events, settings, jobs=1).tolist()


# ------------------------------------------------------------------ scoring
def test_held_out_log_likelihood_of_a_membership_model_by_hand(events):
    # Game 1 held out: trained on g2 (in: 2 candidates, 1 used; out: none): p_in 0.5, p_out 0.5.
    # Game 2 held out: trained on g1 (in: 4, 3 used; out: 1, 0 used): p_in 3.5/5, p_out 0.5/2.
    fit = T.fit_membership("last-description", "baseline", events.last, events, np.array([0, 1]))
    assert fit.game_ll[0] == pytest.approx(5 * math.log(0.5))
    assert fit.game_ll[1] == pytest.approx(math.log(1 - 0.7) + math.log(0.7))
    assert fit.heldout_ll(7) == pytest.approx((5 * math.log(0.5) + math.log(0.3) + math.log(0.7)) / 7)
    assert fit.predicted.tolist() == pytest.approx([0.5] * 5 + [0.7, 0.7])
    # Fitted on both games: in 6 (4 used), out 1 (0 used).
    assert fit.setting == {"p_in": pytest.approx(4.5 / 7), "p_out": pytest.approx(0.25)}


def test_settings_are_chosen_on_the_training_games_only(events):
    used = events.used
    fits_g1 = np.concatenate([used[:5], [True, True]])  # tells g1's outcomes, nothing about g2's
    fits_g2 = np.concatenate([[True] * 5, used[5:]])  # and the other way round
    settings = ({"policy": "displacement", "capacity": 1}, {"policy": "displacement", "capacity": 2})
    fit = T.fit_membership("displacement", "wm", np.stack([fits_g1, fits_g2]), events, np.array([0, 1]), settings,
                           ("capacity",))
    assert fit.fold_settings == [settings[1], settings[0]]  # g1 held out: the setting that fits g2
    # g1 under capacity 2 (all 5 in, 3 used), with the link trained on g2: p_in 1.5/2.
    assert fit.game_ll[0] == pytest.approx(3 * math.log(0.75) + 2 * math.log(0.25))
    assert fit.edge == ["capacity"] and fit.grid == {"capacity": [1, 2]}


def test_logistic_fit_recovers_the_rates_of_a_binary_predictor():
    x = np.array([0.0] * 10 + [1.0] * 10)[:, None]
    y = np.array([1] * 2 + [0] * 8 + [1] * 6 + [0] * 4, dtype=float)
    w = T.logistic_fit(x, y, ridge=0.0)
    logit = lambda p: math.log(p / (1 - p))  # noqa: E731
    assert w[0] == pytest.approx(logit(0.2), abs=1e-8)
    assert w[1] == pytest.approx(logit(0.6) - logit(0.2), abs=1e-8)


def test_ratio_bootstrap_is_the_pooled_ratio_and_reproducible():
    est = ratio_bootstrap_ci([1.0, -3.0, 2.0, 0.5], [2.0, 4.0, 1.0, 3.0], resamples=500)
    assert est.mean == pytest.approx(0.5 / 10)
    assert est.low < est.mean < est.high and est.n == 4
    assert ratio_bootstrap_ci([1.0, -3.0, 2.0, 0.5], [2.0, 4.0, 1.0, 3.0], resamples=500) == est


def test_models_come_from_the_core_rule_list():
    from fsreg_ros.research.reuse_models import needs_clock

    models = T.wm_models()
    clocks = {"activation": ["activation@episodes", "activation@words"]}  # one model per clock, not a grid axis
    assert [m.name for m in models] == [n for r in RULES if r not in T.EXCLUDED for n in [r, *clocks.get(r, [])]] \
        + ["decay+displacement"]
    for model in models:
        assert model.parameters == tuple(T.fitted_parameters(model.name.split("+")))
        for setting in model.settings:
            ForgettingPolicy.from_settings(setting)  # every grid point is a valid policy of the core
    by_name = {m.name: m for m in models}
    for name, clock in (("activation", None), ("activation@episodes", "episodes"), ("activation@words", "words")):
        model = by_name[name]
        assert model.parameters == ("activation_decay", "activation_threshold")
        assert len(model.settings) == len(T.GRIDS["activation_decay"]) * len(T.GRIDS["activation_threshold"])
        assert {s.get("activation_clock") for s in model.settings} == {clock}  # seconds: today's settings
        assert needs_clock(name) == (clock is None)  # the entities' own clocks need no wall clock
    assert needs_clock("decay+displacement") and not needs_clock("episodes+displacement")
    assert [s["decay_period"] for s in by_name["decay"].settings] == list(T.GRIDS["decay_period"])
    assert by_name["displacement-random"].parameters == ("capacity",)  # the seed keeps its fallback
    both = by_name["decay+displacement"]
    assert len(both.settings) == T.COMBINED_VALUES ** 2
    assert {s["capacity"] for s in both.settings} >= {1, 100}  # thinned, ends kept
    grid = T.default_grid("global_capacity")
    assert grid[0] == 1 and grid[-1] == 10_000 and list(grid) == sorted(set(grid))


def test_evaluate_on_the_example_corpus_reports_every_model(tmp_path):
    T.write_example(tmp_path)
    result = T.evaluate(tmp_path, folds=2, grids={"decay_period": (5.0, 10.0, 20.0)}, resamples=200)
    out = result.to_json()
    assert (out["games"], out["events"], out["candidates"]) == (4, 24, 88)
    rules = {m.name for m in T.wm_models()}
    graded = {name + "/graded" for name in rules | {"no-forgetting"}}
    assert set(out["models"]) == rules | graded | set(T.BASELINES) | set(T.RECENCY)
    assert out["models"]["decay"]["grid"] == {"decay_period": [5.0, 10.0, 20.0]}
    for diff in out["differences"]:
        assert diff["ci"][0] <= diff["mean"] <= diff["ci"][1]


# ------------------------------------------------------------------ the command line
def run_cli(capsys, *argv):
    code = cli.eval_main(["tangrams", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_has_the_documented_schema(capsys, corpus):
    code, out, err = run_cli(capsys, corpus, "--folds", "2", "--grid", "capacity=1,2", "--grid", "decay_period=12,20",
                             "--resamples", "100", "--json")
    assert code == 0, err
    data = json.loads(out)
    assert (data["games"], data["events"], data["candidates"]) == (2, 3, 7)
    for name in ("decay", "displacement", "decay+displacement", "none", "last-description", "constant"):
        assert isinstance(data["models"][name]["heldout_ll"], float)
        assert isinstance(data["models"][name]["setting"], dict)
    assert data["models"]["displacement"]["setting"]["capacity"] in (1, 2)
    assert data["models"]["decay+displacement"]["grid"] == {"decay_period": [12.0, 20.0], "capacity": [1, 2]}
    assert data["differences"] and all(set(d) == {"a", "b", "mean", "ci"} for d in data["differences"])


def test_printed_report_and_plots(capsys, corpus, tmp_path):
    code, out, _ = run_cli(capsys, corpus, "--folds", "2", "--grid", "capacity=1,2", "--resamples", "100",
                           "--plots", tmp_path / "plots")
    assert code == 0
    assert out.startswith("tangram games (Hawkins, Frank & Goodman 2020): 2 games, 3 director re-references, "
                          "7 candidate words (4 reused)")
    assert "chosen value at a grid edge: " in out
    for name in ("tangrams-reuse", "tangrams-data"):
        for suffix in (".png", ".pdf"):
            assert (tmp_path / "plots" / (name + suffix)).stat().st_size > 1000


@pytest.mark.parametrize("argv, message", [
    (["/no/such/dir"], "/no/such/dir: no such file (give the directory holding tangramsSequential.csv"),
    (["CORPUS", "--folds", "1"], "--folds must be in [2, 1000], got 1"),
    (["CORPUS", "--folds", "3"], "folds must be in [2, 2] (the number of games), got 3"),
    (["CORPUS", "--tokens", "lemmas"], "--tokens: unknown tokenisation 'lemmas' (known: content, stems, all)"),
    (["CORPUS", "--grid", "alpha=1"], "--grid 'alpha=1': expected PARAM=V1,V2,... with PARAM one of"),
    (["CORPUS", "--grid", "capacity=0,2"], "--grid capacity: 0 is out of range [1, 10000]"),
    (["CORPUS", "--grid", "decay_period=1,x"], "--grid decay_period: 'x' is not a number"),
    (["CORPUS", "--grid", "decay_period=nan"], "--grid decay_period: nan is out of range"),
    (["CORPUS", "--jobs", "0"], "--jobs must be in [1, 64], got 0"),
    (["CORPUS", "--resamples", "10"], "--resamples must be in [100, 1000000], got 10"),
    (["CORPUS", "--plots", "FILE"], "not a directory"),
])
def test_bad_arguments_are_one_line_and_exit_2(capsys, corpus, argv, message):
    argv = [str(corpus) if a == "CORPUS" else str(corpus / T.FILE) if a == "FILE" else a for a in argv]
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("fsreg-eval: error: ") and message in err


@pytest.mark.parametrize("header, row, message", [
    (tuple(c for c in T.COLUMNS if c != "role"), None, "not the tangram corpus: no column role"),
    (T.COLUMNS, ("g", "soon", 1, 1, "director", "A", "x"), f"{T.FILE}:2: msgTime must be a whole number, got 'soon'"),
    (T.COLUMNS, ("g", 0, 1, 1, "judge", "A", "x"), f"{T.FILE}:2: role must be director or matcher, got 'judge'"),
    (T.COLUMNS, ("g", 0, 0, 1, "director", "A", "x"), f"{T.FILE}:2: trialNum and repetitionNum must be >= 1"),
    (T.COLUMNS, ("g", 0, 1, 1, "director", "", "x"), f"{T.FILE}:2: intendedName is empty"),
])
def test_a_malformed_corpus_is_named_by_file_and_line(capsys, tmp_path, header, row, message):
    write(tmp_path, [row] if row else [], header)
    code, out, err = run_cli(capsys, tmp_path)
    assert code == 2 and err.count("\n") == 1 and message in err


def test_a_corpus_with_nothing_to_fit_is_refused(capsys, tmp_path):
    write(tmp_path, [("g", 0, 1, 1, "director", "A", "ghost"), ("h", 0, 1, 1, "director", "A", "ghost")])
    code, _, err = run_cli(capsys, tmp_path)
    assert code == 2 and "no director re-reference with an earlier word" in err


# ------------------------------------------------------------------ the corpus (not shipped)
@pytest.fixture(scope="module")
def tangrams_dir() -> Path:
    """The tangram corpus (not shipped: no licence file), from ``$FSREG_TANGRAMS_DIR``."""
    if not os.environ.get("FSREG_TANGRAMS_DIR"):
        pytest.skip("tangram corpus not given: set FSREG_TANGRAMS_DIR to the directory holding tangramsSequential.csv")
    path = Path(os.environ["FSREG_TANGRAMS_DIR"])
    if not (path / T.FILE).is_file():
        pytest.fail(f"FSREG_TANGRAMS_DIR={path} has no {T.FILE}")
    return path


@pytest.mark.parametrize("tokens, candidates, reused", [("content", 55178, 13608), ("stems", 53376, 13899)])
def test_the_corpus_counts(capsys, tangrams_dir, tokens, candidates, reused):
    one = ["--grid", "decay_period=180", "--grid", "capacity=4", "--grid", "global_capacity=64",
           "--grid", "shared_capacity=64"]
    code, out, err = run_cli(capsys, tangrams_dir, "--tokens", tokens, *one, "--resamples", "100", "--json")
    assert code == 0, err
    data = json.loads(out)
    assert (data["games"], data["events"], data["candidates"], data["reused"]) == (83, 4975, candidates, reused)
    by_rep = data["descriptives"]["by_repetition"]
    assert [by_rep[str(r)]["descriptions"] for r in range(1, 7)] == [991, 995, 995, 996, 996, 996]
    models = data["models"]
    # The finding of docs/research.md section 8 at these settings: the last description beats
    # every WM rule, and every WM rule beats a constant rate.
    for name in ("decay", "displacement", "decay+displacement", "global-capacity"):
        assert models["last-description"]["heldout_ll"] > models[name]["heldout_ll"] > models["constant"]["heldout_ll"]


def test_the_corpus_read_back_from_its_rows_is_the_same_games(tangrams_dir, tmp_path):
    from fsreg_ros.research import reference_games as RG

    rows = RG.write_rows(tmp_path / "tangrams.csv", T.tangram_rows(tangrams_dir))
    assert RG.load_games(rows) == T.load_games(tangrams_dir)


@pytest.mark.slow  # replays the 83 games under one setting per rule
def test_on_the_corpus_episode_strength_beats_the_last_description(capsys, tangrams_dir):
    one = ["--grid", "decay_period=180", "--grid", "capacity=20", "--grid", "global_capacity=64",
           "--grid", "shared_capacity=64", "--grid", "episode_window=1", "--grid", "activation_decay=0.5",
           "--grid", "activation_threshold=-4"]
    code, out, err = run_cli(capsys, tangrams_dir, *one, "--resamples", "100", "--json")
    assert code == 0, err
    models = json.loads(out)["models"]
    # Rule episodes with k = 1 is the last description but for the matcher's words said before the director's.
    assert abs(models["episodes"]["heldout_ll"] - models["last-description"]["heldout_ll"]) < 0.005
    best_regression, last = models["recency-all"]["heldout_ll"], models["last-description"]["heldout_ll"]
    for name in ("displacement/graded", "episodes/graded", "no-forgetting/graded"):
        assert models[name]["heldout_ll"] > best_regression > last
