"""Figures of ``fsreg-eval tangrams`` (matplotlib, Agg backend), sized for a two-column paper.

* ``tangrams-reuse``: people's reuse of an earlier word against the seconds since it was last
  said about the tangram, against the references (trials) since, and per repetition, with the
  held-out prediction of every model with the in/out link in the group's WM and of the best
  graded rule overlaid (models whose predictions coincide with another's are drawn once and
  named in the legend together).
* ``tangrams-data``: the corpus: distinct content words per description by repetition, the
  share of a description's words said earlier and reused, and the gaps between references.

Each is written as PNG and PDF, 7 inches wide (both columns), fonts of 7-8 pt, legends below
the panels; people's points carry a 95 % percentile bootstrap interval over games (:mod:`.stats`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plot import _pyplot
from .stats import method, ratio_bootstrap_ci
from .reuse_eval import Evaluation
from .reuse_models import family

WIDTH = 7.0  # inches: a two-column paper's full text width
FONT = {"font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "xtick.labelsize": 7, "ytick.labelsize": 7,
        "legend.fontsize": 7, "pdf.fonttype": 42}
#: One colour per model, the same in every panel and figure; later models take the remaining colours.
COLOURS = {"last-description": "tab:red", "constant": "dimgray", "decay": "tab:blue", "displacement": "tab:green",
           "decay+displacement": "tab:purple", "displacement-lfu": "tab:olive", "displacement-random": "tab:cyan",
           "global-capacity": "tab:brown", "recency-all": "black", "recency-descriptions": "tab:pink",
           "recency-seconds": "tab:orange", "recency-words": "goldenrod", "recency-references": "tab:gray"}
SPARE = ("darkblue", "darkgreen", "darkred", "teal", "indigo", "sienna")
STYLE = {"wm": "-", "baseline": "--", "recency": ":"}
SECOND_EDGES = (0, 60, 120, 180, 240, 300, 420, 600, 900, 1800, np.inf)
REFERENCE_EDGES = (1, 6, 9, 12, 15, 18, 24, 36, 48, np.inf)


def _binned(values: np.ndarray, edges) -> np.ndarray:
    return np.digitize(values, edges[1:-1])


def _people(result: Evaluation, bins: np.ndarray, count: int):
    """Observed reuse per bin with its bootstrap interval over games: (x index, mean, low, high)."""
    e = result.events
    games = len(e.games)
    out = []
    for b in range(count):
        mask = bins == b
        if not mask.any():
            out.append((np.nan, np.nan, np.nan))
            continue
        used = np.bincount(e.game[mask], weights=e.used[mask], minlength=games)
        total = np.bincount(e.game[mask], minlength=games).astype(float)
        est = ratio_bootstrap_ci(used, total, result.resamples)
        out.append((est.mean, est.low, est.high))
    return np.asarray(out)


def _drawn(result: Evaluation) -> list[str]:
    """Return the models drawn: every model with the in/out link in the group's WM, and the best graded rule."""
    graded = [n for n in result.fits if result.fits[n].graded and family(n) == "rule"]
    best = [max(graded, key=result.heldout)] if graded else []
    return [n for n in result.fits if "/" not in n] + best


def _distinct_models(result: Evaluation) -> list[tuple[str, list[str]]]:
    """Models drawn with distinct held-out predictions, each with the names of those it coincides with."""
    groups: list[tuple[str, list[str]]] = []
    for name in _drawn(result):
        fit = result.fits[name]
        for head, names in groups:
            if np.array_equal(result.fits[head].predicted, fit.predicted):
                names.append(name)
                break
        else:
            groups.append((name, [name]))
    return groups


def _colour(names, index: int) -> str:
    return next((COLOURS[n] for n in names if n in COLOURS), SPARE[index % len(SPARE)])


def reuse_figure(result: Evaluation, out: Path, stem: str = "tangrams-reuse") -> list[str]:
    """Draw people's reuse and every model's held-out prediction; write ``stem``.png and .pdf into ``out``."""
    plt = _pyplot()
    e = result.events
    panels = [
        ("time since the word was last said\nabout the tangram (s, log scale)", e.seconds, SECOND_EDGES,
         (60, 120, 300, 600, 1200)),
        ("references since the word was last said\nabout the tangram (trials, log scale)", e.references.astype(float),
         REFERENCE_EDGES, (5, 10, 20, 40)),
        ("repetition of the tangram", e.repetition.astype(float), (2, 3, 4, 5, 6, np.inf), None),
    ]
    groups = _distinct_models(result)
    with plt.rc_context(FONT):
        fig, axes = plt.subplots(1, 3, figsize=(WIDTH, 3.3), sharey=True)
        for ax, (label, values, edges, ticks) in zip(axes, panels):
            edges = np.asarray(edges, dtype=float)
            bins = _binned(values, edges)
            count = len(edges) - 1
            x = np.array([np.median(values[bins == b]) if (bins == b).any() else np.nan for b in range(count)])
            for i, (name, names) in enumerate(groups):
                fit = result.fits[name]
                means = [np.nanmean(fit.predicted[bins == b]) if (bins == b).any() else np.nan for b in range(count)]
                ax.plot(x, means, STYLE[fit.kind], color=_colour(names, i), linewidth=1.1,
                        label=" = ".join(names))
            people = _people(result, bins, count)
            ax.errorbar(x, people[:, 0], yerr=[people[:, 0] - people[:, 1], people[:, 2] - people[:, 0]], fmt="o",
                        color="black", markersize=3.5, capsize=2, linewidth=0.9, label="people", zorder=5)
            if ticks:
                ax.set_xscale("log")
                ax.set_xticks(ticks)
                ax.set_xticklabels([str(t) for t in ticks])
                ax.minorticks_off()
            else:
                ax.set_xticks([2, 3, 4, 5, 6])
            ax.set_xlabel(label)
            ax.grid(alpha=0.3, linewidth=0.5)
        axes[0].set_ylabel("P(director reuses an earlier word)")
        axes[0].set_ylim(0, None)
        handles, labels = axes[0].get_legend_handles_labels()
        order = [labels.index("people")] + [i for i, lab in enumerate(labels) if lab != "people"]
        fig.legend([handles[i] for i in order], [labels[i] for i in order], loc="lower center", ncol=4,
                   frameon=False, bbox_to_anchor=(0.5, 0.0))
        fig.text(0.5, 0.995, f"{result.games} games, {e.candidates:,} candidate words, tokenisation "
                             f"'{result.tokenisation}'. Points: people (bars: {method(result.resamples)}); lines: each "
                             f"model's held-out prediction ({result.folds}-fold CV by game).", ha="center", va="top",
                 fontsize=6.5, wrap=True)
        rows = (len(groups) + 1 + 3) // 4
        fig.tight_layout(rect=(0, 0.045 * rows + 0.02, 1, 0.95))
        return _save(fig, plt, out, stem)


def data_figure(result: Evaluation, out: Path, stem: str = "tangrams-data") -> list[str]:
    """Draw the corpus descriptives; write ``stem``.png and .pdf into ``out``."""
    plt = _pyplot()
    e, d = result.events, result.events.descriptives
    rows = d["_descriptions"]  # (game, repetition, word types, of them said earlier)
    games, n = len(e.games), result.resamples
    reps = sorted(set(rows[:, 1].tolist()))
    with plt.rc_context(FONT):
        fig, axes = plt.subplots(1, 3, figsize=(WIDTH, 2.8))
        words, earlier, reuse = [], [], []
        for rep in reps:
            mine = rows[rows[:, 1] == rep]
            per_game = np.bincount(mine[:, 0], minlength=games).astype(float)
            words.append(ratio_bootstrap_ci(np.bincount(mine[:, 0], weights=mine[:, 2], minlength=games), per_game, n))
            types = np.bincount(mine[:, 0], weights=mine[:, 2], minlength=games)
            earlier.append(ratio_bootstrap_ci(np.bincount(mine[:, 0], weights=mine[:, 3], minlength=games), types, n))
            cand = e.repetition == rep
            reuse.append(ratio_bootstrap_ci(np.bincount(e.game[cand], weights=e.used[cand], minlength=games),
                                            np.bincount(e.game[cand], minlength=games).astype(float), n))
        _bars(axes[0], reps, words, "tab:blue", "")
        axes[0].set_ylabel("distinct content words\nper description (words)")
        axes[0].set_ylim(0, None)
        later = [r for r in reps if r > 1]
        _bars(axes[1], later, earlier[len(reps) - len(later):], "tab:blue",
              "middle: share of a description's words said earlier")
        _bars(axes[1], later, reuse[len(reps) - len(later):], "tab:red", "middle: share of the earlier words reused")
        axes[1].set_ylabel("share")
        axes[1].set_ylim(0, 1)
        fig.legend(*axes[1].get_legend_handles_labels(), loc="lower center", ncol=2, frameon=False,
                   bbox_to_anchor=(0.5, 0.0))
        for ax in axes[:2]:
            ax.set_xlabel("repetition of the tangram")
            ax.set_xticks(reps if ax is axes[0] else later)
            ax.grid(alpha=0.3, linewidth=0.5)
        gaps = d["_gap_seconds"]
        if len(gaps):
            bins = np.geomspace(max(gaps.min(), 1.0), gaps.max(), 30)
            axes[2].hist(np.maximum(gaps, 1.0), bins=bins, color="tab:gray")
            axes[2].set_xscale("log")
        axes[2].set_xlabel("gap between two references\nto a tangram (s, log scale)")
        axes[2].set_ylabel("references")
        axes[2].grid(alpha=0.3, linewidth=0.5)
        fig.text(0.5, 0.995, f"{result.games} games, tokenisation '{result.tokenisation}'; bars: {method(n)}.",
                 ha="center", va="top", fontsize=6.5)
        fig.tight_layout(rect=(0, 0.07, 1, 0.94))
        return _save(fig, plt, out, stem)


def _bars(ax, xs, estimates, colour, label) -> None:
    means = np.array([x.mean for x in estimates])
    lows = means - np.array([x.low for x in estimates])
    highs = np.array([x.high for x in estimates]) - means
    ax.errorbar(xs, means, yerr=[lows, highs], fmt="o-", color=colour, markersize=3.5, capsize=2, linewidth=1.0,
                label=label or None)


def _save(fig, plt, out: Path, stem: str) -> list[str]:
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for suffix, options in ((".png", {"dpi": 200}), (".pdf", {"metadata": {"CreationDate": None}})):
        fig.savefig(out / (stem + suffix), **options)
        names.append(stem + suffix)
    plt.close(fig)
    return names


def write_figures(result: Evaluation, out: Path) -> list[str]:
    """Write both tangram figures (PNG and PDF) into ``out``; return the file names."""
    return reuse_figure(result, out) + data_figure(result, out)
