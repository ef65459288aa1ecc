"""Every figure of README.md and docs/research.md: its command runs (small scale) and its blocks match the docs."""

import re
import shutil
import tempfile
from pathlib import Path

import pytest
from tuna_mini import write_mini

from fsreg_ros.tools import figures
from fsreg_ros.tools.figures import BEGIN, END, FIGURES, RUN_TIME, ROOT, replace_blocks

DOCS = {doc: (ROOT / doc).read_text(encoding="utf-8") for doc in figures.DOCS}


def block(doc: str, name: str) -> str:
    text = DOCS[doc]
    return text.split(BEGIN.format(name), 1)[1].split(END, 1)[0]


def test_every_block_in_the_docs_belongs_to_a_figure_and_back():
    declared = {(doc, name) for f in FIGURES for name, (doc, _) in f.blocks.items()}
    found = {(doc, name) for doc, text in DOCS.items() for name in re.findall(r"<!-- figure (\S+) -->", text)}
    assert found == declared
    for doc, text in DOCS.items():
        assert text.count("<!-- figure ") == text.count(END)


@pytest.mark.parametrize("figure", FIGURES, ids=lambda f: f.name)
def test_each_documented_block_starts_with_its_command_and_says_its_run_time(figure):
    for name, (doc, _) in figure.blocks.items():
        content = block(doc, name)
        assert content.startswith("\n```bash\n" + figure.command() + "\n```\n"), name
        assert content.count(RUN_TIME) == 1, name


@pytest.fixture(scope="module")
def small_run():
    out = Path(tempfile.mkdtemp(prefix="fsreg-figures-"))
    tuna = write_mini(out / "tuna")
    yield tuna, out
    shutil.rmtree(out, ignore_errors=True)


@pytest.mark.slow  # every study of the docs, at small scale
@pytest.mark.parametrize("figure", FIGURES, ids=lambda f: f.name)
def test_each_figure_command_runs_at_small_scale(figure, small_run):
    tuna, out = small_run
    blocks = figures.run_small(figure, tuna, out)
    assert set(blocks) == set(figure.blocks)
    for name, text in blocks.items():
        assert text.startswith("```bash\n" + figure.command() + "\n```\n\n")
        body = text.split("```\n\n", 1)[1]
        assert body.strip() and RUN_TIME in body
        # The rendered block replaces the documented one, and only it.
        doc = figure.blocks[name][0]
        replaced = replace_blocks(DOCS[doc], {name: text}, doc)
        assert replaced.count(BEGIN.format(name)) == 1 and text in replaced
    if figure.writes:
        assert (out / figure.name / "manifest.json").exists()


def test_check_compares_all_but_run_times():
    text = "a\n<!-- figure x -->\nold\nRun time: 3 s\n<!-- /figure -->\nb\n"
    same = replace_blocks(text, {"x": "old\nRun time: 9 s"}, "doc")
    assert figures._comparable(same) == figures._comparable(text)
    other = replace_blocks(text, {"x": "new\nRun time: 3 s"}, "doc")
    assert figures._comparable(other) != figures._comparable(text)
    with pytest.raises(SystemExit, match="has no block"):
        replace_blocks(text, {"y": "z"}, "doc")


def test_figures_without_the_corpus_say_how_to_give_it(capsys, monkeypatch):
    monkeypatch.delenv("FSREG_TUNA_DIR", raising=False)
    with pytest.raises(SystemExit):
        figures.main(["--check", "--only", "table1"])
    assert "give the TUNA corpus directory" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        figures.main(["--tuna", "/x", "--only", "nothing"])
    assert "unknown figure nothing" in capsys.readouterr().err
