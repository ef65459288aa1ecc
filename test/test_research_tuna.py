"""fsreg-eval tuna on a hand-made mini corpus whose scores were worked out by hand."""

import atexit
import json
import shutil
import tempfile
from pathlib import Path

import pytest
from tuna_mini import write_mini

from fsreg_ros.research import cli
from fsreg_ros.research.scores import dice, masi
from fsreg_ros.research.tuna import TunaError, evaluate, learn_order, load_trials, parse_trial, trial_entities

MINI = write_mini(Path(tempfile.mkdtemp(prefix="fsreg-tuna-mini-")))
atexit.register(shutil.rmtree, MINI, ignore_errors=True)
ORDERS = ["--order", "furniture=type,colour,orientation,size", "--order", "people=type,hasBeard,hasGlasses"]


def test_dice_and_masi_by_hand():
    gold = {"type=chair", "colour=red", "orientation=front"}
    assert dice({"type=chair", "size=large"}, gold) == pytest.approx(2 / 5)
    assert masi({"type=chair", "size=large"}, gold) == pytest.approx(1 / 4 * 1 / 3)
    assert masi({"type=desk", "orientation=left"}, {"type=desk", "orientation=left", "colour=grey"}) == pytest.approx(
        2 / 3 * 2 / 3
    )
    assert masi(gold, set(gold)) == 1.0 and dice(gold, gold) == 1.0
    assert masi({"a"}, {"b"}) == 0.0 and dice({"a"}, {"b"}) == 0.0


def test_loader_reads_trials_and_strips_values():
    trials = load_trials(MINI)
    assert [t.id for t in trials] == ["m1", "m2", "m3"]
    m1 = trials[0]
    assert (m1.domain, m1.condition, m1.target) == ("furniture", "-LOC", "1")
    assert m1.entities["3"]["size"] == "small"  # "small " stripped
    assert m1.gold == frozenset({"type=chair", "colour=red", "orientation=front"})
    # -LOC: no location attributes; booleans only when true
    assert "x-dimension=1" not in trial_entities(m1)["1"]
    m3 = trials[2]
    assert trial_entities(m3)["1"] == ["type=person", "hasBeard=1", "age=old", "x-dimension=1"]


def test_given_orders_give_the_hand_computed_scores():
    trials = load_trials(MINI)
    results = {(r.domain, r.algorithm): r for r in evaluate(trials, {
        "furniture": ["type", "colour", "orientation", "size"], "people": ["type", "hasBeard", "hasGlasses"]})}
    ia = results["furniture", "dist-pia"]
    assert [s.description for s in ia.scores] == [
        ("type=chair", "colour=red", "orientation=front"),
        ("type=desk", "orientation=left"),
    ]
    row = ia.to_json()
    assert (row["n"], row["dice"], row["masi"], row["accuracy"]) == (2, 0.9, round((1 + 4 / 9) / 2, 4), 0.5)
    assert row["minimality"] == 0.5 and row["uniqueness"] == 1.0
    fb = results["furniture", "full-brevity"]
    assert fb.scores[0].description == ("type=chair", "size=large")
    assert fb.to_json()["dice"] == 0.6
    assert fb.to_json()["masi"] == round((1 / 12 + 4 / 9) / 2, 4)
    assert results["furniture", "greedy"].scores[0].description == ("type=chair", "size=large")
    people = results["people", "dist-pia"].scores[0]
    assert (people.condition, people.description) == ("+LOC", ("type=person", "hasBeard=1"))
    assert people.dice == pytest.approx(0.8)


def test_learned_order_is_type_then_human_frequency():
    trials = load_trials(MINI)
    assert learn_order(trials[:2]) == ["type", "colour", "orientation", "size"]


def test_json_output_shape_and_per_trial_csv(tmp_path, capsys):
    out = tmp_path / "trials.csv"
    assert cli.eval_main(["tuna", str(MINI), *ORDERS, "--json", "--per-trial", str(out)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert list(data) == ["results"]
    first = data["results"][0]
    assert {k: first[k] for k in ("domain", "condition", "algorithm", "order", "n", "dice", "masi", "accuracy")} == {
        "domain": "furniture", "condition": "-LOC", "algorithm": "dist-pia",
        "order": ["type", "colour", "orientation", "size"], "n": 2, "dice": 0.9, "masi": 0.7222, "accuracy": 0.5,
    }
    lines = out.read_text().splitlines()
    assert lines[0].startswith("trial,domain,condition,algorithm")
    assert len(lines) == 1 + 3 * 3


def test_cross_validation_reports_fold_orders(capsys):
    assert cli.eval_main(["tuna", str(MINI), "--folds", "2", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["results"]
    furniture = [r for r in rows if r["domain"] == "furniture"][0]
    assert furniture["learned"] == "cross-validated" and len(furniture["fold_orders"]) == 2
    assert furniture["order"][0] == "type"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["tuna", "/no/such/dir"], "no such file or directory"),
        (["tuna", str(MINI), "--order", "kitchen=type"], "--order 'kitchen=type'"),
        (["tuna", str(MINI), "--algorithms", "sd-pia"], "--algorithms: unknown sd-pia"),
        (["tuna", str(MINI), "--folds", "1"], "--folds must be at least 2"),
        (["tuna", str(MINI), "--order", "furniture=type,colur"], "no furniture trial has attribute colur"),
    ],
)
def test_bad_input_is_one_line_exit_2(argv, message, capsys):
    assert cli.eval_main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_malformed_trial_is_named():
    with pytest.raises(TunaError, match="bad.xml: not well-formed XML"):
        parse_trial("<TRIAL", "bad.xml")
    with pytest.raises(TunaError, match="no ENTITY has TYPE"):
        parse_trial('<TRIAL DOMAIN="people" CONDITION="-LOC"><DOMAIN/></TRIAL>', "x.xml")


def test_full_corpus_reproduces_the_reference_figures(tuna_dir):
    trials = load_trials(tuna_dir)
    assert len(trials) == 780
    orders = {
        "furniture": ["type", "colour", "orientation", "size"],
        "people": ["type", "hasBeard", "hasGlasses", "hairColour", "hasHair", "age", "orientation", "hasSuit",
                   "hasTie", "hasShirt"],
    }
    rows = {(r["domain"], r["condition"], r["algorithm"]): r for r in (x.to_json() for x in evaluate(trials, orders))}
    ia = rows["furniture", "-LOC", "dist-pia"]
    assert (ia["n"], round(ia["dice"], 3), round(ia["masi"], 3), round(ia["accuracy"], 3)) == (210, 0.781, 0.579, 0.429)
    assert round(rows["furniture", "-LOC", "full-brevity"]["dice"], 3) == 0.705
    assert round(rows["furniture", "-LOC", "greedy"]["dice"], 3) == 0.705
    people = rows["people", "-LOC", "dist-pia"]
    assert (people["n"], round(people["dice"], 3)) == (180, 0.691)
