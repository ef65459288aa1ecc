"""Forgetting models against people's repeated reference: the tangram games of Hawkins, Frank & Goodman.

Data: R. D. Hawkins, M. C. Frank and N. D. Goodman (2020), "Characterizing the dynamics of
learning in repeated reference games", *Cognitive Science* 44(6), e12845 (arXiv 1912.07199);
the per-message file ``tangramsSequential.csv`` of their repository (hawkrobe/tangrams). 83
online games: a director describes 12 tangram figures to a matcher, 6 repetitions in shuffled
order, both type free text, every message with a millisecond timestamp and the intended
tangram.  The source carries no licence file, so fsreg reads it from a path the user gives and
never copies it (``fsreg-eval tangrams PATH``; :func:`evaluate` as a library call).

**Replay.**  Every game is played through the core's own working memory: one
:class:`~fsreg_ros.core.memory.WMBuffer` per game, managed by a
:class:`~fsreg_ros.core.forgetting.wm_manager.WMManager` under a
:class:`~fsreg_ros.core.forgetting.policies.ForgettingPolicy` (the same code the simulator and the
node graph run; nothing here re-implements a rule).  Each content word type (after
tokenisation, :class:`Tokeniser`) is a property of the message's tangram, an entity; the
messages of both players are encoded in word order (a repeated word is a refresh); the
message time, in seconds from the game's first message, is the clock (the manager catches up
to it before every message, as the simulator does before every turn).

**Events.**  At each director re-reference (a trial of repetition 2-6, at the trial's first
director message, before it is encoded) the *candidates* are the word types said about that
tangram earlier in the game (by either player), and each candidate's *outcome* is whether the
director uses it anywhere in that trial.  A re-reference with no candidate is not an event.

**Link.**  A WM model predicts a candidate's use from its WM membership at the event:
``p_in`` if the word is in the tangram's WM queue, else ``p_out``, both fitted by maximum
likelihood on the training games with add-one-half smoothing (``(k + 0.5) / (n + 1)``, so no
probability is 0 or 1).  Baselines: ``none`` (fsreg's policy: WM holds nothing, so one rate),
``no-forgetting`` (an unmanaged buffer keeps every word: again one rate), ``last-description``
(in WM iff said in the tangram's previous trial, by either player) and ``constant`` (one rate
fitted on the training games).  Recency models (``recency-seconds``, ``-words``,
``-references``, ``-descriptions``, ``-all``) are logistic regressions on log(1 + seconds since
the word was last said about the tangram), log(1 + content words said in the game since, by
either player about any tangram), log(references to any tangram since: trials, >= 1) and
log(references to this tangram since: 1 = its previous one), fitted by Newton's method with a
small ridge (numpy; penalty 1 on the weights of the standardised predictors, none on the
intercept, so a perfectly separable toy stays finite): they compare time-based and interference-based
accounts directly.

**Scoring.**  Held-out log-likelihood per candidate (natural log) under K-fold
cross-validation by game (folds from a seeded shuffle of the games): each rule's setting and
link are chosen on the training folds only, then scored on the held-out fold.  Differences
between models are paired by game; their 95 % intervals are percentile bootstraps over games
of the ratio (summed log-likelihood difference / candidates) (:func:`.stats.ratio_bootstrap_ci`).
A rule's reported setting is the one chosen on all games; a chosen value at the edge of its
grid (in any fold or overall) is flagged.

**Models** come from the core's rule list (:data:`fsreg_ros.core.forgetting.policies.RULES`) and its
settings table, so a rule added there is fitted here without a change: each rule alone over a
grid of the parameters it reads (:data:`GRIDS`; a parameter without one gets a grid from the
table's bounds), ``decay+displacement`` (the paper's both) over their product, and the
baselines.  ``similarity`` is left out (:data:`EXCLUDED`): words have no attributes, so it
forgets nothing; so is ``episodes`` until the replay begins reference episodes.  The random
victim's ``seed`` is not fitted (:data:`NOT_FITTED`).
"""

from __future__ import annotations

import csv
import multiprocessing
import re
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np

from ..core.forgetting import settings as table
from ..core.forgetting.policies import RULE_PARAMETERS, RULES, ForgettingPolicy
from ..core.io.input_file import MAX_CORPUS_BYTES, InputFileError, open_text
from ..core.memory import WMBuffer
from ..core.forgetting.wm_manager import WMManager
from .stats import METHOD, RESAMPLES, SEED, Estimate, bootstrap_ci, ratio_bootstrap_ci

#: The per-message file of the corpus (a PATH may be its directory or the file itself).
FILE = "tangramsSequential.csv"
COLUMNS = ("gameid", "msgTime", "trialNum", "repetitionNum", "role", "intendedName", "contents")
ROLES = ("director", "matcher")
#: Cause of an encoding, by role: the director speaks, the matcher's words are heard (as RR's).
CAUSES = {"director": "speaker", "matcher": "rr"}
DOMAIN = "tangrams"

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


class TangramsError(ValueError):
    """The corpus or a setting is unusable; the message names the file, line or option."""


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
            raise TangramsError("tokenisation 'stems' needs the snowballstemmer package (pip install "
                                "snowballstemmer)") from None
        _STEMMER = snowballstemmer.stemmer("english")
    return _STEMMER


TOKENISATIONS = {
    "content": Tokeniser("content", True, False, "lower-case words minus the stop list"),
    "stems": Tokeniser("stems", True, True, "content words reduced to their Snowball (Porter 2) stems"),
    "all": Tokeniser("all", False, False, "every lower-case word, stop words included"),
}


# ------------------------------------------------------------------ the corpus
@dataclass(frozen=True)
class Message:
    """One message: seconds from the game's first message, its trial, the speaker and the content words."""

    time: float
    trial: int
    repetition: int
    role: str
    tangram: str
    words: tuple[str, ...]


@dataclass(frozen=True)
class Game:
    """One game's messages in time order."""

    gameid: str
    messages: tuple[Message, ...]


def corpus_file(path: Union[str, Path]) -> Path:
    """Return the per-message CSV: ``path`` itself, or ``path/tangramsSequential.csv``."""
    path = Path(path)
    if path.is_dir():
        path = path / FILE
    if not path.exists():  # anything else that is not a regular file is refused when read (input_file)
        raise TangramsError(f"{path}: no such file (give the directory holding {FILE}, or the file)")
    return path


def load_games(path: Union[str, Path], tokeniser: Union[str, Tokeniser] = "content") -> list[Game]:
    """Read the corpus into games (sorted by game id; messages by time, then file order)."""
    tok = tokenisation(tokeniser)
    source = corpus_file(path)
    games: dict[str, list[tuple[int, int, dict]]] = {}
    try:
        with open_text(source, MAX_CORPUS_BYTES) as handle:
            reader = csv.DictReader(handle)
            missing = [c for c in COLUMNS if c not in (reader.fieldnames or ())]
            if missing:
                raise TangramsError(f"{source}: not the tangram corpus: no column {', '.join(missing)}")
            for row in reader:
                line = reader.line_num
                time = _integer(row, "msgTime", source, line)
                games.setdefault(row["gameid"], []).append((time, line, row))
    except InputFileError as err:
        raise TangramsError(str(err)) from None
    except UnicodeDecodeError as err:
        raise TangramsError(f"{source}: not UTF-8 text ({err.reason})") from None
    except csv.Error as err:
        raise TangramsError(f"{source}: not CSV ({err})") from None
    if not games:
        raise TangramsError(f"{source}: no messages")
    out = []
    for gameid in sorted(games):
        rows = sorted(games[gameid], key=lambda item: item[:2])
        start = rows[0][0]
        messages = []
        for time, line, row in rows:
            role = row["role"]
            if role not in ROLES:
                raise TangramsError(f"{source}:{line}: role must be director or matcher, got {role!r}")
            trial, repetition = _integer(row, "trialNum", source, line), _integer(row, "repetitionNum", source, line)
            if trial < 1 or repetition < 1:
                raise TangramsError(f"{source}:{line}: trialNum and repetitionNum must be >= 1")
            if not row["intendedName"]:
                raise TangramsError(f"{source}:{line}: intendedName is empty")
            messages.append(Message((time - start) / 1000.0, trial, repetition, role, row["intendedName"],
                                    tok(row["contents"] or "")))
        out.append(Game(gameid, tuple(messages)))
    return out


def _integer(row: dict, column: str, source: Path, line: int) -> int:
    text = row.get(column)
    try:
        return int(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise TangramsError(f"{source}:{line}: {column} must be a whole number, got {text!r}") from None


def tokenisation(name: Union[str, Tokeniser]) -> Tokeniser:
    """Return the tokeniser called ``name`` (or ``name`` itself)."""
    if isinstance(name, Tokeniser):
        return name
    if name not in TOKENISATIONS:
        raise TangramsError(f"unknown tokenisation '{name}' (known: {', '.join(TOKENISATIONS)})")
    return TOKENISATIONS[name]


# ------------------------------------------------------------------ events
@dataclass
class Events:
    """Every game's event stream and the candidates of all its re-references, as flat arrays.

    ``streams[g]`` lists game g's steps in order: ``("say", time, tangram, words, cause)`` or
    ``("ask", time, tangram, candidates, first)``, ``first`` being the index of the query's first
    candidate in the arrays.  Per candidate: its game, query (event) number, repetition, outcome
    (``used``), and its recency: seconds, content words and references since it was last said
    about the tangram, references to the tangram itself since (``descriptions``: 1 = its previous
    reference), how often it was said about it, and whether it was said in the tangram's
    previous trial (``last``).
    """

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
    descriptives: dict = field(default_factory=dict)

    @property
    def candidates(self) -> int:
        return len(self.used)

    @property
    def events(self) -> int:
        return int(self.event.max()) + 1 if len(self.event) else 0


def build_events(games: Sequence[Game]) -> Events:
    """Turn games into event streams and candidate arrays (once per tokenisation; every replay reuses it)."""
    streams, words = [], []
    names = ("game", "event", "repetition", "used", "seconds", "words_since", "references", "descriptions",
             "mentions", "last")
    cols: dict[str, list] = {k: [] for k in names}
    desc = _Descriptives()
    event = 0
    for g, game in enumerate(games):
        steps: list[tuple] = []
        # Per tangram: word -> (time, trial, word count at the time) of its last mention, and mentions.
        said: dict[str, dict[str, tuple[float, int, int, int]]] = {}
        count: dict[str, dict[str, int]] = {}
        trials_of: dict[str, list[int]] = {}
        spoken = 0  # content words said so far in the game
        director_words: dict[int, set] = {}
        for m in game.messages:
            if m.role == "director":
                director_words.setdefault(m.trial, set()).update(m.words)
        asked: set[int] = set()
        trial_start: dict[int, float] = {}
        for m in game.messages:
            trials = trials_of.setdefault(m.tangram, [])
            if not trials or trials[-1] != m.trial:
                trials.append(m.trial)
                trial_start[m.trial] = m.time
                desc.reference(m.tangram, m.trial, m.time)
            if m.role == "director" and m.trial not in asked:
                asked.add(m.trial)
                desc.description(g, m.repetition, director_words[m.trial], said.get(m.tangram, {}))
                earlier = said.get(m.tangram, {})
                if m.repetition >= 2 and earlier:
                    previous = trials[-2] if len(trials) >= 2 else None
                    used = director_words[m.trial]
                    first = len(words)
                    for word, (when, trial, at, ref) in earlier.items():
                        words.append(word)
                        cols["game"].append(g)
                        cols["event"].append(event)
                        cols["repetition"].append(m.repetition)
                        cols["used"].append(word in used)
                        cols["seconds"].append(m.time - when)
                        cols["words_since"].append(spoken - at)
                        cols["references"].append(m.trial - trial)
                        cols["descriptions"].append(len(trials) - 1 - ref)
                        cols["mentions"].append(count[m.tangram][word])
                        cols["last"].append(trial == previous)
                    steps.append(("ask", m.time, m.tangram, tuple(earlier), first))
                    event += 1
            steps.append(("say", m.time, m.tangram, m.words, CAUSES[m.role]))
            mine = said.setdefault(m.tangram, {})
            counts = count.setdefault(m.tangram, {})
            for word in m.words:
                spoken += 1
                mine[word] = (m.time, m.trial, spoken, len(trials) - 1)  # candidates stay in first-said order
                counts[word] = counts.get(word, 0) + 1
        streams.append(steps)
        desc.game_done()
    dtypes = {"used": bool, "last": bool, "seconds": float}
    arrays = {k: np.asarray(v, dtype=dtypes.get(k, np.int64)) for k, v in cols.items()}
    return Events([game.gameid for game in games], streams, words, descriptives=desc.summary(), **arrays)


class _Descriptives:
    """Running counts for the corpus descriptives (see :func:`build_events`)."""

    def __init__(self) -> None:
        self.rows: list[tuple[int, int, int, int]] = []  # (game, repetition, word types, of them said earlier)
        self.gap_seconds: list[float] = []
        self.gap_references: list[int] = []
        self._last: dict[str, tuple[int, float]] = {}
        self._order: list[int] = []

    def reference(self, tangram: str, trial: int, time: float) -> None:
        self._order.append(trial)
        if tangram in self._last:
            trial0, time0 = self._last[tangram]
            self.gap_seconds.append(time - time0)
            self.gap_references.append(trial - trial0 - 1)
        self._last[tangram] = (trial, time)

    def description(self, game: int, repetition: int, used: set, earlier: Mapping[str, object]) -> None:
        self.rows.append((game, repetition, len(used), sum(1 for w in used if w in earlier)))

    def game_done(self) -> None:
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
        quart = (lambda a: [float(x) for x in np.percentile(a, [25, 50, 75])]) if len(gaps) else (lambda a: [0.0] * 3)
        return {"by_repetition": reps, "gap_seconds_quartiles": quart(gaps),
                "gap_references_quartiles": quart(refs), "gaps": len(gaps),
                "_gap_seconds": gaps, "_gap_references": refs, "_descriptions": rows}


# ------------------------------------------------------------------ models
#: Grids of the core's parameters (wide enough that the fitted values lie inside them; the
#: report flags any that does not).  A parameter not listed gets :func:`default_grid`.
GRIDS: dict[str, tuple] = {
    "decay_period": (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 240.0,
                     360.0, 480.0, 720.0, 1200.0, 2400.0),
    "capacity": (1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 15, 20, 25, 30, 40, 60, 100),
    "global_capacity": (2, 4, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024),
    "shared_capacity": (2, 4, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024),
    # ACT-R base-level activation (when the core has it): d, and tau, with which one encoding
    # stays exp(-tau / d) seconds (1 s to 6 h at d = 0.8).
    "activation_decay": (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.99),
    "activation_threshold": (-10.0, -9.0, -8.0, -7.0, -6.0, -5.0, -4.0, -3.0, -2.0, -1.0, 0.0),
}
#: Parameters held at their table value, not fitted: they are no property of forgetting.
NOT_FITTED = {"seed": "the random victim's seed (its fallback, 0)"}
#: Rules not fitted, and why.
EXCLUDED = {"similarity": "words have no attributes, so it forgets nothing (it is no-forgetting)",
            "episodes": "the replay begins no reference episodes yet, so it forgets nothing (it is no-forgetting)"}
#: Rule combinations fitted beside the single rules (the paper's both).
COMBINATIONS = (("decay", "displacement"),)
#: A combination's grid takes at most this many values of each parameter (ends kept).
COMBINED_VALUES = 8
BASELINES = ("none", "no-forgetting", "last-description", "constant")
RECENCY = {"recency-seconds": ("seconds",), "recency-words": ("words",), "recency-references": ("references",),
           "recency-descriptions": ("descriptions",), "recency-all": ("seconds", "words", "references", "descriptions")}
FOLDS = 10
#: Differences reported beside those from the best model and from ``constant``: the paper's
#: rules against each other and against the referent's last description.
PAIRS = (("displacement", "decay"), ("decay+displacement", "displacement"), ("decay+displacement", "decay"),
         ("last-description", "decay+displacement"), ("last-description", "displacement"))
#: The paper's settings (Williams et al. 2020, Table 1), reported beside the fitted ones.
PAPER = {"decay_period": 10.0, "capacity": 2}


def default_grid(name: str, values: int = 12) -> tuple:
    """Return a grid for a parameter of the settings table without one in :data:`GRIDS`: from its bounds.

    Log-spaced when the bounds are positive and span two decades or more (capped at 1e4 times
    the lower bound), else evenly spaced; whole numbers for an ``int`` parameter.
    """
    row = table.setting(name)
    low, high = float(row.low), float(row.high)  # type: ignore[arg-type]
    if low > 0 and high / low >= 100:
        grid = np.geomspace(low, min(high, low * 1e4), values)
    else:
        grid = np.linspace(low, high, values)
    if row.kind is int:
        return tuple(dict.fromkeys(int(round(v)) for v in grid))
    return tuple(float(f"{v:.4g}") for v in grid)


def fitted_parameters(rules: Sequence[str]) -> list[str]:
    """Return the parameters a policy's rules read that are fitted (all but :data:`NOT_FITTED`)."""
    names = []
    for rule in rules:
        for param in RULE_PARAMETERS[rule]:
            if param not in names and param not in NOT_FITTED:
                names.append(param)
    return names


@dataclass(frozen=True)
class Model:
    """A model of reuse: a forgetting policy over its grid, a baseline, or a recency regression."""

    name: str
    kind: str  # "wm" | "baseline" | "recency"
    settings: tuple = ()  # wm: one dict per grid point (policy + parameters)
    parameters: tuple = ()  # wm: the fitted parameter names


def wm_models(grids: Optional[Mapping[str, Sequence]] = None) -> list[Model]:
    """Every WM model: each rule of the core alone, then :data:`COMBINATIONS`; grids from ``grids``/:data:`GRIDS`."""
    grids = {**GRIDS, **(grids or {})}
    policies = [(rule,) for rule in RULES if rule not in EXCLUDED]
    policies += [combo for combo in COMBINATIONS if all(rule in RULES for rule in combo)]
    models = []
    for rules in policies:
        params = fitted_parameters(rules)
        axes = []
        for param in params:
            grid = tuple(grids[param]) if param in grids else default_grid(param)
            if len(rules) > 1 and len(grid) > COMBINED_VALUES:
                keep = np.unique(np.round(np.linspace(0, len(grid) - 1, COMBINED_VALUES)).astype(int))
                grid = tuple(grid[i] for i in keep)
            axes.append(grid)
        settings = tuple({"policy": "+".join(rules), **dict(zip(params, values))} for values in product(*axes))
        models.append(Model("+".join(rules), "wm", settings, tuple(params)))
    return models


def policy_of(setting: Mapping[str, object]) -> ForgettingPolicy:
    """Return the core's policy for a grid point (validated by the core)."""
    return ForgettingPolicy.from_settings(dict(setting))


# ------------------------------------------------------------------ replay
def replay(stream: Sequence[tuple], policy: Optional[ForgettingPolicy], out: np.ndarray) -> None:
    """Play one game's stream through a WM buffer; write each candidate's WM membership into ``out``.

    ``policy`` None: an unmanaged buffer, which keeps everything (no forgetting).
    """
    buffer = WMBuffer(DOMAIN)
    manager = None
    if policy is not None:
        manager = WMManager()
        manager.manage(buffer, policy, 0.0)
    # Rules the buffer enforces at each encoding need no clock: the manager is asked to catch
    # up only for the others (decay, the shared pool, and any rule this module does not know).
    clocked = manager is not None and bool(set(policy.rules) - ENCODING_RULES)  # type: ignore[union-attr]
    for turn, step in enumerate(stream):
        kind, time, tangram, words, extra = step
        if clocked:
            manager.advance(time)  # type: ignore[union-attr]
        if kind == "ask":
            held = buffer.queue(tangram)
            if held:
                held = set(held)
                for i, word in enumerate(words):
                    out[extra + i] = word in held
        else:
            buffer.encode(tangram, words, extra, time, turn)


#: Rules enforced by the buffer after each encoding event (:class:`~fsreg_ros.core.memory.Limits`),
#: which the WM Manager's clock never triggers.
ENCODING_RULES = frozenset(("displacement", "displacement-lfu", "displacement-random", "similarity", "global-capacity"))
_SHARED: dict = {}


def _replay_setting(index: int) -> np.ndarray:
    events, settings = _SHARED["events"], _SHARED["settings"]
    setting = settings[index]
    policy = None if setting is None else policy_of(setting)
    out = np.zeros(events.candidates, dtype=bool)
    for stream in events.streams:
        replay(stream, policy, out)
    return np.packbits(out)


def memberships(events: Events, settings: Sequence[Optional[Mapping]], jobs: int = 1) -> np.ndarray:
    """WM membership of every candidate under each setting (rows), replaying every game; ``jobs`` processes."""
    _SHARED.update(events=events, settings=list(settings))
    try:
        if jobs <= 1 or len(settings) < 2:
            packed = [_replay_setting(i) for i in range(len(settings))]
        else:
            with multiprocessing.get_context("fork").Pool(jobs) as pool:
                packed = pool.map(_replay_setting, range(len(settings)), chunksize=max(1, len(settings) // (8 * jobs)))
    finally:
        _SHARED.clear()
    if not packed:
        return np.zeros((0, events.candidates), dtype=bool)
    return np.unpackbits(np.stack(packed), axis=1, count=events.candidates).astype(bool)


# ------------------------------------------------------------------ scoring
def folds_of(games: int, folds: int, seed: int = SEED) -> np.ndarray:
    """Fold number of each game: a seeded shuffle dealt round-robin into ``folds`` folds."""
    order = np.random.default_rng(seed).permutation(games)
    fold = np.empty(games, dtype=np.int64)
    fold[order] = np.arange(games) % folds
    return fold


def _smoothed(k: np.ndarray, n: np.ndarray) -> np.ndarray:
    return (k + 0.5) / (n + 1.0)


def _binary_ll(k: np.ndarray, n: np.ndarray, p: np.ndarray) -> np.ndarray:
    return k * np.log(p) + (n - k) * np.log1p(-p)


@dataclass
class Fit:
    """One model's cross-validated result.

    ``game_ll``: held-out log-likelihood summed over each game's candidates; ``predicted``:
    each candidate's held-out probability of use; ``setting``: fitted on all games (with the
    link's parameters); ``fold_settings``: chosen on each fold's training games; ``edge``: the
    parameters whose chosen value (in any fold or overall) sits on the edge of their grid.
    """

    name: str
    kind: str
    game_ll: np.ndarray
    predicted: np.ndarray
    setting: dict
    fold_settings: list = field(default_factory=list)
    edge: list = field(default_factory=list)
    grid: dict = field(default_factory=dict)
    in_wm: Optional[float] = None  # share of candidates in WM under the setting fitted on all games

    def heldout_ll(self, candidates: int) -> float:
        return float(self.game_ll.sum() / candidates)


def fit_membership(name: str, kind: str, member: np.ndarray, events: Events, fold: np.ndarray,
                   settings: Sequence[dict] = ({},), parameters: Sequence[str] = ()) -> Fit:
    """Cross-validate a membership model: ``member`` is (settings x candidates); pick on training games only."""
    games = len(events.games)
    member = np.atleast_2d(member)
    y = events.used
    # Per setting and game: candidates in WM, of them used; candidates out, of them used.
    counts = np.zeros((len(member), games, 4))
    for s, row in enumerate(member):
        counts[s, :, 0] = np.bincount(events.game, weights=row, minlength=games)
        counts[s, :, 1] = np.bincount(events.game, weights=row & y, minlength=games)
        counts[s, :, 2] = np.bincount(events.game, weights=~row, minlength=games)
        counts[s, :, 3] = np.bincount(events.game, weights=~row & y, minlength=games)
    game_ll = np.zeros(games)
    predicted = np.zeros(events.candidates)
    chosen = []
    total = counts.sum(axis=1)  # settings x 4
    for f in range(int(fold.max()) + 1):
        held = fold == f
        train = total - counts[:, held].sum(axis=1)
        best, p_in, p_out = _choose(train)
        chosen.append(best)
        c = counts[best, held]
        game_ll[held] = _binary_ll(c[:, 1], c[:, 0], p_in) + _binary_ll(c[:, 3], c[:, 2], p_out)
        rows = held[events.game]
        predicted[rows] = np.where(member[best, rows], p_in, p_out)
    best, p_in, p_out = _choose(total)
    setting = {**settings[best], "p_in": float(p_in), "p_out": float(p_out)}
    grid = {p: sorted({s[p] for s in settings}) for p in parameters}
    edge = []
    for p in parameters:
        values = grid[p]
        picked = [settings[i][p] for i in chosen + [best]]
        if len(values) > 1 and any(v in (values[0], values[-1]) for v in picked):
            edge.append(p)
    in_wm = float(member[best].mean()) if kind == "wm" else None
    return Fit(name, kind, game_ll, predicted, setting, [settings[i] for i in chosen], edge, grid, in_wm)


def _choose(train: np.ndarray) -> tuple[int, float, float]:
    """Return the setting (row) of the best training log-likelihood (first of equals) and its link."""
    p_in = _smoothed(train[:, 1], train[:, 0])
    p_out = _smoothed(train[:, 3], train[:, 2])
    ll = _binary_ll(train[:, 1], train[:, 0], p_in) + _binary_ll(train[:, 3], train[:, 2], p_out)
    best = int(np.argmax(np.round(ll, 9)))
    return best, float(p_in[best]), float(p_out[best])


def recency_features(events: Events, names: Sequence[str]) -> np.ndarray:
    """Return the recency predictors: log1p(seconds), log1p(words since), log(references), log(descriptions)."""
    columns = {"seconds": np.log1p(np.maximum(events.seconds, 0.0)),
               "words": np.log1p(events.words_since.astype(float)),
               "references": np.log(np.maximum(events.references, 1).astype(float)),
               "descriptions": np.log(np.maximum(events.descriptions, 1).astype(float))}
    return np.column_stack([columns[n] for n in names])


def logistic_fit(x: np.ndarray, y: np.ndarray, ridge: float = 1.0, steps: int = 50) -> np.ndarray:
    """Logistic regression by Newton's method: returns (intercept, weights...) on ``x`` as given."""
    design = np.column_stack([np.ones(len(x)), x])
    w = np.zeros(design.shape[1])
    penalty = np.full(design.shape[1], ridge)
    penalty[0] = 0.0
    for _ in range(steps):
        p = 1.0 / (1.0 + np.exp(-design @ w))
        grad = design.T @ (y - p) - penalty * w
        hess = (design * (p * (1 - p))[:, None]).T @ design + np.diag(penalty)
        step = np.linalg.solve(hess, grad)
        w += step
        if np.max(np.abs(step)) < 1e-10:
            break
    return w


def _logistic_predict(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    p = 1.0 / (1.0 + np.exp(-(w[0] + x @ w[1:])))
    return np.clip(p, 1e-12, 1 - 1e-12)


def fit_recency(name: str, events: Events, fold: np.ndarray) -> Fit:
    """Cross-validate a logistic regression on recency predictors (standardised on the training games)."""
    names = RECENCY[name]
    x = recency_features(events, names)
    y = events.used.astype(float)
    predicted = np.zeros(events.candidates)
    fold_settings = []
    for f in range(int(fold.max()) + 1):
        held = (fold == f)[events.game]
        mean, std = x[~held].mean(axis=0), x[~held].std(axis=0) + 1e-12
        w = logistic_fit((x[~held] - mean) / std, y[~held])
        predicted[held] = _logistic_predict((x[held] - mean) / std, w)
        fold_settings.append(_coefficients(names, w, mean, std))
    ll = np.where(events.used, np.log(predicted), np.log1p(-predicted))
    game_ll = np.bincount(events.game, weights=ll, minlength=len(events.games))
    mean, std = x.mean(axis=0), x.std(axis=0) + 1e-12
    setting = _coefficients(names, logistic_fit((x - mean) / std, y), mean, std)
    return Fit(name, "recency", game_ll, predicted, setting, fold_settings)


def _coefficients(names: Sequence[str], w: np.ndarray, mean: np.ndarray, std: np.ndarray) -> dict:
    """Coefficients on the unstandardised predictors (log scale): intercept and one per predictor."""
    slopes = w[1:] / std
    return {"intercept": float(w[0] - (slopes * mean).sum()),
            **{f"log_{n}": float(s) for n, s in zip(names, slopes)}}


# ------------------------------------------------------------------ the evaluation
@dataclass
class Evaluation:
    """Everything ``fsreg-eval tangrams`` reports (:meth:`to_json` is its ``--json``)."""

    tokenisation: str
    folds: int
    events: Events
    fits: dict
    differences: list
    best: str

    @property
    def games(self) -> int:
        return len(self.events.games)

    def heldout(self, name: str) -> float:
        return self.fits[name].heldout_ll(self.events.candidates)

    def to_json(self) -> dict:
        d = self.events.descriptives
        models = {}
        for name, fit in self.fits.items():
            entry = {"kind": fit.kind, "heldout_ll": self.heldout(name), "setting": fit.setting}
            if fit.kind == "wm":
                entry.update(grid=fit.grid, at_grid_edge=fit.edge, fold_settings=fit.fold_settings, in_wm=fit.in_wm)
            models[name] = entry
        return {
            "games": self.games, "events": self.events.events, "candidates": self.events.candidates,
            "reused": int(self.events.used.sum()), "tokenisation": self.tokenisation, "folds": self.folds,
            "descriptives": {k: v for k, v in d.items() if not k.startswith("_")},
            "models": models, "best": self.best, "differences": self.differences,
            "intervals": METHOD.replace("CI over games", "CI over games of the ratio (summed difference / candidates)"),
        }


def evaluate(source: Union[str, Path, Sequence[Game]], tokeniser: Union[str, Tokeniser] = "content",
             folds: int = FOLDS, grids: Optional[Mapping[str, Sequence]] = None, jobs: int = 1,
             resamples: int = RESAMPLES) -> Evaluation:
    """Fit every model to people's reuse in the tangram games (a corpus path, or games already loaded)."""
    tok = tokenisation(tokeniser)
    games = load_games(source, tok) if isinstance(source, (str, Path)) else list(source)
    events = build_events(games)
    if events.candidates == 0:
        raise TangramsError("no director re-reference with an earlier word: nothing to fit")
    if not 2 <= folds <= len(games):
        raise TangramsError(f"folds must be in [2, {len(games)}] (the number of games), got {folds}")
    fold = folds_of(len(games), folds)
    models = wm_models(grids)
    settings: list[Optional[dict]] = [{"policy": "none"}, None]  # none, no-forgetting
    for model in models:
        settings.extend(model.settings)
    member = memberships(events, settings, jobs)
    fits: dict[str, Fit] = {}
    row = 2
    for model in models:
        span = member[row:row + len(model.settings)]
        fits[model.name] = fit_membership(model.name, "wm", span, events, fold, model.settings, model.parameters)
        row += len(model.settings)
    fits["none"] = fit_membership("none", "wm", member[0], events, fold, ({"policy": "none"},))
    fits["no-forgetting"] = fit_membership("no-forgetting", "baseline", member[1], events, fold)
    fits["last-description"] = fit_membership("last-description", "baseline", events.last, events, fold)
    fits["constant"] = fit_membership("constant", "baseline", np.zeros(events.candidates, bool), events, fold)
    for name in RECENCY:
        fits[name] = fit_recency(name, events, fold)
    n = np.bincount(events.game, minlength=len(games)).astype(float)
    best = max(fits, key=lambda name: fits[name].game_ll.sum())
    differences = []
    pairs = [(a, b) for a, b in PAIRS if a in fits and b in fits]
    for name, reference in pairs:
        est = ratio_bootstrap_ci(fits[name].game_ll - fits[reference].game_ll, n, resamples)
        differences.append({"a": name, "b": reference, "mean": est.mean, "ci": [est.low, est.high]})
    for reference in dict.fromkeys((best, "constant")):
        for name, fit in fits.items():
            if name == reference or (name, reference) in pairs:
                continue
            est = ratio_bootstrap_ci(fit.game_ll - fits[reference].game_ll, n, resamples)
            differences.append({"a": name, "b": reference, "mean": est.mean, "ci": [est.low, est.high]})
    return Evaluation(tok.name, folds, events, fits, differences, best)


# ------------------------------------------------------------------ a small example
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


# ------------------------------------------------------------------ report
def report(result: Evaluation) -> list[str]:
    """Return the printed report: descriptives, every model's held-out fit, the differences."""
    e, d = result.events, result.events.descriptives
    described = TOKENISATIONS[result.tokenisation].description if result.tokenisation in TOKENISATIONS else ""
    lines = [f"tangram games (Hawkins, Frank & Goodman 2020): {result.games} games, {e.events} director "
             f"re-references, {e.candidates} candidate words ({int(e.used.sum())} reused); tokenisation "
             f"'{result.tokenisation}' ({described})",
             "",
             "repetition  descriptions  content words per description  share said earlier  reuse of earlier words"]
    for rep, row in d["by_repetition"].items():
        reuse = e.used[e.repetition == rep].mean() if (e.repetition == rep).any() else float("nan")
        earlier = f"{row['share_said_earlier']:.3f}" if rep > 1 else "-"
        reused = f"{reuse:.3f}" if rep > 1 else "-"
        lines.append(f"{rep:>10}  {row['descriptions']:>12}  {row['words_per_description']:>28.2f}  "
                     f"{earlier:>19}  {reused:>22}")
    qs, qr = d["gap_seconds_quartiles"], d["gap_references_quartiles"]
    lines += [f"gaps between references to a tangram ({d['gaps']}): {qs[1]:.0f} s (quartiles {qs[0]:.0f}-{qs[2]:.0f}),"
              f" {qr[1]:.0f} intervening references (quartiles {qr[0]:.0f}-{qr[2]:.0f})", ""]
    n = e.candidates
    width = max(len(name) for name in result.fits)
    lines.append(f"{'model':{width}}  {'held-out LL':>11}  {'vs constant [95% CI]':>26}  setting (fitted on all games)")
    ordered = sorted(result.fits.values(), key=lambda fit: -fit.game_ll.sum())
    for fit in ordered:
        diff = next((x for x in result.differences if x["a"] == fit.name and x["b"] == "constant"), None)
        text = "" if diff is None else f"{diff['mean']:+.4f} [{diff['ci'][0]:+.4f}, {diff['ci'][1]:+.4f}]"
        lines.append(f"{fit.name:{width}}  {fit.game_ll.sum() / n:11.4f}  {text:>26}  {setting_text(fit)}")
    lines += ["", "the paper's rules against each other and against the last description (held-out LL per "
                  "candidate, 95% CI):"]
    for a, b in PAIRS:
        diff = next((x for x in result.differences if (x["a"], x["b"]) == (a, b)), None)
        if diff is not None:
            lines.append(f"  {a + ' - ' + b:{2 * width}}  {diff['mean']:+.4f} [{diff['ci'][0]:+.4f}, "
                         f"{diff['ci'][1]:+.4f}]")
    lines += ["", f"best: {result.best}; differences from it (held-out LL per candidate, 95% CI):"]
    for diff in result.differences:
        if diff["b"] == result.best:
            lines.append(f"  {diff['a']:{width}}  {diff['mean']:+.4f} [{diff['ci'][0]:+.4f}, {diff['ci'][1]:+.4f}]")
    edges = [fit.name for fit in result.fits.values() if fit.edge]
    lines += ["",
              f"held-out LL: mean natural-log likelihood per candidate, {result.folds}-fold cross-validation by game "
              "(settings and link chosen on the training folds); WM models: p_in if the word is in the tangram's WM "
              "queue, else p_out.",
              f"intervals: paired by game, {METHOD} of the ratio (summed difference / candidates).",
              "chosen value at a grid edge: " + (", ".join(f"{n} ({', '.join(result.fits[n].edge)})" for n in edges)
                                                 if edges else "none (every fitted value lies inside its grid)")]
    return lines


def setting_text(fit: Fit) -> str:
    s = fit.setting
    if fit.kind == "recency":
        return ", ".join(f"{k} {v:+.3f}" for k, v in s.items())
    params = [f"{table.setting(k).symbol} = {v:g}" for k, v in s.items() if k not in ("policy", "p_in", "p_out")]
    if fit.in_wm == 0.0 or fit.name in ("constant", "none"):
        link = f"rate {s['p_out']:.3f}"
    elif fit.name == "no-forgetting":
        link = f"rate {s['p_in']:.3f}"
    else:
        link = f"p_in {s['p_in']:.3f}, p_out {s['p_out']:.3f}"
    wm = f", {fit.in_wm:.0%} in WM" if fit.in_wm else ""
    return (", ".join(params) + "; " if params else "") + link + wm


__all__ = ["TangramsError", "Tokeniser", "TOKENISATIONS", "STOP_WORDS", "Message", "Game", "load_games",
           "build_events", "Events", "Model", "wm_models", "GRIDS", "EXCLUDED", "COMBINATIONS", "BASELINES",
           "RECENCY", "PAIRS", "replay", "memberships", "folds_of", "fit_membership", "fit_recency", "logistic_fit",
           "Fit",
           "Evaluation", "evaluate", "report", "default_grid", "write_example", "Estimate", "bootstrap_ci"]
