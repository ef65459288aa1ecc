"""Every file a tool reads is a regular file of bounded size and depth, refused in one line otherwise (issue 38.5).

Each kind of file -- a scenario, a params file, a lexicon, a recording's ``metadata.yaml``
and ``.mcap``, an event trace for ``fsreg-plot``, the TUNA and tangram corpora -- is given
a named pipe (which would block a reader forever), a link to ``/dev/zero`` (which never
ends), a file over its limit (sparse: no disk is used), and for YAML a document nested
5,000 deep (libyaml's composer recurses in C) and an alias bomb (a billion nodes once
expanded): each is one exact line, at once.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Callable

import pytest

from fsreg_ros.core.io import input_file
from fsreg_ros.core.lexicon import Lexicon
from fsreg_ros.core.io.recording import (
    MAX_BAG_BYTES, METADATA_MAX_BYTES, STRING, TOPICS_KEY, BagWriter, Channel, open_recording,
)
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.io.yaml_source import MAX_FILE_BYTES
from fsreg_ros.research.cli import read_trace
from fsreg_ros.research.reference_games import read_rows
from fsreg_ros.research.tangrams import load_games
from fsreg_ros.research.tuna import load_trials
from fsreg_ros.ros.node_parameters import PARAMS_MAX_BYTES, read_params_file

DEEP = "[" * 5000 + "]" * 5000 + "\n"
BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi"))
FIFO = "is a named pipe (FIFO), not a regular file"
DEVICE = "is a character device, not a regular file"
DEPTH = "not valid here: YAML nested deeper than 1000 levels"
ALIASES = "not valid here: its aliases expand to over 1,000,000 nodes (an alias bomb?)"


def make(path: Path, case: str, limit: int = 0) -> Path:
    """Make ``path`` a FIFO, a link to /dev/zero, a sparse file one byte over ``limit``, or a YAML text."""
    if case == "fifo":
        os.mkfifo(path)
    elif case == "zero":
        path.symlink_to("/dev/zero")
    elif case == "big":
        with path.open("wb") as handle:
            handle.truncate(limit + 1)
    else:
        path.write_text({"deep": DEEP, "bomb": BOMB}[case])
    return path


def refusal(read: Callable, path: Path) -> str:
    with pytest.raises(Exception) as err:
        read(path)
    text = str(err.value)
    assert "\n" not in text and isinstance(err.value, ValueError), text
    return text


YAML_KINDS = {"scenario": (load_scenario, MAX_FILE_BYTES), "lexicon": (Lexicon.load, MAX_FILE_BYTES)}


@pytest.mark.parametrize("kind", sorted(YAML_KINDS))
@pytest.mark.parametrize("case, said", [("fifo", ": " + FIFO), ("zero", ": " + DEVICE), ("big", None),
                                        ("deep", ":1: " + DEPTH), ("bomb", ":6: " + ALIASES)])
def test_a_scenario_or_lexicon_that_is_no_file_or_too_much_is_one_line(tmp_path, kind, case, said):
    read, limit = YAML_KINDS[kind]
    path = make(tmp_path / f"{kind}.yaml", case, limit)
    assert refusal(read, path) == f"{path}{said or f': too large: over {limit:,} bytes'}"


@pytest.mark.parametrize("case, said", [
    ("fifo", FIFO), ("zero", DEVICE), ("big", f"too large: over {PARAMS_MAX_BYTES:,} bytes"),
    ("deep", f"{DEPTH} (line 1)"), ("bomb", f"{ALIASES} (line 6)")])
def test_a_params_file_that_is_no_file_or_too_much_is_one_line(tmp_path, case, said):
    path = make(tmp_path / "params.yaml", case, PARAMS_MAX_BYTES)
    assert refusal(read_params_file, path) == f"{path}: {said}"


def recording(path: Path) -> Path:
    writer = BagWriter(path, [Channel("/r/rr/result", STRING, 10)], custom={TOPICS_KEY: json.dumps(
        {"/r/rr/result": "rr"})})
    writer.close()
    open_recording(path)  # readable as written
    return path


@pytest.mark.parametrize("case, said", [
    ("fifo", FIFO), ("zero", DEVICE), ("big", f"too large: over {METADATA_MAX_BYTES:,} bytes"),
    ("deep", None), ("bomb", None)])
def test_a_recordings_metadata_that_is_no_file_or_too_much_is_one_line(tmp_path, case, said):
    bag = recording(tmp_path / "bag")
    metadata = bag / "metadata.yaml"
    metadata.unlink()
    make(metadata, case, METADATA_MAX_BYTES)
    text = refusal(open_recording, bag)
    if case == "deep":
        assert text == f"{metadata}:1: not a readable recording ({DEPTH})"
    elif case == "bomb":
        assert text == f"{metadata}:6: not a readable recording ({ALIASES})"
    else:
        assert text == f"{metadata}: not a readable recording ({said})"


@pytest.mark.parametrize("case, said", [("fifo", FIFO), ("zero", DEVICE),
                                        ("big", f"too large: over {MAX_BAG_BYTES:,} bytes")])
def test_a_recordings_mcap_that_is_no_file_or_too_big_is_one_line(tmp_path, case, said):
    bag = recording(tmp_path / "bag")
    mcap = bag / "bag.mcap"
    mcap.unlink()
    make(mcap, case, MAX_BAG_BYTES)
    assert refusal(open_recording, bag) == f"{mcap}: not a readable recording ({said})"
    assert refusal(open_recording, mcap) == f"{mcap}: not a readable recording ({said})"  # the file itself


CORPORA = {"trace": read_trace, "tangrams": load_games}


@pytest.mark.parametrize("kind", sorted(CORPORA))
@pytest.mark.parametrize("case, said", [("fifo", FIFO), ("zero", DEVICE),
                                        ("big", f"too large: over {input_file.MAX_CORPUS_BYTES:,} bytes")])
def test_a_corpus_or_trace_that_is_no_file_or_too_big_is_one_line(tmp_path, kind, case, said):
    path = make(tmp_path / f"{kind}.csv", case, input_file.MAX_CORPUS_BYTES)
    assert refusal(CORPORA[kind], path) == f"{path}: {said}"


@pytest.mark.parametrize("case, said", [("fifo", FIFO), ("zero", DEVICE),
                                        ("big", f"too large: over {input_file.MAX_CORPUS_BYTES:,} bytes")])
def test_a_tuna_trial_that_is_no_file_or_too_big_is_one_line(tmp_path, case, said):
    trial = make(tmp_path / "s1.xml", case, input_file.MAX_CORPUS_BYTES)
    assert refusal(load_trials, tmp_path) == f"{trial}: cannot read ({said})"


def test_a_trace_line_nested_too_deeply_is_one_line(tmp_path):
    path = tmp_path / "trace.jsonl"
    path.write_text("[" * 100_000 + "]" * 100_000 + "\n")
    assert refusal(read_trace, path) == f"{path}: line 1: not JSON (nested too deeply)"


#: The JSON Lines readers (an event trace, a reference-game corpus): one reader, one wording.
JSON_LINES = {"trace": read_trace, "reference-games": read_rows}


@pytest.mark.parametrize("kind", sorted(JSON_LINES))
@pytest.mark.parametrize("line, said", [
    (b'{"op": "encode", "time": 1', "line 2, column 27: not JSON (Expecting ',' delimiter)"),
    (b'{"time": NaN}', "line 2: not JSON (NaN is not a JSON number)"),
    (b'{"time": -Infinity}', "line 2: not JSON (-Infinity is not a JSON number)"),
    (b'{"time": ' + b"9" * 5000 + b"}",
     "line 2: not JSON (Exceeds the limit (4300 digits) for integer string conversion)"),
    (b'{"text": "caf\xe9"}', "line 2, column 14: not UTF-8 text (invalid continuation byte)"),
])
def test_a_bad_json_line_is_one_line_naming_file_line_and_column(tmp_path, kind, line, said):
    path = tmp_path / "file.jsonl"
    path.write_bytes(b"\n" + line + b"\n{}\n")
    assert refusal(JSON_LINES[kind], path) == f"{path}: {said}"


def test_json_lines_yields_each_value_with_its_line(tmp_path):
    path = tmp_path / "file.jsonl"
    path.write_bytes(b'{"a": 1}\r\n\n  \n[2, "\xc3\xa9"]\n3')
    assert list(input_file.json_lines(path)) == [(1, {"a": 1}), (4, [2, "\u00e9"]), (5, 3)]


def test_ordinary_yaml_is_parsed_once_and_a_deep_one_is_refused_before_any_tree():
    """A text that cannot be too deep or hold aliases skips the event pass; a 200,000-deep one does not crash."""
    from fsreg_ros.core.io.yaml_source import SourceError, load_yaml

    assert load_yaml("a: [1, {b: c}]\n", "f.yaml")[1] == {"a": [1, {"b": "c"}]}
    with pytest.raises(SourceError) as err:
        load_yaml("[" * 200_000 + "]" * 200_000, "f.yaml")  # libyaml's C composer overflows the stack here
    assert str(err.value) == f"f.yaml:1: {DEPTH}"
    assert load_yaml("a: &x [1, 2]\nb: *x\n", "f.yaml")[1] == {"a": [1, 2], "b": [1, 2]}  # aliases still work


def test_a_plot_result_or_a_sweep_ledger_that_is_a_fifo_is_one_line(tmp_path, capsys):
    from fsreg_ros.research.cli import plot_main
    from fsreg_ros.research.ledger import GAMES, Ledger, LedgerError

    trace = tmp_path / "trace.jsonl"
    trace.write_text('{"op": "encode", "domain": "faces", "entity": "face1", "property": "male", "cause": "speaker", '
                     '"time": 1.0}\n')
    result = make(tmp_path / "result.json", "fifo")
    assert plot_main([str(trace), "--result", str(result), "-o", str(tmp_path / "wm.png")]) == 2
    assert capsys.readouterr().err == f"fsreg-plot: error: {result}: {FIFO}\n"
    make(tmp_path / GAMES, "zero")
    with pytest.raises(LedgerError) as err:
        Ledger.read(tmp_path)
    assert str(err.value) == f"{tmp_path / GAMES}: {DEVICE}"
