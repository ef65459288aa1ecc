"""Cross-validated fits of reuse models: the in/out and graded links of WM cells, and the recency regressions.

**Links.**  A WM model predicts a candidate's use from its cell at the event
(:mod:`.reuse_replay`).  The *in/out* link: ``p_in`` if the word is in the referent's WM
queue, else ``p_out``.  The *graded* link: one rate per cell (not in WM, and each strength
bin of an entry in WM).  Every rate is fitted by maximum likelihood on the training games with
add-one-half smoothing (``(k + 0.5) / (n + 1)``, so no probability is 0 or 1; a cell never
seen in training gets 0.5).

**Regressions** are logistic regressions on log(1 + seconds since the word was last said
about the referent), log(1 + content words said in the game since), log(references to any
referent since: trials, >= 1) and log(references to this referent since: 1 = its previous
one), fitted by Newton's method with a small ridge (numpy; penalty 1 on the weights of the
standardised predictors, none on the intercept, so a perfectly separable toy stays finite).

**Scoring.**  Held-out log-likelihood per candidate (natural log) under K-fold
cross-validation by game (:func:`folds_of`): each rule's setting and link are chosen on the
training folds only, then scored on the held-out fold.  A model may be left out of some
games (``games``: a rule on seconds in a game without times); it is then trained and scored
on the others only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from .reuse_events import Events
from .reuse_models import CLOCK_PREDICTORS, RECENCY
from .stats import SEED


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

    ``game_ll``: held-out log-likelihood summed over each game's candidates (0 for a game the
    model is left out of: ``games`` False); ``predicted``: each candidate's held-out probability
    of use (NaN where left out); ``setting``: fitted on all games (with the link's rates);
    ``fold_settings``: chosen on each fold's training games; ``edge``: the parameters whose
    chosen value (in any fold or overall) sits on the edge of their grid.
    """

    name: str
    kind: str  # "wm" | "baseline" | "recency"
    game_ll: np.ndarray
    predicted: np.ndarray
    setting: dict
    fold_settings: list = field(default_factory=list)
    edge: list = field(default_factory=list)
    grid: dict = field(default_factory=dict)
    in_wm: Optional[float] = None  # share of candidates in WM under the setting fitted on all games
    graded: bool = False
    games: Optional[np.ndarray] = None  # per game: scored (None: every game)
    scored: int = 0  # candidates scored

    def heldout_ll(self, candidates: Optional[int] = None) -> float:
        """Mean held-out log-likelihood per candidate scored."""
        n = self.scored or candidates
        return float(self.game_ll.sum() / n) if n else float("nan")


def _counts(cells: np.ndarray, ncells: int, events: Events) -> np.ndarray:
    """Per setting, game and cell: candidates (``[..., 0]``) and of them used (``[..., 1]``)."""
    games = len(events.games)
    index = events.game * ncells
    out = np.zeros((len(cells), games, ncells, 2))
    used = events.used.astype(float)
    for s, row in enumerate(cells):
        flat = index + row
        out[s, :, :, 0] = np.bincount(flat, minlength=games * ncells).reshape(games, ncells)
        out[s, :, :, 1] = np.bincount(flat, weights=used, minlength=games * ncells).reshape(games, ncells)
    return out


def _choose(train: np.ndarray) -> tuple[int, np.ndarray]:
    """Return the setting (row) of the best training log-likelihood (first of equals) and its cells' rates."""
    p = _smoothed(train[:, :, 1], train[:, :, 0])
    ll = _binary_ll(train[:, :, 1], train[:, :, 0], p).sum(axis=1)
    best = int(np.argmax(np.round(ll, 9)))
    return best, p[best]


def fit_cells(name: str, kind: str, cells: np.ndarray, ncells: int, events: Events, fold: np.ndarray,
              settings: Sequence[dict] = ({},), parameters: Sequence[str] = (), graded: bool = True,
              games: Optional[np.ndarray] = None) -> Fit:
    """Cross-validate a WM model: ``cells`` is (settings x candidates); pick on the training games only.

    ``graded`` False collapses the cells to in/out (the setting's link is then ``p_in``, ``p_out``).
    """
    cells = np.atleast_2d(cells).astype(np.intp)
    if not graded:
        cells, ncells = (cells > 0).astype(np.intp), 2
    scored = np.ones(len(events.games), bool) if games is None else games
    counts = _counts(cells, ncells, events)
    counts[:, ~scored] = 0.0
    game_ll = np.zeros(len(events.games))
    predicted = np.full(events.candidates, np.nan)
    chosen = []
    total = counts.sum(axis=1)  # settings x cells x 2
    for f in range(int(fold.max()) + 1):
        held = (fold == f) & scored
        best, p = _choose(total - counts[:, held].sum(axis=1))
        chosen.append(best)
        c = counts[best, held]
        game_ll[held] = _binary_ll(c[:, :, 1], c[:, :, 0], p).sum(axis=1)
        rows = held[events.game]
        predicted[rows] = p[cells[best, rows]]
    best, p = _choose(total)
    rates = {"p_in": float(p[1]), "p_out": float(p[0])} if not graded else {"p_cell": [float(x) for x in p]}
    setting = {**settings[best], **rates}
    grid = {q: sorted({s[q] for s in settings}) for q in parameters}
    edge = []
    for q in parameters:
        values = grid[q]
        picked = [settings[i][q] for i in chosen + [best]]
        if len(values) > 1 and any(v in (values[0], values[-1]) for v in picked):
            edge.append(q)
    rows = scored[events.game]
    in_wm = float((cells[best, rows] > 0).mean()) if kind == "wm" and rows.any() else None
    return Fit(name, kind, game_ll, predicted, setting, [settings[i] for i in chosen], edge, grid, in_wm, graded,
               None if games is None else scored, int(rows.sum()))


def fit_membership(name: str, kind: str, member: np.ndarray, events: Events, fold: np.ndarray,
                   settings: Sequence[dict] = ({},), parameters: Sequence[str] = (),
                   games: Optional[np.ndarray] = None) -> Fit:
    """Cross-validate an in/out model: ``member`` is (settings x candidates) of WM membership."""
    return fit_cells(name, kind, np.atleast_2d(member).astype(np.uint8), 2, events, fold, settings, parameters,
                     graded=False, games=games)


def recency_features(events: Events, names: Sequence[str]) -> np.ndarray:
    """Return the recency predictors: log1p(seconds), log1p(words since), log(references), log(descriptions)."""
    columns = {"seconds": np.log1p(np.maximum(np.nan_to_num(events.seconds), 0.0)),
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
    """Cross-validate a logistic regression on recency predictors (standardised on the training games).

    A regression on seconds is trained and scored on the games with times only.
    """
    names = RECENCY[name]
    clocked = bool(CLOCK_PREDICTORS & set(names)) and not events.timed.all()
    scored = events.timed.copy() if clocked else np.ones(len(events.games), bool)
    x = recency_features(events, names)
    y = events.used.astype(float)
    predicted = np.full(events.candidates, np.nan)
    fold_settings = []
    usable = scored[events.game]
    for f in range(int(fold.max()) + 1):
        held = (fold == f)[events.game] & usable
        train = ~(fold == f)[events.game] & usable
        if not train.any():  # no game with times to train on: the link's 0.5, as for an unseen cell
            mean, std, w = np.zeros(len(names)), np.ones(len(names)), np.zeros(len(names) + 1)
        else:
            mean, std = x[train].mean(axis=0), x[train].std(axis=0) + 1e-12
            w = logistic_fit((x[train] - mean) / std, y[train])
        predicted[held] = _logistic_predict((x[held] - mean) / std, w)
        fold_settings.append(_coefficients(names, w, mean, std))
    ll = np.where(events.used, np.log(predicted), np.log1p(-predicted))
    game_ll = np.bincount(events.game[usable], weights=ll[usable], minlength=len(events.games))
    mean, std = x[usable].mean(axis=0), x[usable].std(axis=0) + 1e-12
    setting = _coefficients(names, logistic_fit((x[usable] - mean) / std, y[usable]), mean, std)
    return Fit(name, "recency", game_ll, predicted, setting, fold_settings, games=scored if clocked else None,
               scored=int(usable.sum()))


def _coefficients(names: Sequence[str], w: np.ndarray, mean: np.ndarray, std: np.ndarray) -> dict:
    """Coefficients on the unstandardised predictors (log scale): intercept and one per predictor."""
    slopes = w[1:] / std
    return {"intercept": float(w[0] - (slopes * mean).sum()),
            **{f"log_{n}": float(s) for n, s in zip(names, slopes)}}


__all__ = ["folds_of", "Fit", "fit_cells", "fit_membership", "recency_features", "logistic_fit", "fit_recency"]
