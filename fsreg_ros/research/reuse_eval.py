"""The evaluation of reference games: every model fitted, compared with intervals, and the printed report.

:func:`evaluate_games` is what ``fsreg-eval reference-games`` and ``fsreg-eval tangrams`` run
on loaded games: every rule of the core with the in/out and the graded link, in the group's
WM and (when some describer joined their game late) in each player's own WM, the
baselines (``none``, ``no-forgetting`` and its graded link, ``last-description``,
``said-by-describer``: in WM iff this trial's describer said the word about the referent
before, ``constant``) and the recency regressions; then the differences between models,
paired by game, with 95 % percentile bootstrap intervals over games of the ratio (summed
log-likelihood difference / candidates) (:func:`.stats.ratio_bootstrap_ci`), over the games
both models were scored on.  A rule's reported setting is the one chosen on all games; a
chosen value at the edge of its grid (in any fold or overall) is flagged.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Optional, Sequence

import numpy as np

from ..core.forgetting import settings as table
from .reference_games import TOKENISATIONS, Game, ReferenceGamesError, Tokeniser, tokenisation
from .reuse_events import Events, build_events
from .reuse_fit import Fit, fit_cells, fit_membership, fit_recency, folds_of
from .reuse_models import FOLDS, GRADED, PAIRS, PLAYER, RECENCY, family, needs_clock, wm_models
from .reuse_replay import CELL_NAMES, CELLS, cells_of
from .stats import RESAMPLES, method, ratio_bootstrap_ci

#: What the printed report calls the corpus and its describers, by default.
TITLE, DESCRIBER = "reference games", "describer"


@dataclass
class Evaluation:
    """Everything ``fsreg-eval reference-games`` reports (:meth:`to_json` is its ``--json``)."""

    tokenisation: str
    folds: int
    events: Events
    fits: dict
    differences: list
    best: str
    notes: list = field(default_factory=list)
    title: str = TITLE
    describer: str = DESCRIBER
    resamples: int = RESAMPLES  # of every interval's bootstrap

    @property
    def games(self) -> int:
        return len(self.events.games)

    def heldout(self, name: str) -> float:
        return self.fits[name].heldout_ll(self.events.candidates)

    def best_of(self, kind: str) -> Optional[str]:
        """Return the model of family ``kind`` with the best held-out log-likelihood (None if there is none)."""
        names = [n for n in self.fits if family(n) == kind]
        return max(names, key=self.heldout) if names else None

    def to_json(self) -> dict:
        d = self.events.descriptives
        models = {}
        for name, fit in self.fits.items():
            entry = {"kind": fit.kind, "family": family(name), "graded": fit.graded, "heldout_ll": self.heldout(name),
                     "setting": fit.setting}
            if fit.kind == "wm":
                entry.update(grid=fit.grid, at_grid_edge=fit.edge, fold_settings=fit.fold_settings, in_wm=fit.in_wm)
            if family(name) == "rule":
                entry["wm"] = "player" if name.endswith(PLAYER) else "group"
            if fit.games is not None:
                entry["games_scored"] = int(fit.games.sum())
            models[name] = entry
        return {
            "games": self.games, "events": self.events.events, "candidates": self.events.candidates,
            "reused": int(self.events.used.sum()), "tokenisation": self.tokenisation, "folds": self.folds,
            "descriptives": {k: v for k, v in d.items() if not k.startswith("_")},
            "models": models, "best": self.best, "best_rule": self.best_of("rule"),
            "best_regression": self.best_of("regression"), "differences": self.differences,
            "strength_cells": list(CELL_NAMES), "notes": self.notes,
            "intervals": method(self.resamples).replace("CI over games",
                                                        "CI over games of the ratio (summed difference / candidates)"),
        }


def evaluate_games(games: Sequence[Game], tokeniser: str = "content", folds: int = FOLDS,
                   grids: Optional[Mapping[str, Sequence]] = None, jobs: int = 1, resamples: int = RESAMPLES,
                   title: str = TITLE, describer: str = DESCRIBER) -> Evaluation:
    """Fit every model to people's reuse in games already loaded (``tokeniser``: the name they were read with)."""
    events = build_events(games)
    if events.candidates == 0:
        raise ReferenceGamesError(f"no {describer} re-reference with an earlier word: nothing to fit")
    if not 2 <= folds <= len(games):
        raise ReferenceGamesError(f"folds must be in [2, {len(games)}] (the number of games), got {folds}")
    fold = folds_of(len(games), folds)
    models = wm_models(grids)
    settings: list[Optional[dict]] = [{"policy": "none"}, None]  # none, no-forgetting
    for model in models:
        settings.extend(model.settings)
    cells = cells_of(events, settings, jobs)
    untimed = int((~events.timed).sum())
    notes = []
    if untimed:
        notes.append(f"{untimed} game{'s' if untimed != 1 else ''} without times: the rules and regressions on "
                     "seconds (decay, activation, recency-seconds, recency-all) are left out of their fit")
    fits: dict[str, Fit] = {}
    row = 2
    for model in models:
        span = cells[row:row + len(model.settings)]
        scored = events.timed if needs_clock(model.name) and untimed else None
        for suffix, graded in (("", False), (GRADED, True)):
            fits[model.name + suffix] = fit_cells(model.name + suffix, "wm", span, CELLS, events, fold, model.settings,
                                                  model.parameters, graded, scored)
        row += len(model.settings)
    late = int(events.late.sum())
    if not late:
        notes.append("every re-reference's describer was present from their game's first trial, so their own WM "
                     "holds what the group's does: the per-player rules are not fitted separately")
    else:
        notes.append(f"in {late} game{'s' if late != 1 else ''} a re-reference's describer wrote first after the "
                     "game's first trial (present from then on): there the per-player WM differs from the group's")
        # Elsewhere every describer's own WM holds what the group's does: only the late games are replayed.
        player_cells = cells[2:].copy()
        rows = events.late[events.game]
        player_cells[:, rows] = cells_of(events, settings[2:], jobs, players=True, games=events.late)[:, rows]
        row = 0
        for model in models:
            span = player_cells[row:row + len(model.settings)]
            scored = events.timed if needs_clock(model.name) and untimed else None
            fits[model.name + PLAYER] = fit_cells(model.name + PLAYER, "wm", span, CELLS, events, fold,
                                                  model.settings, model.parameters, False, scored)
            row += len(model.settings)
    fits["none"] = fit_membership("none", "wm", cells[0] > 0, events, fold, ({"policy": "none"},))
    fits["no-forgetting"] = fit_membership("no-forgetting", "baseline", cells[1] > 0, events, fold)
    fits["no-forgetting" + GRADED] = fit_cells("no-forgetting" + GRADED, "baseline", cells[1], CELLS, events, fold)
    fits["last-description"] = fit_membership("last-description", "baseline", events.last, events, fold)
    fits["said-by-describer"] = fit_membership("said-by-describer", "baseline", events.by_describer, events, fold)
    fits["constant"] = fit_membership("constant", "baseline", np.zeros(events.candidates, bool), events, fold)
    for name in RECENCY:
        fits[name] = fit_recency(name, events, fold)
    result = Evaluation(tokenisation(tokeniser).name, folds, events, fits, [], "", notes, title, describer, resamples)
    result.best = max(fits, key=result.heldout)
    result.differences = differences(result, resamples)
    return result


def difference(a: Fit, b: Fit, events: Events, resamples: int = RESAMPLES) -> dict:
    """Return ``a - b``: held-out log-likelihood per candidate, paired by game over the games both were scored on."""
    both = np.ones(len(events.games), bool)
    for fit in (a, b):
        if fit.games is not None:
            both &= fit.games
    n = np.bincount(events.game, minlength=len(events.games)).astype(float)
    est = ratio_bootstrap_ci((a.game_ll - b.game_ll)[both], n[both], resamples)
    out = {"a": a.name, "b": b.name, "mean": est.mean, "ci": [est.low, est.high]}
    if not both.all():
        out["games"] = int(both.sum())
    return out


def differences(result: Evaluation, resamples: int = RESAMPLES) -> list:
    """Return every difference reported.

    The paper's pairs, the best rule against the last description and against the best
    regression, and every model against the best model and against ``constant``.
    """
    fits, events = result.fits, result.events
    pairs = [(a, b) for a, b in PAIRS if a in fits and b in fits]
    rule, regression = result.best_of("rule"), result.best_of("regression")
    for extra in ((rule, "last-description"), (rule, regression)):
        if None not in extra and extra[0] != extra[1] and extra not in pairs:
            pairs.append(extra)  # type: ignore[arg-type]
    out = [difference(fits[a], fits[b], events, resamples) for a, b in pairs]
    for reference in dict.fromkeys((result.best, "constant")):
        for name, fit in fits.items():
            if name == reference or (name, reference) in pairs:
                continue
            out.append(difference(fit, fits[reference], events, resamples))
    return out


# ------------------------------------------------------------------ report
def report(result: Evaluation) -> list[str]:
    """Return the printed report: descriptives, every model's held-out fit, the differences."""
    e, d = result.events, result.events.descriptives
    described = TOKENISATIONS[result.tokenisation].description if result.tokenisation in TOKENISATIONS else ""
    lines = [f"{result.title}: {result.games} games, {e.events} {result.describer} "
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
    lines += [f"gaps between references to a referent ({d['gaps']}): {qs[1]:.0f} s (quartiles {qs[0]:.0f}-{qs[2]:.0f}),"
              f" {qr[1]:.0f} intervening references (quartiles {qr[0]:.0f}-{qr[2]:.0f})", ""]
    width = max(len(name) for name in result.fits)
    lines.append(f"{'model':{width}}  {'held-out LL':>11}  {'vs constant [95% CI]':>26}  setting (fitted on all games)")
    ordered = sorted(result.fits, key=lambda name: -result.heldout(name))
    for name in ordered:
        fit = result.fits[name]
        diff = _find(result, name, "constant")
        text = "" if diff is None else f"{diff['mean']:+.4f} [{diff['ci'][0]:+.4f}, {diff['ci'][1]:+.4f}]"
        lines.append(f"{name:{width}}  {result.heldout(name):11.4f}  {text:>26}  {setting_text(fit)}")
    lines += ["", "the paper's rules against each other, and the best rule against the last description and the best "
                  "regression (held-out LL per candidate, 95% CI):"]
    rule, regression = result.best_of("rule"), result.best_of("regression")
    shown = [p for p in PAIRS] + [(rule, "last-description"), (rule, regression)]
    for a, b in dict.fromkeys(shown):
        diff = _find(result, a, b)
        if diff is not None:
            lines.append(f"  {a + ' - ' + b:{2 * width}}  {_ci(diff)}")
    lines += ["", f"best: {result.best}; differences from it (held-out LL per candidate, 95% CI):"]
    for diff in result.differences:
        if diff["b"] == result.best:
            lines.append(f"  {diff['a']:{width}}  {_ci(diff)}")
    edges = [fit.name for fit in result.fits.values() if fit.edge]
    lines += ["",
              f"held-out LL: mean natural-log likelihood per candidate, {result.folds}-fold cross-validation by game "
              "(settings and link chosen on the training folds); WM models: p_in if the word is in the referent's WM "
              "queue, else p_out; /graded: one rate per cell (out of WM, or in it by episode age, <=1, 2, 3, 4-5, >5, "
              "x episodes used in, 1 or 2+); /player: each player's own WM.",
              f"intervals: paired by game, {method(result.resamples)} of the ratio (summed difference / candidates).",
              "chosen value at a grid edge: " + (", ".join(f"{n} ({', '.join(result.fits[n].edge)})" for n in edges)
                                                 if edges else "none (every fitted value lies inside its grid)")]
    lines += [f"note: {note}" for note in result.notes]
    return lines


def _find(result: Evaluation, a: Optional[str], b: Optional[str]) -> Optional[dict]:
    return next((x for x in result.differences if (x["a"], x["b"]) == (a, b)), None)


def _ci(diff: dict) -> str:
    games = f" ({diff['games']} games)" if "games" in diff else ""
    return f"{diff['mean']:+.4f} [{diff['ci'][0]:+.4f}, {diff['ci'][1]:+.4f}]{games}"


def setting_text(fit: Fit) -> str:
    """Return a model's fitted setting in one line (parameters by symbol, then its link)."""
    s = fit.setting
    if fit.kind == "recency":
        return ", ".join(f"{k} {v:+.3f}" for k, v in s.items())
    links = ("policy", "p_in", "p_out", "p_cell")
    params = [f"{table.setting(k).symbol} = {v if isinstance(v, str) else format(v, 'g')}"  # (a clock: its name)
              for k, v in s.items() if k not in links]
    if fit.graded:
        link = "p " + "/".join(f"{p:.2f}" for p in s["p_cell"])
    elif fit.in_wm == 0.0 or fit.name in ("constant", "none"):
        link = f"rate {s['p_out']:.3f}"
    elif fit.name == "no-forgetting":
        link = f"rate {s['p_in']:.3f}"
    else:
        link = f"p_in {s['p_in']:.3f}, p_out {s['p_out']:.3f}"
    wm = f", {fit.in_wm:.0%} in WM" if fit.in_wm else ""
    scored = f", {int(fit.games.sum())} games" if fit.games is not None else ""
    return (", ".join(params) + "; " if params else "") + link + wm + scored


__all__ = ["Evaluation", "evaluate_games", "difference", "differences", "report", "setting_text", "Tokeniser"]
