"""Re-reference events of reference games: what is predicted, and each game's stream for the WM replays.

At each describer re-reference (a trial of repetition >= 2, at the trial's describer's first
message, before it is encoded) the *candidates* are the word types said about that referent
earlier in the game (by any player), and each candidate's *outcome* is whether the trial's
describer uses it anywhere in that trial.  A re-reference with no candidate is not an event.

Per candidate the arrays also keep what the baselines and regressions read: its recency
(seconds -- NaN in a game without times -- content words and references since it was last
said about the referent, the referent's own references since), how often it was said about
it, whether it was said in the referent's previous trial (``last``) and whether this trial's
describer said it about the referent before (``by_describer``).

A game's *stream* is what the replays play (:mod:`.reuse_replay`), in order:
``("episode", time, referent, (), None, "", present)`` at each trial's first message,
``("ask", time, referent, candidates, first, describer, present)`` at each event (``first``:
the index of its first candidate in the arrays), ``("say", time, referent, words, cause,
player, present)`` for each message (``cause``: ``speaker`` for the describer, ``rr`` for a
matcher, as the robot hears a human).  ``present`` lists the players present in the trial:
a player is present from the trial of their first message in the game on (the format says
when a player joins by their first message; nothing says that one left).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .reference_games import Game

#: Cause of an encoding, by role: the describer speaks, a matcher's words are heard (as RR's).
CAUSES = {"describer": "speaker", "matcher": "rr"}


@dataclass
class Events:
    """Every game's event stream and the candidates of all its re-references, as flat arrays (module docstring)."""

    games: list[str]
    streams: list[list[tuple]]
    words: list[str]
    game: np.ndarray
    event: np.ndarray
    repetition: np.ndarray
    used: np.ndarray
    seconds: np.ndarray
    words_since: np.ndarray
    references: np.ndarray
    descriptions: np.ndarray
    mentions: np.ndarray
    last: np.ndarray
    by_describer: np.ndarray
    timed: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # per game
    late: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # per game: an event's describer joined late
    descriptives: dict = field(default_factory=dict)

    @property
    def describers_from_start(self) -> bool:
        """Whether every event's describer was present from their game's first trial (player WM = group WM)."""
        return not self.late.any()

    @property
    def candidates(self) -> int:
        return len(self.used)

    @property
    def events(self) -> int:
        return int(self.event.max()) + 1 if len(self.event) else 0


def presence(game: Game) -> dict[str, int]:
    """Each player's first trial in the game (they are present from it on)."""
    first: dict[str, int] = {}
    for m in game.messages:
        first.setdefault(m.player, m.trial)
    return first


def build_events(games: Sequence[Game]) -> Events:
    """Turn games into event streams and candidate arrays (once per tokenisation; every replay reuses it)."""
    streams, words = [], []
    names = ("game", "event", "repetition", "used", "seconds", "words_since", "references", "descriptions",
             "mentions", "last", "by_describer")
    cols: dict[str, list] = {k: [] for k in names}
    desc = _Descriptives()
    event = 0
    late = np.zeros(len(games), bool)
    for g, game in enumerate(games):
        steps: list[tuple] = []
        # Per referent: word -> (time, trial, word count at the time, reference index) of its last mention.
        said: dict[str, dict[str, tuple[float, int, int, int]]] = {}
        count: dict[str, dict[str, int]] = {}
        by_player: dict[tuple[str, str], set] = {}  # (player, referent) -> words that player said about it
        trials_of: dict[str, list[int]] = {}
        spoken = 0  # content words said so far in the game
        describer_words: dict[int, set] = {}
        for m in game.messages:
            if m.role == "describer":
                describer_words.setdefault(m.trial, set()).update(m.words)
        joined = presence(game)
        opening = game.messages[0].trial
        asked: set[int] = set()
        present: tuple = ()
        for m in game.messages:
            trials = trials_of.setdefault(m.referent, [])
            if not trials or trials[-1] != m.trial:
                trials.append(m.trial)
                present = tuple(p for p, first in joined.items() if first <= m.trial)
                desc.reference(m.referent, m.trial, m.time)
                steps.append(("episode", m.time, m.referent, (), None, "", present))
            if m.role == "describer" and m.trial not in asked:
                asked.add(m.trial)
                desc.description(g, m.repetition, describer_words[m.trial], said.get(m.referent, {}))
                earlier = said.get(m.referent, {})
                if m.repetition >= 2 and earlier:
                    previous = trials[-2] if len(trials) >= 2 else None
                    used = describer_words[m.trial]
                    own = by_player.get((m.player, m.referent), set())
                    first = len(words)
                    for word, (when, trial, at, ref) in earlier.items():
                        words.append(word)
                        cols["game"].append(g)
                        cols["event"].append(event)
                        cols["repetition"].append(m.repetition)
                        cols["used"].append(word in used)
                        cols["seconds"].append(m.time - when if game.timed else np.nan)
                        cols["words_since"].append(spoken - at)
                        cols["references"].append(m.trial - trial)
                        cols["descriptions"].append(len(trials) - 1 - ref)
                        cols["mentions"].append(count[m.referent][word])
                        cols["last"].append(trial == previous)
                        cols["by_describer"].append(word in own)
                    steps.append(("ask", m.time, m.referent, tuple(earlier), first, m.player, present))
                    late[g] |= joined[m.player] != opening
                    event += 1
            steps.append(("say", m.time, m.referent, m.words, CAUSES[m.role], m.player, present))
            mine = said.setdefault(m.referent, {})
            counts = count.setdefault(m.referent, {})
            by_player.setdefault((m.player, m.referent), set()).update(m.words)
            for word in m.words:
                spoken += 1
                mine[word] = (m.time, m.trial, spoken, len(trials) - 1)  # candidates stay in first-said order
                counts[word] = counts.get(word, 0) + 1
        streams.append(steps)
        desc.game_done(game.timed)
    dtypes = {"used": bool, "last": bool, "by_describer": bool, "seconds": float}
    arrays = {k: np.asarray(v, dtype=dtypes.get(k, np.int64)) for k, v in cols.items()}
    timed = np.asarray([game.timed for game in games], dtype=bool)
    return Events([game.gameid for game in games], streams, words, timed=timed, late=late,
                  descriptives=desc.summary(), **arrays)


class _Descriptives:
    """Running counts for the corpus descriptives (see :func:`build_events`)."""

    def __init__(self) -> None:
        self.rows: list[tuple[int, int, int, int]] = []  # (game, repetition, word types, of them said earlier)
        self.gap_seconds: list[float] = []
        self.gap_references: list[int] = []
        self._seconds: list[float] = []
        self._last: dict[str, tuple[int, float]] = {}

    def reference(self, referent: str, trial: int, time: float) -> None:
        if referent in self._last:
            trial0, time0 = self._last[referent]
            self._seconds.append(time - time0)
            self.gap_references.append(trial - trial0 - 1)
        self._last[referent] = (trial, time)

    def description(self, game: int, repetition: int, used: set, earlier: Mapping[str, object]) -> None:
        self.rows.append((game, repetition, len(used), sum(1 for w in used if w in earlier)))

    def game_done(self, timed: bool) -> None:
        if timed:
            self.gap_seconds.extend(self._seconds)
        self._seconds = []
        self._last = {}

    def summary(self) -> dict:
        reps = {}
        rows = np.asarray(self.rows, dtype=np.int64).reshape(-1, 4)
        for rep in sorted(set(rows[:, 1].tolist())):
            mine = rows[rows[:, 1] == rep]
            types = int(mine[:, 2].sum())
            reps[rep] = {"descriptions": len(mine), "words_per_description": types / len(mine),
                         "share_said_earlier": (int(mine[:, 3].sum()) / types) if types else 0.0}
        gaps = np.asarray(self.gap_seconds)
        refs = np.asarray(self.gap_references)

        def quart(a: np.ndarray) -> list:
            return [float(x) for x in np.percentile(a, [25, 50, 75])] if len(a) else [0.0] * 3

        return {"by_repetition": reps, "gap_seconds_quartiles": quart(gaps),
                "gap_references_quartiles": quart(refs), "gaps": len(refs),
                "_gap_seconds": gaps, "_gap_references": refs, "_descriptions": rows}


__all__ = ["CAUSES", "Events", "build_events", "presence"]
