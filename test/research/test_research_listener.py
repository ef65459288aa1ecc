"""The listener that can fail (fsreg_ros.research.listener): exact outcomes on hand-made games, repairs, robot-robot."""

import csv

import pytest

from fsreg_ros.research import cli
from fsreg_ros.research.games import DOMAIN, ROBOT_ORDER, Game, _consultant, make_game, play, scenario_of
from fsreg_ros.research.listener import Listener, ListenerOptions, perceive
from fsreg_ros.research.sweep import COLUMNS, LISTENER_METRICS

# Three faces: face1 and face2 differ in hair colour and glasses, face3 in nearly everything.
BOARD = {
    "face1": ["light-hair", "short-hair", "male", "lab-coat", "glasses"],
    "face2": ["dark-hair", "short-hair", "male", "lab-coat", "no-glasses"],
    "face3": ["light-hair", "long-hair", "female", "hoodie", "no-glasses"],
}
HUMAN_ORDER = ("glasses", "no-glasses", "lab-coat", "hoodie", "t-shirt", "male", "female", "light-hair", "dark-hair",
               "short-hair", "long-hair")


def tiny_game(turns=(("human", 1.0, "face3", ("female",)), ("robot", 2.0, "face1", None))) -> Game:
    return Game(5, "faces", {DOMAIN: {e: list(p) for e, p in BOARD.items()}}, {DOMAIN: HUMAN_ORDER}, 1.0,
                tuple((s, t, e, DOMAIN, d) for s, t, e, d in turns), (), (2,))


def knowing(listener: Listener, board: dict) -> Listener:
    """Give ``listener`` exactly ``board`` as its knowledge (instead of the drawn one)."""
    listener.consultants[DOMAIN] = _consultant(DOMAIN, board, ROBOT_ORDER)
    return listener


def test_a_perfect_listener_identifies_every_referent_at_once_and_changes_nothing():
    game = make_game(3, 40)
    heard = play(game, {"policy": "decay", "decay_period": 10}, listener=ListenerOptions())
    alone = play(game, {"policy": "decay", "decay_period": 10})
    assert len(heard.heard) == 20
    assert all(h.success and h.turns == 1 and not h.repairs for h in heard.heard)
    assert [h.attempts[0] for h in heard.heard] == [t["description"] for t in alone.result["turns"]
                                                    if t["speaker"] == "robot"]
    assert heard.result == alone.result and alone.heard is None


def test_the_robot_says_the_incremental_algorithm_description_and_a_perfect_listener_takes_it():
    played = play(tiny_game(), {"policy": "none"}, listener=ListenerOptions())
    (robot,) = [t for t in played.result["turns"] if t["speaker"] == "robot"]
    assert robot["description"] == ["light-hair", "short-hair"]  # light-hair rules out face2, short-hair face3
    (heard,) = played.heard
    assert heard.attempts == [["light-hair", "short-hair"]] and heard.outcomes == ["resolved"]


def test_a_listener_missing_a_fact_fails_then_succeeds_after_a_repair_with_one_added_property():
    game = tiny_game()
    robot = _consultant(DOMAIN, game.board, ROBOT_ORDER)
    partial = {**BOARD, "face1": ["short-hair", "male", "lab-coat", "glasses"]}  # face1's hair colour unknown
    listener = knowing(Listener(game, ListenerOptions(), scenario_of(game)), partial)
    heard = listener.hear(["light-hair", "short-hair"], "face1", DOMAIN, robot, 2.0, 1)
    # None fits; without light-hair face1 and face2 do, so the listener disputes light-hair; the robot drops it
    # and adds its first property (robot order) that rules face2 out: glasses.
    assert heard.outcomes == ["no-match", "resolved"]
    assert heard.attempts == [["light-hair", "short-hair"], ["short-hair", "glasses"]]
    assert heard.repairs == [{"added": "glasses", "dropped": "light-hair"}]
    assert heard.success and heard.turns == 2 and heard.final_length == 2 and heard.said == 3
    assert robot.queue("face1") == ["glasses"]  # rule 1: the robot said it


def test_an_ambiguous_reference_is_repaired_with_the_next_distinguishing_property():
    game = tiny_game()
    robot = _consultant(DOMAIN, game.board, ROBOT_ORDER)
    listener = knowing(Listener(game, ListenerOptions(), scenario_of(game)), BOARD)
    heard = listener.hear(["short-hair"], "face1", DOMAIN, robot, 2.0, 1)  # face1 and face2 are short-haired
    assert heard.outcomes == ["ambiguous", "resolved"]
    assert heard.attempts == [["short-hair"], ["short-hair", "light-hair"]]
    wrong = {**BOARD, "face1": ["dark-hair", "short-hair", "male", "lab-coat", "no-glasses"],
             "face2": ["light-hair", "short-hair", "male", "lab-coat", "no-glasses"]}  # misperceived
    listener = knowing(Listener(game, ListenerOptions(max_repairs=1), scenario_of(game)), wrong)
    heard = listener.hear(["light-hair", "short-hair"], "face1", DOMAIN, robot, 2.0, 1)
    # The listener takes face2; the robot rules it out with glasses, which the listener sees on nobody.
    assert heard.outcomes == ["wrong-referent", "no-match"]
    assert heard.repairs == [{"added": "glasses", "dropped": None}]
    assert not heard.success and heard.turns is None


def test_perception_is_seeded_per_game_and_the_same_for_every_setting():
    boards = make_game(11, 10).boards
    one, errors = perceive(boards, 11, 0.2, 0.2)
    assert (one, errors) == perceive(boards, 11, 0.2, 0.2)
    assert one != perceive(boards, 12, 0.2, 0.2)[0]
    kinds = [k for entity in errors[DOMAIN].values() for k, _, _ in entity]
    assert {"missing", "noise"} <= set(kinds)
    missing = sum(k == "missing" for k in kinds)
    assert sum(len(p) for p in one[DOMAIN].values()) == 16 * 5 - missing
    assert perceive(boards, 11, 0.0, 0.0) == ({DOMAIN: {e: list(p) for e, p in boards[DOMAIN].items()}}, {})
    game = make_game(11, 40)
    options = ListenerOptions(missing=0.1, noise=0.1)
    a = play(game, {"policy": "decay", "decay_period": 10}, listener=options)
    b = play(game, {"policy": "decay", "decay_period": 10}, listener=options)
    assert [(h.attempts, h.outcomes) for h in a.heard] == [(h.attempts, h.outcomes) for h in b.heard]
    assert not all(h.success and h.turns == 1 for h in a.heard)  # this listener fails somewhere


def test_robot_robot_game_exact_descriptions():
    game = tiny_game((("human", 1.0, "face1", None), ("robot", 2.0, "face1", None), ("human", 3.0, "face2", None),
                      ("robot", 4.0, "face3", None)))
    played = play(game, {"policy": "decay", "decay_period": 10}, listener=ListenerOptions(partner="robot"))
    said = [(t["speaker"], t["description"]) for t in played.result["turns"]]
    assert said == [
        ("human", ["light-hair", "short-hair"]),  # the partner: DIST-PIA-like SD-PIA on an empty WM, robot order
        ("robot", ["light-hair", "short-hair"]),  # the robot reuses what its WM holds of face1
        ("human", ["dark-hair"]),
        # SD-PIA: light-hair from face3's WM (RR affirmed it of face3 at turn 0, rule 2), then long-hair.
        ("robot", ["light-hair", "long-hair"]),
    ]
    assert all(t["resolved"] == t["target"] for t in played.result["turns"] if t["speaker"] == "human")
    assert [h.turns for h in played.heard] == [1, 1]
    human = play(game, {"policy": "decay", "decay_period": 10}, listener=ListenerOptions(partner="robot",
                                                                                         order="human"))
    assert human.result["turns"][0]["description"] == ["glasses"]  # the partner's order: glasses first


def test_sweep_with_a_listener_adds_its_metrics_and_without_one_writes_what_it_did(tmp_path, capsys):
    small = ["--policies", "decay,none", "--decay-periods", "10", "--seeds", "2", "--turns", "12", "--no-progress",
             "--no-plots"]
    assert cli.sweep_main([*small, "--out", str(tmp_path / "plain")]) == 0
    plain = capsys.readouterr().out
    with (tmp_path / "plain" / "runs.csv").open() as handle:
        assert tuple(next(csv.reader(handle))) == COLUMNS
    assert "\nlistener:" not in plain
    assert cli.sweep_main([*small, "--out", str(tmp_path / "l"), "--listener-missing", "0"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(plain.splitlines()[0].replace("plain", "l"))
    assert "listener: the human, facts missing 0, misperceived 0, at most 3 repairs" in out
    with (tmp_path / "l" / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == COLUMNS + LISTENER_METRICS
    assert {(r["success"], r["first_success"], r["turns_to_success"], r["repairs"]) for r in rows} == {
        ("1.000000", "1.000000", "1.000000", "0.000000")}
    with (tmp_path / "l" / "summary.csv").open() as handle:
        assert "success_low" in next(csv.reader(handle))
    assert cli.sweep_main([*small, "--out", str(tmp_path / "r"), "--partner", "robot", "--partner-memory",
                           "policy=none"]) == 0
    assert "robot resolved" in capsys.readouterr().out
    with (tmp_path / "r" / "runs.csv").open() as handle:
        assert next(csv.reader(handle))[-1] == "partner_resolved"


@pytest.mark.parametrize("extra, message", [
    (["--listener-missing", "1.5"], "--listener-missing must be in [0, 1], got 1.5"),
    (["--listener-missing", "-0.1"], "--listener-missing must be in [0, 1], got -0.1"),
    (["--listener-missing", "nan"], "--listener-missing must be in [0, 1], got nan"),
    (["--listener-missing", "lots"], "--listener-missing: 'lots' is not a number"),
    (["--listener-noise", "2"], "--listener-noise must be in [0, 1], got 2"),
    (["--listener-noise", "nan"], "--listener-noise must be in [0, 1], got nan"),
    (["--listener-noise", "inf"], "--listener-noise must be in [0, 1], got inf"),
    (["--max-repairs", "-1"], "--max-repairs must be in [0, 20], got -1"),
    (["--max-repairs", "21"], "--max-repairs must be in [0, 20], got 21"),
    (["--max-repairs", "two"], "--max-repairs: 'two' is not an integer"),
    (["--partner", "dog"], "--partner: expected human or robot, got 'dog'"),
    (["--listener-order", "robot"], "--listener-order needs --partner robot"),
    (["--partner", "robot", "--listener-order", "sideways"], "--listener-order: expected one of human, robot, "
                                                             "reversed, got 'sideways'"),
    (["--partner-memory", "policy=none"], "--partner-memory needs --partner robot"),
    (["--partner", "robot", "--partner-memory", "policy=sometimes"], "policy"),
    (["--partner", "robot", "--human-memory", "policy=none"], "--human-memory and --partner robot"),
])
def test_bad_listener_options_are_one_line_and_exit_2(tmp_path, capsys, extra, message):
    argv = ["--policies", "none", "--seeds", "1", "--turns", "4", "--no-progress", "--no-plots",
            "--out", str(tmp_path / "x"), *extra]
    assert cli.sweep_main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("fsreg-sweep: error: ")
    assert not (tmp_path / "x" / "runs.csv").exists()
