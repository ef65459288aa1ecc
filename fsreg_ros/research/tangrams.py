"""The tangram games of Hawkins, Frank & Goodman, as one adapter onto the reference-game format.

Data: R. D. Hawkins, M. C. Frank and N. D. Goodman (2020), "Characterizing the dynamics of
learning in repeated reference games", *Cognitive Science* 44(6), e12845 (arXiv 1912.07199);
the per-message file ``tangramsSequential.csv`` of their repository (hawkrobe/tangrams). 83
online games: a director describes 12 tangram figures to a matcher, 6 repetitions in shuffled
order, both type free text, every message with a millisecond timestamp and the intended
tangram.  The source carries no licence file, so fsreg reads it from a path the user gives and
never copies it (``fsreg-eval tangrams PATH``; :func:`evaluate` as a library call).

This module owns only the corpus's own file: :func:`tangram_rows` turns it into rows of the
general format (:mod:`.reference_games`): ``game`` = gameid, ``trial`` = trialNum,
``referent`` = intendedName, ``player`` and ``role`` from role (director -> describer),
``time`` = msgTime in seconds from the game's first message (messages sorted by time, then
file order), ``text`` = contents, ``repetition`` = repetitionNum.  Everything else --
events, replays, links, fits, report -- is the reference-game evaluation's
(:mod:`.reuse_events`, :mod:`.reuse_replay`, :mod:`.reuse_fit`, :mod:`.reuse_eval`), whose
names are re-exported here for the callers of the tangram evaluation.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

from .reference_games import (STOP_WORDS, TOKENISATIONS, Game, Message, ReferenceGamesError, Row, Tokeniser,
                              corpus_text, games_from_rows, tokenisation)
from .reuse_eval import Evaluation, evaluate_games, report, setting_text
from .reuse_events import Events, build_events
from .reuse_fit import Fit, fit_cells, fit_membership, fit_recency, folds_of, logistic_fit
from .reuse_models import (BASELINES, COMBINATIONS, COMBINED_VALUES, EXCLUDED, FOLDS, GRIDS, NOT_FITTED, PAIRS, PAPER,
                           RECENCY, Model, default_grid, fitted_parameters, wm_models)
from .reuse_replay import memberships, replay
from .stats import RESAMPLES, Estimate, bootstrap_ci

#: The per-message file of the corpus (a PATH may be its directory or the file itself).
FILE = "tangramsSequential.csv"
COLUMNS = ("gameid", "msgTime", "trialNum", "repetitionNum", "role", "intendedName", "contents")
ROLES = ("director", "matcher")
#: The corpus's roles in the general format.
AS_ROLE = {"director": "describer", "matcher": "matcher"}
#: The corpus's columns, by the general format's names (for error messages).
NAMES = {"game": "gameid", "trial": "trialNum", "referent": "intendedName", "player": "role", "role": "role",
         "time": "msgTime", "text": "contents", "repetition": "repetitionNum"}
TITLE = "tangram games (Hawkins, Frank & Goodman 2020)"


class TangramsError(ReferenceGamesError):
    """The corpus or a setting is unusable; the message names the file, line or option."""


def corpus_file(path: Union[str, Path]) -> Path:
    """Return the per-message CSV: ``path`` itself, or ``path/tangramsSequential.csv``."""
    path = Path(path)
    if path.is_dir():
        path = path / FILE
    if not path.exists():  # anything else that is not a regular file is refused when read (input_file)
        raise TangramsError(f"{path}: no such file (give the directory holding {FILE}, or the file)")
    return path


def tangram_rows(path: Union[str, Path]) -> list[Row]:
    """Read the corpus file into rows of the reference-game format (games by id; messages by time, then file order)."""
    source = corpus_file(path)
    games: dict[str, list[tuple[int, int, dict]]] = {}
    with corpus_text(source, TangramsError) as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or ())]
        if missing:
            raise TangramsError(f"{source}: not the tangram corpus: no column {', '.join(missing)}")
        for row in reader:
            line = reader.line_num
            time = _integer(row, "msgTime", source, line)
            games.setdefault(row["gameid"], []).append((time, line, row))
    if not games:
        raise TangramsError(f"{source}: no messages")
    out = []
    for gameid in sorted(games):
        rows = sorted(games[gameid], key=lambda item: item[:2])
        start = rows[0][0]
        for time, line, row in rows:
            role = row["role"]
            if role not in ROLES:
                raise TangramsError(f"{source}:{line}: role must be director or matcher, got {role!r}")
            trial, repetition = _integer(row, "trialNum", source, line), _integer(row, "repetitionNum", source, line)
            if trial < 1 or repetition < 1:
                raise TangramsError(f"{source}:{line}: trialNum and repetitionNum must be >= 1")
            if not row["intendedName"]:
                raise TangramsError(f"{source}:{line}: intendedName is empty")
            out.append(Row(gameid, trial, row["intendedName"], role, AS_ROLE[role], (time - start) / 1000.0,
                           row["contents"] or "", repetition, line))
    return out


def _integer(row: dict, column: str, source: Path, line: int) -> int:
    text = row.get(column)
    try:
        return int(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise TangramsError(f"{source}:{line}: {column} must be a whole number, got {text!r}") from None


def load_games(path: Union[str, Path], tokeniser: Union[str, Tokeniser] = "content") -> list[Game]:
    """Read the corpus into games (sorted by game id; messages by time, then file order)."""
    return games_from_rows(tangram_rows(path), tokeniser, corpus_file(path), NAMES)


def evaluate(source: Union[str, Path, Sequence[Game]], tokeniser: Union[str, Tokeniser] = "content",
             folds: int = FOLDS, grids: Optional[Mapping[str, Sequence]] = None, jobs: int = 1,
             resamples: int = RESAMPLES) -> Evaluation:
    """Fit every model to people's reuse in the tangram games (a corpus path, or games already loaded)."""
    tok = tokenisation(tokeniser)
    games = load_games(source, tok) if isinstance(source, (str, Path)) else list(source)
    return evaluate_games(games, tok.name, folds, grids, jobs, resamples, TITLE, "director")


#: The example corpus's descriptions: per tangram, the director's words at repetitions 1, 2, 3 ...
_EXAMPLE = {"A": ("a ghost with arms raised", "ghost arms raised", "ghost"),
            "B": ("a kneeling man holding a bowl", "kneeling man bowl", "kneeling bowl"),
            "C": ("a bunny with long ears sitting", "bunny ears", "bunny")}


def write_example(path: Union[str, Path], games: int = 4) -> Path:
    """Write a tiny hand-made corpus in the corpus's format (``games`` games, 3 tangrams x 3 repetitions).

    For demonstrations and the figures' small runs, not for conclusions.  The director
    shortens each description over the repetitions; in odd games the matcher echoes a word.
    Returns the file written (``path`` is its directory).
    """
    directory = Path(path)
    directory.mkdir(parents=True, exist_ok=True)
    out = directory / FILE
    with out.open("w", encoding="utf-8", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for g in range(games):
            time, trial = 1_500_000_000_000 + g * 10_000_000, 0
            for rep in range(3):
                order = ("A", "B", "C") if (g + rep) % 2 == 0 else ("C", "A", "B")
                for tangram in order:
                    trial += 1
                    time += 4_000 + 1_000 * ((g + trial) % 5)
                    writer.writerow((f"game{g}", time, trial, rep + 1, "director", tangram, _EXAMPLE[tangram][rep]))
                    if g % 2 and rep == 0:
                        time += 2_000
                        writer.writerow((f"game{g}", time, trial, rep + 1, "matcher", tangram,
                                         _EXAMPLE[tangram][1].split()[0] + "?"))
    return out


__all__ = ["TangramsError", "Tokeniser", "TOKENISATIONS", "STOP_WORDS", "Message", "Game", "load_games",
           "tangram_rows", "corpus_file", "build_events", "Events", "Model", "wm_models", "GRIDS", "EXCLUDED",
           "COMBINATIONS", "COMBINED_VALUES", "BASELINES", "NOT_FITTED", "PAPER", "RECENCY", "PAIRS", "replay",
           "memberships", "folds_of", "fit_cells", "fit_membership", "fit_recency", "logistic_fit", "fitted_parameters",
           "Fit", "Evaluation", "evaluate", "report", "setting_text", "default_grid", "write_example", "Estimate",
           "bootstrap_ci"]
