"""fsreg-eval reference-games: the general format (CSV and JSON Lines), its events, WMs, links and refusals.

Small hand-made games with a rotating describer, a player who joins late and a game without
times: exact rows, events, candidates, cells (group and per-player WM), the graded link fitted on
the training folds only, the JSON's families; every bad file refused in one line naming file, row
and column; the tangram adapter giving today's numbers and the same result as its rows read back.
"""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from fsreg_ros.research import cli
from fsreg_ros.research import reference_games as RG
from fsreg_ros.research import tangrams as T
from fsreg_ros.research.reuse_events import build_events
from fsreg_ros.research.reuse_fit import fit_cells
from fsreg_ros.core.memory import WMBuffer
from fsreg_ros.research.reuse_replay import CELL_NAMES, CELLS, cells_of, strength_cells

HEADER = ("game", "trial", "referent", "player", "role", "time", "text")
# r1: the describer rotates (ann, bob, cat, ann) and cat joins at trial 3; r2 has no times and eve joins late.
R1 = [
    ("r1", 1, "A", "ann", "describer", 0, "the red ghost"),
    ("r1", 1, "A", "bob", "matcher", 2, "ghost?"),
    ("r1", 2, "B", "bob", "describer", 5, "a tall man"),
    ("r1", 2, "B", "ann", "matcher", 6, "man ok"),
    ("r1", 3, "A", "cat", "describer", 10, "Ghost, red"),
    ("r1", 4, "B", "ann", "describer", 20, "man"),
]
R2 = [
    ("r2", 1, "A", "dan", "describer", "", "blue bird"),
    ("r2", 2, "A", "eve", "describer", "", "bird"),
]


def write_csv(path: Path, rows, header=HEADER) -> Path:
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def write_jsonl(path: Path, rows, header=HEADER) -> Path:
    with path.open("w", encoding="utf-8") as handle:
        for row in rows:
            handle.write(json.dumps(dict(zip(header, row))) + "\n")
    return path


@pytest.fixture(params=["csv", "jsonl"])
def corpus(request, tmp_path) -> Path:
    # Games interleaved in the file: each game keeps its own order; games come back sorted by id.
    rows = R2[:1] + R1 + R2[1:]
    if request.param == "csv":
        return write_csv(tmp_path / "games.csv", rows)
    return write_jsonl(tmp_path / "games.jsonl", [r[:5] + ((None if r[5] == "" else r[5]),) + r[6:] for r in rows])


@pytest.fixture
def events(corpus):
    return build_events(RG.load_games(corpus))


def test_rows_become_games_with_counted_repetitions(corpus):
    games = RG.load_games(corpus)
    assert [g.gameid for g in games] == ["r1", "r2"] and [g.timed for g in games] == [True, False]
    r1, r2 = games
    assert [(m.trial, m.repetition, m.role, m.player, m.referent, m.words) for m in r1.messages] == [
        (1, 1, "describer", "ann", "A", ("red", "ghost")), (1, 1, "matcher", "bob", "A", ("ghost",)),
        (2, 1, "describer", "bob", "B", ("tall", "man")), (2, 1, "matcher", "ann", "B", ("man",)),
        (3, 2, "describer", "cat", "A", ("ghost", "red")), (4, 2, "describer", "ann", "B", ("man",))]
    assert [m.time for m in r1.messages] == [0.0, 2.0, 5.0, 6.0, 10.0, 20.0]
    assert [m.time for m in r2.messages] == [0.0, 1.0]  # no times: the message's index
    assert [m.repetition for m in r2.messages] == [1, 2]


def test_events_candidates_and_outcomes_are_exact(events):
    assert events.events == 3 and events.candidates == 6
    assert events.words == ["red", "ghost", "tall", "man", "blue", "bird"]
    assert events.event.tolist() == [0, 0, 1, 1, 2, 2]
    assert events.game.tolist() == [0, 0, 0, 0, 1, 1]
    assert events.used.tolist() == [True, True, False, True, False, True]
    assert events.last.tolist() == [True] * 6
    # Said about the referent before by this trial's describer: only ann's "man" (as B's matcher in trial 2).
    assert events.by_describer.tolist() == [False, False, False, True, False, False]
    assert events.seconds[:4].tolist() == [10.0, 8.0, 15.0, 14.0] and np.isnan(events.seconds[4:]).all()
    assert events.timed.tolist() == [True, False]
    assert events.late.tolist() == [True, True] and events.describers_from_start is False  # cat, eve joined late


@pytest.mark.parametrize("setting, group, player", [
    # No forgetting: the group's WM holds every earlier word; cat and eve heard nothing before they joined.
    (None, [1, 1, 1, 1, 1, 1], [0, 0, 1, 1, 0, 0]),
    # Capacity 1: the last word said about the referent stays (ghost, man, bird); ann heard "tall man" then said "man".
    ({"policy": "displacement", "capacity": 1}, [0, 1, 0, 1, 0, 1], [0, 0, 0, 1, 0, 0]),
    # Episode window 1: every candidate was said in its referent's previous trial, so it stays.
    ({"policy": "episodes", "episode_window": 1}, [1, 1, 1, 1, 1, 1], [0, 0, 1, 1, 0, 0]),
])
def test_cells_in_the_group_wm_and_in_each_players_wm(events, setting, group, player):
    # Cell 0: not in WM; 1: in WM, used in the referent's previous episode (age 1) and in that one only.
    assert cells_of(events, [setting]).tolist() == [group]
    assert cells_of(events, [setting], players=True).tolist() == [player]


def test_a_describer_present_from_the_start_holds_what_the_group_holds(tmp_path):
    # r3: the matcher joins late, but the describer (ann) wrote from the first trial: her WM is the group's,
    # which is why only games with a late describer are replayed per player.
    rows = [("r3", 1, "A", "ann", "describer", 0, "red ghost"), ("r3", 2, "B", "ann", "describer", 1, "tall man"),
            ("r3", 2, "B", "bob", "matcher", 2, "man?"), ("r3", 3, "A", "ann", "describer", 3, "ghost"),
            ("r3", 4, "B", "ann", "describer", 4, "man")]
    events = build_events(RG.load_games(write_csv(tmp_path / "r3.csv", rows)))
    assert events.late.tolist() == [False] and events.candidates == 4
    settings = [None, {"policy": "displacement", "capacity": 1}, {"policy": "episodes", "episode_window": 1}]
    assert cells_of(events, settings, players=True).tolist() == cells_of(events, settings).tolist()


def test_strength_cells_bin_each_entrys_episode_age_and_episodes():
    buffer = WMBuffer("games")
    buffer.begin_episode("A")
    buffer.encode("A", ["x", "y"], "speaker", 0.0)
    buffer.begin_episode("A")
    buffer.encode("A", ["y"], "speaker", 1.0)
    for _ in range(2):
        buffer.begin_episode("A")  # episodes 3 and 4: nothing said
    assert [tuple(s[:2]) for s in buffer.strength("A")] == [(3, 1), (2, 2)]
    # Cell 1 + 2 x (age bin: <=1, 2, 3, 4-5, >5) + (used in 2+ episodes).
    assert strength_cells(buffer, "A", ["x", "y", "z"]) == [1 + 2 * 2, 1 + 2 * 1 + 1, 0]
    for _ in range(3):
        buffer.begin_episode("A")
    assert strength_cells(buffer, "A", ["x", "y"]) == [1 + 2 * 4, 1 + 2 * 3 + 1]  # ages 6 (>5) and 5 (4-5)
    assert strength_cells(buffer, "B", ["x"]) is None
    assert CELLS == len(CELL_NAMES) == 11


def test_the_graded_link_is_fitted_on_the_training_games_only(events):
    cells = np.array([[2, 1, 2, 1, 1, 0]], dtype=np.uint8)
    fit = fit_cells("toy/graded", "wm", cells, 3, events, np.array([0, 1]))
    # r1 held out: trained on r2 (cell 1: 0 of 1 used -> 0.5/2; cell 0: 1 of 1 -> 1.5/2; cell 2: unseen -> 0.5).
    assert fit.game_ll[0] == pytest.approx(2 * math.log(0.5) + 2 * math.log(0.25))
    # r2 held out: trained on r1 (cell 2: 1 of 2 -> 0.5; cell 1: 2 of 2 -> 2.5/3; cell 0: unseen -> 0.5).
    assert fit.game_ll[1] == pytest.approx(math.log(1 - 2.5 / 3) + math.log(0.5))
    assert fit.predicted.tolist() == pytest.approx([0.5, 0.25, 0.5, 0.25, 2.5 / 3, 0.5])
    assert fit.setting == {"p_cell": pytest.approx([1.5 / 2, 2.5 / 4, 1.5 / 3])}


def run_cli(capsys, *argv):
    code = cli.eval_main(["reference-games", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_families_graded_players_and_the_clockless_game(capsys, corpus):
    code, out, err = run_cli(capsys, corpus, "--folds", "2", "--grid", "capacity=1,2", "--grid", "decay_period=4,8",
                             "--resamples", "100", "--json")
    assert code == 0, err
    data = json.loads(out)
    models = data["models"]
    assert (models["displacement"]["family"], models["displacement"]["graded"], models["displacement"]["wm"]) == \
        ("rule", False, "group")
    assert (models["displacement/graded"]["family"], models["displacement/graded"]["graded"]) == ("rule", True)
    assert models["displacement/player"]["wm"] == "player"
    assert models["displacement/player"]["in_wm"] == pytest.approx(1 / 6)  # ann's "man" under capacity 1 or 2
    assert {models[n]["family"] for n in ("last-description", "said-by-describer", "constant", "none")} == {"baseline"}
    assert models["recency-all"]["family"] == "regression" and models["recency-all"]["graded"] is False
    # The game without times is left out of the rules and regressions on seconds, and only of them.
    assert models["decay"]["games_scored"] == models["activation/graded"]["games_scored"] == 1
    assert models["recency-seconds"]["games_scored"] == 1
    assert "games_scored" not in models["displacement"] and "games_scored" not in models["recency-words"]
    assert any("1 game without times" in note for note in data["notes"])
    pairs = {(d["a"], d["b"]) for d in data["differences"]}
    assert (data["best_rule"], "last-description") in pairs and (data["best_rule"], data["best_regression"]) in pairs
    assert models[data["best_rule"]]["family"] == "rule"


def test_printed_report(capsys, corpus):
    code, out, _ = run_cli(capsys, corpus, "--folds", "2", "--grid", "capacity=1,2", "--resamples", "100")
    assert code == 0
    assert out.startswith(f"reference games ({corpus.name}): 2 games, 3 describer re-references, 6 candidate words "
                          "(4 reused)")
    assert "note: 1 game without times: the rules and regressions on seconds" in out
    # The intervals' line names the resamples used, not the default's 10,000.
    assert "intervals: paired by game, 95 % percentile bootstrap CI over games (100 resamples, seed 0) of the ratio " \
           "(summed difference / candidates)." in out.splitlines()
    assert "10,000" not in out


def test_json_intervals_name_the_resamples_used(capsys, corpus):
    code, out, _ = run_cli(capsys, corpus, "--folds", "2", "--grid", "capacity=1,2", "--resamples", "250", "--json")
    assert code == 0
    assert json.loads(out)["intervals"] == \
        "95 % percentile bootstrap CI over games of the ratio (summed difference / candidates) (250 resamples, seed 0)"


# ------------------------------------------------------------------ bad files: one line, file, row, column
def bad(name, rows, header=HEADER):
    return name, rows, header


@pytest.mark.parametrize("name, rows, header, message", [
    ("f.csv", [], ("game", "trial", "referent", "player", "time", "text"),
     "f.csv: row 1, column role: missing from the header"),
    ("f.csv", [("g", "x", "A", "p", "describer", 0, "hi")], HEADER,
     "f.csv: row 2, column trial: must be a whole number >= 1, got 'x'"),
    ("f.csv", [("g", 0, "A", "p", "describer", 0, "hi")], HEADER,
     "f.csv: row 2, column trial: must be a whole number >= 1, got '0'"),
    ("f.csv", [("g", 1, "A", "p", "judge", 0, "hi")], HEADER,
     "f.csv: row 2, column role: must be describer or matcher, got 'judge'"),
    ("f.csv", [("g", 1, "", "p", "describer", 0, "hi")], HEADER, "f.csv: row 2, column referent: empty"),
    ("f.csv", [("g", 1, "A", "p", "describer", "soon", "hi")], HEADER,
     "f.csv: row 2, column time: must be a number of seconds (or empty), got 'soon'"),
    ("f.csv", [("g", 1, "A", "p", "describer", "nan", "hi")], HEADER,
     "f.csv: row 2, column time: must be a number of seconds (or empty), got 'nan'"),
    ("f.csv", [("g", 1, "A", "p", "describer", 0, "hi"), ("g", 1, "A", "q", "matcher", "", "ok")], HEADER,
     "f.csv: row 3, column time: empty, but game g's first row has a time (give every row of a game a time, or none)"),
    ("f.csv", [("g", 1, "A", "p", "describer", 5, "hi"), ("g", 1, "A", "q", "matcher", 4, "ok")], HEADER,
     "f.csv: row 3, column time: 4 is earlier than the row before in game g (rows are in the order said)"),
    ("f.csv", [("g", 2, "A", "p", "describer", 0, "hi"), ("g", 1, "B", "p", "describer", 1, "ok")], HEADER,
     "f.csv: row 3, column trial: trial 1 of game g comes after trial 2 began"),
    ("f.csv", [("g", 1, "A", "p", "describer", 0, "hi"), ("g", 1, "B", "p", "describer", 1, "ok")], HEADER,
     "f.csv: row 3, column referent: trial 1 of game g is about 'A', this row says 'B' (one referent per trial)"),
    ("f.csv", [("g", 1, "A", "p", "describer", 0, "hi"), ("g", 1, "A", "q", "describer", 1, "ok")], HEADER,
     "f.csv: row 3, column player: trial 1 of game g already has describer 'p' (one describer per trial)"),
    ("f.csv", [("g", 1, "A", "p", "describer", 0, "hi"), ("g", 1, "A", "p", "matcher", 1, "ok")], HEADER,
     "f.csv: row 3, column role: 'p' is the describer of trial 1 of game g"),
    ("f.csv", [("g", 1, "A", "p", "describer", 0, "hi", 1), ("g", 1, "A", "q", "matcher", 1, "ok", 2)],
     HEADER + ("repetition",), "f.csv: row 3, column repetition: trial 1 of game g is repetition 1, this row says 2"),
    ("f.csv", [], HEADER, "f.csv: no messages"),
    ("f.jsonl", ['{"game": "g"'], None, "f.jsonl: line 1, column 13: not JSON (Expecting ',' delimiter)"),
    ("f.jsonl", ["[1, 2]"], None, "f.jsonl: row 1: not a message (a JSON object with the keys game, trial"),
    ("f.jsonl", ['{"game": "g", "trial": 1, "referent": "A", "player": "p", "role": "describer"}'], None,
     "f.jsonl: row 1, column text: missing"),
    ("f.jsonl", ["", '{"game": "g", "trial": true, "referent": "A", "player": "p", "role": "describer", "text": ""}'],
     None, "f.jsonl: row 2, column trial: must be a whole number >= 1, got True"),
    ("f.jsonl", ['{"game": ["g"], "trial": 1, "referent": "A", "player": "p", "role": "describer", "text": ""}'], None,
     "f.jsonl: row 1, column game: must be a string, got ['g']"),
])
def test_a_bad_file_is_one_line_naming_file_row_and_column(capsys, tmp_path, name, rows, header, message):
    path = tmp_path / name
    if header is None:
        path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    else:
        write_csv(path, rows, header)
    code, out, err = run_cli(capsys, path)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(f"fsreg-eval: error: {path.parent}/") and message in err


def test_a_file_not_utf8_or_missing_is_one_line(capsys, tmp_path):
    path = tmp_path / "f.csv"
    path.write_bytes(b"game,trial\n\xff\xfe\n")
    code, _, err = run_cli(capsys, path)
    assert code == 2 and err.count("\n") == 1 and f"{path}: not UTF-8 text" in err
    code, _, err = run_cli(capsys, tmp_path / "none.csv")
    assert code == 2 and err.count("\n") == 1 and f"{tmp_path / 'none.csv'}: file not found" in err


# ------------------------------------------------------------------ the tangram adapter
#: Held-out log-likelihoods of ``fsreg-eval tangrams`` on ``write_example`` before it became an adapter
#: (commit 8ee1673, folds 2, these grids): the adapter must give them to the last digit printed.
BEFORE = {"decay": -0.695562741246, "activation": -0.584106382925, "displacement": -0.676070457057,
          "displacement-random": -0.649364296685, "global-capacity": -0.666941479235,
          "decay+displacement": -0.670270924645, "last-description": -0.578494419833, "constant": -0.689011295586,
          "recency-seconds": -0.671438302701, "recency-all": -0.549024281447}


def test_the_tangram_adapter_gives_todays_result_and_its_rows_read_back_give_the_same(capsys, tmp_path):
    T.write_example(tmp_path / "corpus")
    grids = ["--grid", "decay_period=5,10,20", "--grid", "capacity=1,2,3"]
    options = ["--folds", "2", *grids, "--resamples", "200", "--json"]
    code, out, err = run_cli(capsys, tmp_path / "corpus" / T.FILE, *options)  # no reference-game file
    assert code == 2 and "column game: missing from the header" in err
    assert cli.eval_main(["tangrams", str(tmp_path / "corpus"), *options]) == 0
    adapted = json.loads(capsys.readouterr()[0])
    for model, value in BEFORE.items():
        assert round(adapted["models"][model]["heldout_ll"], 12) == value, model
    for suffix in ("csv", "jsonl"):
        rows = tmp_path / f"rows.{suffix}"
        assert cli.eval_main(["tangrams", str(tmp_path / "corpus"), "--export-rows", str(rows)]) == 0
        assert capsys.readouterr()[0] == f"42 messages of 4 games written to {rows}\n"
        code, out, err = run_cli(capsys, rows, *options)
        assert code == 0, err
        assert json.loads(out) == adapted
    missing = tmp_path / "no" / "rows.csv"
    assert cli.eval_main(["tangrams", str(tmp_path / "corpus"), "--export-rows", str(missing)]) == 2
    assert capsys.readouterr()[1] == f"fsreg-eval: error: --export-rows {missing}: cannot write (No such file or " \
                                     "directory)\n"
