"""fsreg-eval tuna on a hand-made mini corpus whose scores were worked out by hand."""

import atexit
import hashlib
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
    assert (row["n"], row["dice"], row["accuracy"]) == (2, 0.9, 0.5)
    assert row["masi"] == (1 + 4 / 9) / 2  # unrounded: a report rounds once, when it prints
    assert row["minimality"] == 0.5 and row["uniqueness"] == 1.0
    fb = results["furniture", "full-brevity"]
    assert fb.scores[0].description == ("type=chair", "size=large")
    assert fb.to_json()["dice"] == pytest.approx(0.6)
    assert fb.to_json()["masi"] == pytest.approx((1 / 12 + 4 / 9) / 2)
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
        "order": ["type", "colour", "orientation", "size"], "n": 2, "dice": 0.9, "masi": (1 + 4 / 9) / 2,
        "accuracy": 0.5,
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


PEOPLE = ["type", "hasBeard", "hasGlasses", "hairColour", "hasHair", "age", "orientation", "hasSuit", "hasTie",
          "hasShirt"]
GIVEN = {"furniture": ["type", "colour", "orientation", "size"], "people": PEOPLE}
#: Every row of the full corpus (780 singular trials), given orders (as in docs/research.md) and learned ones
#: (10-fold cross-validation): n, Dice, MASI, accuracy, minimality, uniqueness (to 6 decimals) and the first 16
#: hex digits of the SHA-256 of every trial's description (so a changed description fails even if means agree).
RECORDED = {
    ("given", "furniture", "-LOC", "dist-pia"):
        (210, 0.780824, 0.578466, 0.428571, 0.571429, 1.0, "e6dc9d69b2f2c1c1"),
    ("given", "furniture", "-LOC", "full-brevity"):
        (210, 0.704996, 0.461032, 0.271429, 1.0, 1.0, "da4a4bfec6d786cf"),
    ("given", "furniture", "-LOC", "greedy"):
        (210, 0.704996, 0.461032, 0.271429, 1.0, 1.0, "da4a4bfec6d786cf"),
    ("given", "furniture", "+LOC", "dist-pia"):
        (210, 0.700983, 0.461262, 0.342857, 0.571429, 1.0, "46123025c51b8f4f"),
    ("given", "furniture", "+LOC", "full-brevity"):
        (210, 0.626051, 0.366221, 0.214286, 1.0, 1.0, "6b125313ed158ccf"),
    ("given", "furniture", "+LOC", "greedy"):
        (210, 0.626051, 0.366221, 0.214286, 1.0, 1.0, "6b125313ed158ccf"),
    ("given", "people", "-LOC", "dist-pia"):
        (180, 0.691173, 0.452597, 0.25, 0.5, 1.0, "1b347e81c65f3846"),
    ("given", "people", "-LOC", "full-brevity"):
        (180, 0.640423, 0.402156, 0.205556, 1.0, 1.0, "4ff0c6d05bf736d1"),
    ("given", "people", "-LOC", "greedy"):
        (180, 0.640423, 0.402156, 0.205556, 1.0, 1.0, "4ff0c6d05bf736d1"),
    ("given", "people", "+LOC", "dist-pia"):
        (180, 0.557328, 0.341574, 0.2, 0.5, 1.0, "13b8ec747042a277"),
    ("given", "people", "+LOC", "full-brevity"):
        (180, 0.518254, 0.312469, 0.177778, 1.0, 1.0, "c3f45a25e246d478"),
    ("given", "people", "+LOC", "greedy"):
        (180, 0.518254, 0.312469, 0.177778, 1.0, 1.0, "c3f45a25e246d478"),
    ("learned", "furniture", "-LOC", "dist-pia"):
        (210, 0.780824, 0.578466, 0.428571, 0.571429, 1.0, "e6dc9d69b2f2c1c1"),
    ("learned", "furniture", "-LOC", "full-brevity"):
        (210, 0.704996, 0.461032, 0.271429, 1.0, 1.0, "da4a4bfec6d786cf"),
    ("learned", "furniture", "-LOC", "greedy"):
        (210, 0.704996, 0.461032, 0.271429, 1.0, 1.0, "da4a4bfec6d786cf"),
    ("learned", "furniture", "+LOC", "dist-pia"):
        (210, 0.711255, 0.390741, 0.204762, 0.261905, 1.0, "e38552466e36ec94"),
    ("learned", "furniture", "+LOC", "full-brevity"):
        (210, 0.569751, 0.282434, 0.104762, 1.0, 1.0, "201b7d439e9dd3d9"),
    ("learned", "furniture", "+LOC", "greedy"):
        (210, 0.568390, 0.282063, 0.104762, 1.0, 1.0, "91c0b6b231ef96a4"),
    ("learned", "people", "-LOC", "dist-pia"):
        (180, 0.692985, 0.454943, 0.261111, 0.5, 1.0, "5aa3042effa4e886"),
    ("learned", "people", "-LOC", "full-brevity"):
        (180, 0.640423, 0.402156, 0.205556, 1.0, 1.0, "4ff0c6d05bf736d1"),
    ("learned", "people", "-LOC", "greedy"):
        (180, 0.640423, 0.402156, 0.205556, 1.0, 1.0, "4ff0c6d05bf736d1"),
    ("learned", "people", "+LOC", "dist-pia"):
        (180, 0.521481, 0.268951, 0.155556, 0.116667, 1.0, "1eb73573be1e87f9"),
    ("learned", "people", "+LOC", "full-brevity"):
        (180, 0.507884, 0.263765, 0.122222, 1.0, 1.0, "1a3f358d994f2a3a"),
    ("learned", "people", "+LOC", "greedy"):
        (180, 0.507884, 0.263765, 0.122222, 1.0, 1.0, "1a3f358d994f2a3a"),
}


def measured(result) -> tuple:
    """Return a result's row as RECORDED holds it."""
    row = result.to_json()
    digest = hashlib.sha256(json.dumps([[s.trial, list(s.description)] for s in result.scores]).encode()).hexdigest()
    return (row["n"], *(round(row[k], 6) for k in ("dice", "masi", "accuracy", "minimality", "uniqueness")),
            digest[:16])


@pytest.fixture(scope="module")
def corpus_rows(tuna_dir) -> dict:
    """Every row of the real corpus, given and learned orders, keyed as RECORDED."""
    trials = load_trials(tuna_dir)
    assert len(trials) == 780
    rows = {}
    for label, orders in (("given", GIVEN), ("learned", {})):
        for result in evaluate(trials, orders):
            rows[(label, result.domain, result.condition, result.algorithm)] = measured(result)
    return rows


def test_full_corpus_has_every_recorded_row_and_no_other(corpus_rows):
    assert sorted(corpus_rows) == sorted(RECORDED)


@pytest.mark.parametrize("key", sorted(RECORDED), ids=lambda k: "/".join(k))
def test_full_corpus_row_equals_the_recorded_figures(corpus_rows, key):
    assert corpus_rows[key] == RECORDED[key]


def test_full_corpus_reproduces_the_reference_figures(corpus_rows):
    """The independent reference (furniture -LOC IA 0.781 / 0.578 / 0.429; FB, Greedy 0.705; people -LOC 0.691)."""
    n, dice_, masi_, accuracy, *_ = corpus_rows["given", "furniture", "-LOC", "dist-pia"]
    assert (n, f"{dice_:.3f}", f"{masi_:.3f}", f"{accuracy:.3f}") == (210, "0.781", "0.578", "0.429")
    assert f'{corpus_rows["given", "furniture", "-LOC", "full-brevity"][1]:.3f}' == "0.705"
    assert f'{corpus_rows["given", "people", "-LOC", "dist-pia"][1]:.3f}' == "0.691"


def test_printed_table_equals_the_recorded_figures_rounded_once(tuna_dir, capsys):
    orders = ["--order", "furniture=" + ",".join(GIVEN["furniture"]), "--order", "people=" + ",".join(PEOPLE)]
    assert cli.eval_main(["tuna", str(tuna_dir), *orders]) == 0
    lines = capsys.readouterr().out.splitlines()[1:]
    printed = {tuple(line.split()[:3]): line.split()[3:9] for line in lines}
    expected = {
        (domain, cond, algorithm): [str(v[0])] + [f"{x:.3f}" for x in v[1:6]]
        for (label, domain, cond, algorithm), v in RECORDED.items() if label == "given"
    }
    assert printed == expected


def test_documented_tables_equal_the_recorded_figures():
    """docs/research.md's tables (written by scripts/figures.sh) are the recorded rows, rounded once."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "research.md").read_text(encoding="utf-8")
    for label, name in (("given", "tuna"), ("learned", "tuna-learned")):
        block = text.split(f"<!-- figure {name} -->", 1)[1].split("<!-- /figure -->", 1)[0]
        rows = [line.split() for line in block.splitlines() if line.startswith(("furniture ", "people "))]
        documented = {(label, *cells[:3]): [cells[3], *cells[4:9]] for cells in rows}
        recorded = {key: [str(v[0])] + [f"{x:.3f}" for x in v[1:6]] for key, v in RECORDED.items() if key[0] == label}
        assert documented == recorded
