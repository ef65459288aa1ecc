"""The reference-game format, its reader and tokenisation: any repeated-reference corpus as games of messages.

This module owns what a repeated-reference corpus *is* to fsreg (docs/reference-games.md):
a UTF-8 file, CSV with a header or JSON Lines with the same keys, one row per message, in
the order said within each game, with the columns

``game``        the game (any non-empty string);
``trial``       the trial's index in its game, a whole number >= 1 (one referent per trial,
                trials in increasing order within a game);
``referent``    what the trial is about (a non-empty string);
``player``      who wrote the message (a non-empty string);
``role``        ``describer`` or ``matcher`` (one describer per trial; it may change between trials);
``time``        seconds (optional: empty for every row of a game means the game has no times;
                within a game, never earlier than the row before);
``text``        the message;
``repetition``  optional: the how-many-th reference to its referent the trial is (else counted).

A file is JSON Lines when its name ends in ``.jsonl``, ``.ndjson`` or ``.json``, CSV otherwise.
Anything wrong is one :class:`ReferenceGamesError` naming the file, the row (its line in the
file; a CSV header is row 1) and the column.  Games are returned sorted by their id (which
fixes the cross-validation's folds), each message's text turned into content words by a
:class:`Tokeniser`.  :mod:`.tangrams` is one adapter onto this format.
"""

from __future__ import annotations

import csv
import json
import math
import re
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Mapping, Optional, Sequence, TextIO, Union

from ..core.io.input_file import MAX_CORPUS_BYTES, InputFileError, json_lines, open_text

COLUMNS = ("game", "trial", "referent", "player", "role", "time", "text", "repetition")
REQUIRED = ("game", "trial", "referent", "player", "role", "text")
ROLES = ("describer", "matcher")
JSON_SUFFIXES = (".jsonl", ".ndjson", ".json")

#: An English stop list (function words, auxiliaries, pronouns -- "one" too, as in "this one" --
#: and chat fillers), written for fsreg: what is left are the content words.  Tokens are
#: lower-case runs of letters, with an apostrophe inside (``he's``); digits and punctuation separate tokens.
STOP_WORDS = frozenset("""
a about above across after again against all almost also am an and another any anything are
around as at b be because been before being below beside besides between both but by c can
could d did do does doing done don't down during e each either else etc even ever every f for
from further g get gets getting go going got h had has have having he he'd he'll he's her here
hers herself him himself his how i i'd i'll i'm i've if in into is isn't it it's its itself j
just k l let's m maybe me might more most much must my myself n no nor not now o of off ok
okay on once one one's ones only onto or other our ours ourselves out over own p perhaps q r really s same
she she'd she'll she's should so some something such t than that that's the their theirs them
themselves then there there's these they they'd they'll they're they've thing things this
those though through to too u under until up upon us v very w was wasn't we we'd we'll we're
we've were weren't what what's when where where's which while who who's whom whose why will
with within without would x y yeah yes yep you you'd you'll you're you've your yours yourself
z hmm hm um uh oh lol haha ah ahh ooh wow sure got gotcha alright right's thanks thank
""".split())
_TOKEN = re.compile(r"[a-z]+(?:'[a-z]+)*")


class ReferenceGamesError(ValueError):
    """The corpus or a setting is unusable; the message names the file, row and column, or the option."""


# ------------------------------------------------------------------ tokenisation
@dataclass(frozen=True)
class Tokeniser:
    """How a message becomes content words: lower-case letter runs, optionally stop-listed and stemmed.

    ``stem`` uses the Snowball English (Porter 2) stemmer of the ``snowballstemmer`` package
    (pure Python; pinned with the research tools).
    """

    name: str
    stop: bool = True
    stem: bool = False
    description: str = ""

    def __call__(self, text: str) -> tuple[str, ...]:
        words = _TOKEN.findall(text.lower().replace("\u2019", "'"))
        if self.stop:
            words = [w for w in words if w not in STOP_WORDS]
        if self.stem:
            words = _stemmer().stemWords(words)
        return tuple(words)


_STEMMER = None


def _stemmer():
    global _STEMMER
    if _STEMMER is None:
        try:
            import snowballstemmer
        except ImportError:  # pragma: no cover - pinned in the requirements
            raise ReferenceGamesError("tokenisation 'stems' needs the snowballstemmer package (pip install "
                                      "snowballstemmer)") from None
        _STEMMER = snowballstemmer.stemmer("english")
    return _STEMMER


TOKENISATIONS = {
    "content": Tokeniser("content", True, False, "lower-case words minus the stop list"),
    "stems": Tokeniser("stems", True, True, "content words reduced to their Snowball (Porter 2) stems"),
    "all": Tokeniser("all", False, False, "every lower-case word, stop words included"),
}


def tokenisation(name: Union[str, Tokeniser]) -> Tokeniser:
    """Return the tokeniser called ``name`` (or ``name`` itself)."""
    if isinstance(name, Tokeniser):
        return name
    if name not in TOKENISATIONS:
        raise ReferenceGamesError(f"unknown tokenisation '{name}' (known: {', '.join(TOKENISATIONS)})")
    return TOKENISATIONS[name]


# ------------------------------------------------------------------ games
@dataclass(frozen=True)
class Row:
    """One message as the format gives it (``line``: its row in the file, for error messages)."""

    game: str
    trial: int
    referent: str
    player: str
    role: str
    time: Optional[float]
    text: str
    repetition: Optional[int] = None
    line: int = 0


@dataclass(frozen=True)
class Message:
    """One message: its time, trial, repetition, role, player, referent and content words.

    ``time``: seconds from the game's first message; the message's index when the game has no times.
    """

    time: float
    trial: int
    repetition: int
    role: str
    referent: str
    words: tuple[str, ...]
    player: str = ""


@dataclass(frozen=True)
class Game:
    """One game's messages in the order said; ``timed``: whether its rows gave times."""

    gameid: str
    messages: tuple[Message, ...]
    timed: bool = True


def load_games(path: Union[str, Path], tokeniser: Union[str, Tokeniser] = "content") -> list[Game]:
    """Read a reference-game file (CSV or JSON Lines) into games sorted by id."""
    source = Path(path)
    return games_from_rows(read_rows(source), tokeniser, source)


def read_rows(path: Union[str, Path]) -> list[Row]:
    """Read and check every row of a reference-game file, each cell by itself (see :func:`games_from_rows`)."""
    source = Path(path)
    if source.suffix.lower() in JSON_SUFFIXES:
        with corpus_errors(source):
            rows = [_row(_message(record, line, source), line, source)
                    for line, record in json_lines(source, MAX_CORPUS_BYTES)]
    else:
        with corpus_text(source) as handle:
            rows = [_row(record, line, source) for line, record in _csv_records(handle, source)]
    if not rows:
        raise ReferenceGamesError(f"{source}: no messages")
    return rows


@contextmanager
def corpus_errors(source: Path, error: type = ReferenceGamesError) -> Iterator[None]:
    """Turn a fault of reading a corpus file (:mod:`fsreg_ros.core.io.input_file`) into one ``error``."""
    try:
        yield
    except InputFileError as err:
        raise error(str(err)) from None


@contextmanager
def corpus_text(source: Path, error: type = ReferenceGamesError) -> Iterator[TextIO]:
    """Open a corpus file as text (:mod:`fsreg_ros.core.io.input_file`); any reading fault is one ``error``."""
    try:
        with corpus_errors(source, error), open_text(source, MAX_CORPUS_BYTES) as handle:
            yield handle
    except UnicodeDecodeError as err:
        raise error(f"{source}: not UTF-8 text ({err.reason})") from None
    except csv.Error as err:
        raise error(f"{source}: not CSV ({err})") from None


def _csv_records(handle, source: Path) -> Iterator[tuple[int, Mapping]]:
    reader = csv.DictReader(handle)
    header = reader.fieldnames or ()
    for column in REQUIRED:
        if column not in header:
            raise ReferenceGamesError(f"{source}: row 1, column {column}: missing from the header (the format needs "
                                      f"{', '.join(REQUIRED)}; time and repetition are optional)")
    for record in reader:
        yield reader.line_num, record


def _message(record: object, line: int, source: Path) -> Mapping:
    """Return a JSON Lines record if it is a message (an object), else refuse it naming its row."""
    if not isinstance(record, dict):
        raise ReferenceGamesError(f"{source}: row {line}: not a message (a JSON object with the keys "
                                  f"{', '.join(REQUIRED)})")
    return record


def _row(record: Mapping, line: int, source: Path) -> Row:
    def where(column: str) -> str:
        return f"{source}: row {line}, column {column}"

    def name(column: str) -> str:
        value = record.get(column)
        if value is None:
            raise ReferenceGamesError(f"{where(column)}: missing")
        if isinstance(value, bool) or not isinstance(value, (str, int)):
            raise ReferenceGamesError(f"{where(column)}: must be a string, got {value!r}")
        if not str(value).strip():
            raise ReferenceGamesError(f"{where(column)}: empty")
        return str(value)

    def whole(column: str, optional: bool = False) -> Optional[int]:
        value = record.get(column)
        if optional and (value is None or value == ""):
            return None
        number = value if isinstance(value, int) and not isinstance(value, bool) else \
            int(value) if isinstance(value, str) and value.strip().isdigit() else None
        if number is None or number < 1:
            raise ReferenceGamesError(f"{where(column)}: must be a whole number >= 1, got {value!r}")
        return number

    role = name("role")
    if role not in ROLES:
        raise ReferenceGamesError(f"{where('role')}: must be describer or matcher, got {role!r}")
    text = record.get("text")
    if text is None or not isinstance(text, str):
        problem = "missing" if text is None else f"must be a string, got {text!r}"
        raise ReferenceGamesError(f"{where('text')}: {problem}")
    raw = record.get("time")
    time = None
    if raw is not None and raw != "":
        try:
            time = float(raw) if not isinstance(raw, bool) else math.nan
        except (TypeError, ValueError):
            time = math.nan
        if not math.isfinite(time):
            raise ReferenceGamesError(f"{where('time')}: must be a number of seconds (or empty), got {raw!r}")
    return Row(name("game"), whole("trial"), name("referent"), name("player"), role, time, text,  # type: ignore
               whole("repetition", optional=True), line)


def games_from_rows(rows: Iterable[Row], tokeniser: Union[str, Tokeniser] = "content",
                    source: Union[str, Path] = "<rows>", names: Optional[Mapping[str, str]] = None) -> list[Game]:
    """Check the rows of each game together and return the games, sorted by id.

    Within a game: times given for every row or none, never going back; trials in increasing
    order, one referent and at most one describer each, the describer not also a matcher of it;
    a trial's repetition the same on all its rows.  ``names`` renames columns in the error
    messages (an adapter's own column names).
    """
    tok = tokenisation(tokeniser)
    called = dict(names or {})
    by_game: dict[str, list[Row]] = {}
    for row in rows:
        by_game.setdefault(row.game, []).append(row)
    if not by_game:
        raise ReferenceGamesError(f"{source}: no messages")
    return [_game(gameid, by_game[gameid], tok, source, called) for gameid in sorted(by_game)]


def _game(gameid: str, rows: Sequence[Row], tok: Tokeniser, source: Union[str, Path],
          called: Mapping[str, str]) -> Game:
    def fail(row: Row, column: str, message: str) -> None:
        raise ReferenceGamesError(f"{source}: row {row.line}, column {called.get(column, column)}: {message}")

    timed = rows[0].time is not None
    start = rows[0].time if timed else 0.0
    trial_of: dict[int, tuple[str, Optional[int]]] = {}
    describer: dict[int, str] = {}
    matchers: dict[int, set] = {}
    seen: dict[str, int] = {}
    repetition_of: dict[int, int] = {}
    last_time, last_trial = start, 0
    messages = []
    for index, row in enumerate(rows):
        if (row.time is not None) != timed:
            fail(row, "time", f"{'empty' if row.time is None else 'given'}, but game {gameid}'s first row "
                              f"{'has a time' if timed else 'has none'} (give every row of a game a time, or none)")
        if timed and row.time < last_time:  # type: ignore[operator]
            fail(row, "time", f"{row.time:g} is earlier than the row before in game {gameid} (rows are in the order "
                              "said)")
        if row.trial < last_trial:
            fail(row, "trial", f"trial {row.trial} of game {gameid} comes after trial {last_trial} began (a trial's "
                               "rows are together, trials in increasing order)")
        if row.trial not in trial_of:
            trial_of[row.trial] = (row.referent, row.repetition)
            seen[row.referent] = seen.get(row.referent, 0) + 1
            repetition_of[row.trial] = row.repetition if row.repetition is not None else seen[row.referent]
        referent, repetition = trial_of[row.trial]
        if row.referent != referent:
            fail(row, "referent", f"trial {row.trial} of game {gameid} is about {referent!r}, this row says "
                                  f"{row.referent!r} (one referent per trial)")
        if row.repetition != repetition:
            fail(row, "repetition", f"trial {row.trial} of game {gameid} is repetition {repetition}, this row says "
                                    f"{row.repetition} (one repetition per trial)")
        if row.role == "describer":
            if describer.setdefault(row.trial, row.player) != row.player:
                fail(row, "player", f"trial {row.trial} of game {gameid} already has describer "
                                    f"{describer[row.trial]!r} (one describer per trial)")
            if row.player in matchers.get(row.trial, ()):
                fail(row, "role", f"{row.player!r} is a matcher of trial {row.trial} of game {gameid} already")
        else:
            if describer.get(row.trial) == row.player:
                fail(row, "role", f"{row.player!r} is the describer of trial {row.trial} of game {gameid}")
            matchers.setdefault(row.trial, set()).add(row.player)
        last_trial = row.trial
        time = row.time - start if timed else float(index)  # type: ignore[operator]
        last_time = row.time if timed else last_time
        messages.append(Message(time, row.trial, repetition_of[row.trial], row.role, row.referent, tok(row.text),
                                row.player))
    return Game(gameid, tuple(messages), timed)


def write_rows(path: Union[str, Path], rows: Iterable[Row]) -> Path:
    """Write rows as a reference-game file (JSON Lines if the name ends in .jsonl/.ndjson/.json, else CSV)."""
    out = Path(path)
    with out.open("w", encoding="utf-8", newline="") as handle:
        if out.suffix.lower() in JSON_SUFFIXES:
            for row in rows:
                record = {c: getattr(row, c) for c in COLUMNS}
                handle.write(json.dumps(record, ensure_ascii=False) + "\n")
        else:
            writer = csv.writer(handle)
            writer.writerow(COLUMNS)
            for row in rows:
                writer.writerow(["" if getattr(row, c) is None else getattr(row, c) for c in COLUMNS])
    return out


__all__ = ["COLUMNS", "REQUIRED", "ROLES", "ReferenceGamesError", "Tokeniser", "TOKENISATIONS", "STOP_WORDS",
           "tokenisation", "Row", "Message", "Game", "load_games", "read_rows", "games_from_rows", "write_rows"]
