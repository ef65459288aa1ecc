"""Plots of the research workbench (matplotlib, Agg backend; never imported by the core).

* :func:`sweep_plots` - each sweep metric against decay period and against
  capacity per policy, and the divergence-from-``none`` curve per policy with a
  95 % band (mean +- 1.96 standard errors over games; a game's settings are
  averaged first, so copies of one game never narrow a band).
* :func:`wm_timeline` - a WM timeline from an event trace: one row per entity, one
  lane per property, a bar while the property is in WM, markers coloured by the
  cause of encoding and of forgetting, the dialogue turns on the time axis.
  :func:`wm_segments` computes the bars and markers (pure, tested).
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

CAUSE_COLOURS = {
    "speaker": "tab:blue",
    "rr": "tab:green",
    "reg-distractor": "tab:orange",
    "decay": "tab:red",
    "displacement": "tab:purple",
    "global-capacity": "tab:brown",
    "reset": "tab:gray",
    "retract": "black",
}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def mean_band(values: Sequence[float]) -> tuple[float, float]:
    """Return the mean and the half-width of its 95 % confidence band (normal approximation)."""
    n = len(values)
    if n == 0:
        return 0.0, 0.0
    mean = sum(values) / n
    if n < 2:
        return mean, 0.0
    var = sum((v - mean) ** 2 for v in values) / (n - 1)
    return mean, 1.96 * math.sqrt(var / n)


def per_seed_means(pairs: Sequence[tuple[Any, float]]) -> list[float]:
    """Return one mean per seed from (seed, value) pairs, so a game's settings count once in a band."""
    by_seed: dict[Any, list[float]] = defaultdict(list)
    for seed, value in pairs:
        by_seed[seed].append(value)
    return [sum(v) / len(v) for _, v in sorted(by_seed.items())]


def divergence_curve(
    curves: Mapping[tuple, Sequence[int]], policy: str, window: int = 1
) -> list[tuple[int, float, float]]:
    """Return (robot turn, mean, band) of the divergence indicator for ``policy``.

    Robot turns are grouped in blocks of ``window`` (the point is the block's last
    turn); each game (seed) contributes its mean over its settings and the block,
    and the band is 95 % over games.
    """
    by_block: dict[int, list[tuple[Any, float]]] = defaultdict(list)
    for (name, _, _, seed), flags in curves.items():
        if name == policy:
            for j, flag in enumerate(flags):
                by_block[j // window].append((seed, flag))
    last = {b: min((b + 1) * window, max(len(f) for k, f in curves.items() if k[0] == policy)) for b in by_block}
    return [(last[b], *mean_band(per_seed_means(by_block[b]))) for b in sorted(by_block)]


def sweep_plots(
    rows: list[dict], curves: Mapping[tuple, Sequence[int]], out: Path, metrics: Sequence[str]
) -> list[str]:
    """Write the sweep's PNG plots (one per metric in ``metrics``) into ``out``; return their file names."""
    plt = _pyplot()
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    files = []
    for metric in metrics:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
        for ax, parameter, label in ((axes[0], "decay_period", "decay period (s)"), (axes[1], "capacity", "capacity")):
            for policy in policies:
                mine = [r for r in rows if r["policy"] == policy]
                if policy == "none":
                    mean, band = mean_band([r[metric] for r in mine])  # one row per seed
                    ax.axhline(mean, color="gray", linestyle="--", label="none")
                    continue
                xs = sorted({r[parameter] for r in mine})
                stats = [mean_band(per_seed_means([(r["seed"], r[metric]) for r in mine if r[parameter] == x]))
                         for x in xs]
                ax.errorbar(xs, [m for m, _ in stats], yerr=[b for _, b in stats], marker="o", capsize=3,
                            label=policy)
            ax.set_xlabel(label)
            ax.grid(alpha=0.3)
        axes[0].set_ylabel(metric.replace("_", " "))
        axes[1].legend()
        fig.suptitle(f"{metric.replace('_', ' ')} (mean, 95 % band)")
        fig.tight_layout()
        name = f"{metric}.png"
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        files.append(name)
    fig, ax = plt.subplots(figsize=(8, 4))
    for policy in policies:
        if policy == "none":
            continue
        curve = divergence_curve(curves, policy, window=5)
        xs = [j for j, _, _ in curve]
        ax.plot(xs, [m for _, m, _ in curve], label=policy)
        ax.fill_between(xs, [m - b for _, m, b in curve], [m + b for _, m, b in curve], alpha=0.25)
    ax.set_xlabel("robot turn (blocks of 5)")
    ax.set_ylabel("share of descriptions differing from none")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("Divergence from No-WM by turn (95 % band)")
    fig.tight_layout()
    fig.savefig(out / "divergence.png", dpi=100)
    plt.close(fig)
    return files + ["divergence.png"]


@dataclass(frozen=True)
class Segment:
    """A property's stay in an entity's WM: [start, end) and the causes that began and ended it."""

    domain: str
    entity: str
    property: str
    start: float
    end: Optional[float]  # None: still in WM at the end of the trace
    encoded_by: str
    forgotten_by: Optional[str]


def wm_segments(events: Sequence[Mapping[str, Any]]) -> list[Segment]:
    """Return every stay of a property in WM from an event trace (in trace order of their starts)."""
    open_: dict[tuple, tuple[float, str]] = {}
    done: list[tuple[int, Segment]] = []
    order: dict[tuple, int] = {}
    for i, event in enumerate(events):
        key = (event.get("domain"), event.get("entity"), event.get("property"))
        time = float(event.get("time") or 0.0)
        if event.get("op") == "encode":
            if key not in open_:
                open_[key] = (time, str(event.get("cause")))
                order[key] = i
        elif event.get("op") == "forget" and key in open_:
            start, cause = open_.pop(key)
            done.append((order.pop(key), Segment(*key, start, time, cause, str(event.get("cause")))))
    for key, (start, cause) in open_.items():
        done.append((order[key], Segment(*key, start, None, cause, None)))
    return [s for _, s in sorted(done, key=lambda pair: pair[0])]


def turn_times(events: Sequence[Mapping[str, Any]], result: Optional[Mapping[str, Any]] = None) -> list[tuple]:
    """Return (time, turn, speaker or None) per dialogue turn, from the result if given, else the events."""
    if result is not None:
        return [(float(t.get("time") or 0.0), t.get("turn"), t.get("speaker")) for t in result.get("turns", ())]
    seen: dict[int, float] = {}
    for event in events:
        if event.get("turn") is not None:
            seen.setdefault(event["turn"], float(event.get("time") or 0.0))
    return [(time, turn, None) for turn, time in sorted(seen.items())]


def wm_timeline(
    events: Sequence[Mapping[str, Any]], out: Path, result: Optional[Mapping[str, Any]] = None, title: str = ""
) -> list[Segment]:
    """Draw the WM timeline of ``events`` into the PNG ``out``; return the segments drawn."""
    segments = wm_segments(events)
    turns = turn_times(events, result)
    last = max([s.end or s.start for s in segments] + [t for t, _, _ in turns] + [1.0])
    end_of_plot = last * 1.05
    lanes: dict[tuple, int] = {}
    for s in sorted(segments, key=lambda s: (s.domain, _natural(s.entity), s.property)):
        lanes.setdefault((s.domain, s.entity, s.property), len(lanes))
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(12, max(3.0, 0.18 * len(lanes) + 1.5)))
    for s in segments:
        y = lanes[(s.domain, s.entity, s.property)]
        stop = s.end if s.end is not None else end_of_plot
        ax.broken_barh([(s.start, max(stop - s.start, 1e-3))], (y - 0.35, 0.7), color="lightsteelblue")
        ax.plot(s.start, y, marker=">", color=CAUSE_COLOURS.get(s.encoded_by, "black"), markersize=5)
        if s.forgotten_by is not None:
            ax.plot(stop, y, marker="x", color=CAUSE_COLOURS.get(s.forgotten_by, "black"), markersize=5)
    for time, turn, speaker in turns:
        colour = "tab:blue" if speaker == "human" else "tab:orange" if speaker == "robot" else "gray"
        ax.axvline(time, color=colour, alpha=0.4, linewidth=0.8)
        if turn is not None:  # the turn number above the lanes: H3 = human turn 3, R4 = robot turn 4
            mark = {"human": "H", "robot": "R"}.get(str(speaker), "")
            ax.text(time, -1.0, f"{mark}{turn}", color=colour, fontsize=7, ha="center", va="bottom")
    ax.set_yticks(range(len(lanes)))
    ax.set_yticklabels([f"{entity}: {prop}" for (_, entity, prop) in lanes], fontsize=7)
    ax.set_ylim(len(lanes), -2.0)
    ax.set_xlim(0, end_of_plot)
    ax.set_xlabel("time (s); vertical lines: human turns (blue, H), robot turns (orange, R), numbered on top")
    handles = [plt.Line2D([], [], marker="o", linestyle="", color=c, label=cause) for cause, c in CAUSE_COLOURS.items()]
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              title="cause (> encode, x forget)", title_fontsize=7)
    ax.set_title(title or "Working memory over time")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return segments


def _natural(name: str) -> tuple:
    digits = "".join(ch for ch in name if ch.isdigit())
    return (name.rstrip("0123456789"), int(digits) if digits else -1, name)
