"""Plots of the research workbench (matplotlib, Agg backend; never imported by the core).

* :func:`sweep_plots` - per policy, its metrics against the parameters *it* reads
  (one PNG per policy, one line per value of a second parameter), the divergence
  from ``none`` by robot turn (one panel per policy), and for dynamic games the
  entrainment / outdated-information trade-off.  Every point is a mean over games
  with a 95 % percentile bootstrap interval over games (:mod:`.stats`), and every
  caption says so, with n.
* :func:`wm_timeline` - a WM timeline from an event trace: one row per entity, one
  lane per property, a bar while the property is in WM, markers coloured by the
  cause of encoding and of forgetting (only causes that occur), the dialogue turns
  on the time axis; lanes can be selected (``entities``, ``top``).
  :func:`wm_segments` computes the bars and markers (pure, tested).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

from .grid import BOUNDS, GRID
from .stats import METHOD, bootstrap_ci

#: One colour per cause; the turn lines use grey and black line styles no cause uses.
CAUSE_COLOURS = {
    "speaker": "tab:blue",
    "rr": "tab:green",
    "reg-distractor": "tab:orange",
    "decay": "tab:red",
    "displacement": "tab:purple",
    "similarity": "tab:pink",
    "global-capacity": "tab:brown",
    "shared-capacity": "tab:olive",
    "reset": "tab:cyan",
    "retract": "black",
}
TURN_STYLE = {"human": ("dimgray", ":"), "robot": ("darkgray", "--"), None: ("silver", "-")}
#: Names of the grid parameters on plot axes.
AXIS = {"decay_period": "decay period delta (s)", "capacity": "capacity alpha (properties per entity)",
        "global_capacity": "global capacity (properties per domain)",
        "shared_capacity": "shared pool (properties, all domains)"}
INTEGER = ("capacity", "global_capacity", "shared_capacity")
#: What each policy plot shows, panel by panel (dynamic games add two).
PANELS = (
    ("entrainment_gain", "entrainment gain over none\n(Dice with the human's last description)"),
    ("length_change", "length change over none\n(properties per description)"),
    ("mean_wm_occupancy", "WM occupancy\n(properties before the robot speaks)"),
    ("divergence", "divergence from none\n(share of descriptions differing)"),
)
DYNAMIC_PANELS = (("outdated_rate", "outdated rate\n(share of properties said no longer true)"),)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _caption(fig, text: str) -> None:
    fig.text(0.01, 0.005, text, fontsize=7, ha="left", va="bottom", wrap=True)


def _file_name(policy: str) -> str:
    return "policy-" + "".join(ch if ch.isalnum() or ch in "+-" else "_" for ch in policy) + ".png"


def _grid_parameters(entries: Sequence[dict]) -> list[str]:
    return [p for p in GRID if any(getattr(e["setting"], p) is not None for e in entries)]


def policy_plot(policy: str, entries: Sequence[dict], none: Optional[dict], out: Path, dynamic: bool) -> str:
    """Draw one policy's metrics against the parameters it reads into ``out``; return the file name."""
    plt = _pyplot()
    params = _grid_parameters(entries)
    x_param = params[0] if params else None
    line_params = params[1:]
    panels = PANELS + (DYNAMIC_PANELS if dynamic else ())
    fig, axes = plt.subplots(1, len(panels), figsize=(4.0 * len(panels), 3.9))
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for entry in entries:
        s = entry["setting"]
        groups[(tuple(getattr(s, p) for p in line_params), s.retraction)].append(entry)
    xs_all = sorted({getattr(e["setting"], x_param) for e in entries}) if x_param else [0]
    n = max(e["n"] for e in entries)
    colours = {values: f"C{i % 10}" for i, values in enumerate(dict.fromkeys(v for v, _ in groups))}
    for ax, (metric, title) in zip(axes, panels):
        for (line_values, told), group in groups.items():
            group = sorted(group, key=lambda e: getattr(e["setting"], x_param) if x_param else 0)
            xs = [getattr(e["setting"], x_param) if x_param else 0 for e in group]
            est = [e["estimates"][metric] for e in group]
            label = ", ".join(f"{'alpha' if p == 'capacity' else p.replace('_', ' ')}={v:g}"
                              for p, v in zip(line_params, line_values)) or policy
            if dynamic:
                label += "" if told else " (WM not told)"
            ax.errorbar(xs, [e.mean for e in est], yerr=[[e.mean - e.low for e in est], [e.high - e.mean for e in est]],
                        marker="o" if told else "s", capsize=3, linestyle="-" if told else "--", label=label,
                        color=colours[line_values])
        if metric.endswith("_gain") or metric.endswith("_change"):
            ax.axhline(0.0, color="gray", linewidth=0.8)
        elif none is not None and metric in none["estimates"] and none["estimates"][metric].mean:
            ax.axhline(none["estimates"][metric].mean, color="gray", linestyle="--", label="none")
        ax.set_title(title, fontsize=9)
        if x_param == "decay_period" and len(xs_all) > 2 and xs_all[-1] / xs_all[0] > 8:
            ax.set_xscale("log")  # periods spread over decades: equal steps for doublings
            ax.minorticks_off()
        ax.set_xticks(xs_all)
        if x_param in INTEGER or x_param is None:
            ax.set_xticklabels([str(int(x)) for x in xs_all] if x_param else ["(no parameter)"])
        else:
            ax.set_xticklabels([f"{x:g}" for x in xs_all])
        ax.set_xlabel(AXIS.get(x_param, "") if x_param else "")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    if len(labels) > 1:
        axes[-1].legend(handles, labels, fontsize=7)
    fig.suptitle(f"{policy}: each metric against its own parameters")
    _caption(fig, f"Points: mean over n = {n} games; bars: {METHOD}. Gains and changes are paired by game "
                  "against the same game under policy none.")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    name = _file_name(policy)
    fig.savefig(out / name, dpi=100)
    plt.close(fig)
    return name


def divergence_curve(
    curves: Mapping[tuple, Sequence[int]], setting: Any, window: int = 1
) -> list[tuple[int, float, float, float]]:
    """Return (last robot turn of the block, mean, low, high) of one setting's divergence, by block of turns.

    Each game contributes its mean over the block; the interval is the bootstrap over games.
    """
    by_block: dict[int, list[float]] = defaultdict(list)
    longest = 0
    for (s, _seed), flags in curves.items():
        if s != setting:
            continue
        longest = max(longest, len(flags))
        for b in range((len(flags) + window - 1) // window):
            block = flags[b * window:(b + 1) * window]
            by_block[b].append(sum(block) / len(block))
    out = []
    for b in sorted(by_block):
        e = bootstrap_ci(by_block[b])
        out.append((min((b + 1) * window, longest), e.mean, e.low, e.high))
    return out


#: At most this many settings per panel of the divergence plot (evenly chosen; divergence.csv has all).
DIVERGENCE_LINES = 6


def shown_settings(settings: Sequence[Any], most: int = DIVERGENCE_LINES) -> list:
    """Return at most ``most`` of ``settings``, evenly spread over the grid order, first and last included."""
    if len(settings) <= most:
        return list(settings)
    picks = sorted({round(i * (len(settings) - 1) / (most - 1)) for i in range(most)})
    return [settings[i] for i in picks]


def divergence_plot(curves: Mapping[tuple, Sequence[int]], out: Path) -> Optional[str]:
    """Draw the divergence from ``none`` by robot turn, one panel per policy, one line per setting shown."""
    settings = list(dict.fromkeys(s for s, _ in curves if s.policy != "none"))
    if not settings:
        return None
    policies = list(dict.fromkeys(s.policy for s in settings))
    turns = max(len(f) for f in curves.values())
    window = max(1, turns // 20)
    games = len({seed for _, seed in curves})
    columns = min(3, len(policies))
    rows = (len(policies) + columns - 1) // columns
    plt = _pyplot()
    fig, axes = plt.subplots(rows, columns, figsize=(5.2 * columns, 3.8 * rows + 0.5), squeeze=False)
    for ax in axes.flat[len(policies):]:
        ax.set_visible(False)
    omitted = []
    for ax, policy in zip(axes.flat, policies):
        mine = [s for s in settings if s.policy == policy]
        told = [s for s in mine if s.retraction]  # WM not told of changes diverges alike: one family is drawn
        shown = shown_settings(told or mine)
        if len(shown) < len(mine):
            omitted.append(f"{policy}: {len(shown)} of {len(mine)}")
        for setting in shown:
            curve = divergence_curve(curves, setting, window)
            xs = [j for j, _, _, _ in curve]
            ax.plot(xs, [m for _, m, _, _ in curve], label=setting.label().split(" ", 1)[-1] or policy,
                    linestyle="-" if setting.retraction else "--")
            ax.fill_between(xs, [lo for _, _, lo, _ in curve], [hi for _, _, _, hi in curve], alpha=0.15)
        ax.set_title(policy, fontsize=10)
        ax.set_xlabel(f"robot turn (blocks of {window})")
        ax.set_ylabel("share differing from none")
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Divergence from No-WM by robot turn")
    note = f" Settings shown ({'; '.join(omitted)}): WM told of fact changes, evenly chosen over the grid; " \
           "divergence.csv has all." if omitted else ""
    _caption(fig, f"Lines: mean over n = {games} games of each game's share of differing descriptions in the "
                  f"block; bands: {METHOD}.{note}")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(out / "divergence_by_turn.png", dpi=100)
    plt.close(fig)
    return "divergence_by_turn.png"


def tradeoff_plot(summary: Sequence[dict], out: Path, bounds: Sequence[float]) -> str:
    """Draw entrainment against the outdated rate, one panel per WM configuration, bounds as vertical lines."""
    plt = _pyplot()
    configurations = list(dict.fromkeys(e["setting"].wm for e in summary if e["setting"].policy != "none"))
    none = [e for e in summary if e["setting"].policy == "none"]
    columns = 2 if len(configurations) > 1 else 1
    rows = (len(configurations) + columns - 1) // columns
    fig, axes = plt.subplots(rows, columns, figsize=(6.5 * columns, 4.0 * rows + 0.6), squeeze=False,
                             sharex=True, sharey=True)
    n = max(e["n"] for e in summary)
    worst = max(e["estimates"]["outdated_rate"].high for e in summary)
    for ax in axes.flat[len(configurations):]:
        ax.set_visible(False)
    for ax, wm in zip(axes.flat, configurations):
        mine = [e for e in summary if e["setting"].wm == wm and e["setting"].policy != "none"]
        for policy in dict.fromkeys(e["setting"].policy for e in mine):
            points = [e for e in mine if e["setting"].policy == policy]
            x = [e["estimates"]["outdated_rate"] for e in points]
            y = [e["estimates"]["entrainment"] for e in points]
            ax.errorbar([e.mean for e in x], [e.mean for e in y],
                        xerr=[[e.mean - e.low for e in x], [e.high - e.mean for e in x]],
                        yerr=[[e.mean - e.low for e in y], [e.high - e.mean for e in y]],
                        marker="o", linestyle="", capsize=2, label=policy)
        for e in none:
            ax.axhline(e["estimates"]["entrainment"].mean, color="gray", linestyle="--", label="none")
        for bound in bounds:
            ax.axvline(bound, color="black", linewidth=0.8, linestyle=":")
            ax.text(bound, 0.02, f" {bound:.0%}", fontsize=7, va="bottom", transform=ax.get_xaxis_transform())
        ax.set_title(f"WM: {wm}", fontsize=10)
        ax.set_xlim(-0.002, max(worst, max(bounds)) * 1.1)
        ax.set_xlabel("outdated rate (share of properties said no longer true)")
        ax.set_ylabel("entrainment (Dice with the\nhuman's last description)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Entrainment against outdated information, one point per setting")
    _caption(fig, f"Points: means over n = {n} games; bars: {METHOD}; dotted lines: the recommendation's bounds.")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(out / "tradeoff.png", dpi=100)
    plt.close(fig)
    return "tradeoff.png"


def sweep_plots(rows: Sequence[dict], summary: Sequence[dict], curves: Mapping[tuple, Sequence[int]], out: Path,
                dynamic: bool = False) -> list[str]:
    """Write the sweep's PNG plots into ``out``; return their file names (each written once)."""
    files = []
    none = next((e for e in summary if e["setting"].policy == "none"), None)
    for policy in dict.fromkeys(e["setting"].policy for e in summary):
        if policy == "none":
            continue
        entries = [e for e in summary if e["setting"].policy == policy]
        files.append(policy_plot(policy, entries, none, out, dynamic))
    divergence = divergence_plot(curves, out)
    if divergence:
        files.append(divergence)
    if dynamic and any(e["setting"].policy != "none" for e in summary):
        files.append(tradeoff_plot(summary, out, BOUNDS))
    return files


# ------------------------------------------------------------------ timelines
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


def select_lanes(segments: Sequence[Segment], entities: Optional[Sequence[str]] = None,
                 top: Optional[int] = None, until: float = 0.0) -> list[Segment]:
    """Keep the stays of the chosen lanes: of ``entities`` only, then the ``top`` lanes longest in WM.

    A stay still open at the end counts until ``until``; ties go to the lane with more
    stays, then to the first in entity order.
    """
    chosen = [s for s in segments if entities is None or s.entity in set(entities)]
    if top is None:
        return chosen
    held: dict[tuple, list[float]] = defaultdict(lambda: [0.0, 0])
    for s in chosen:
        lane = held[(s.domain, s.entity, s.property)]
        lane[0] += (s.end if s.end is not None else max(until, s.start)) - s.start
        lane[1] += 1
    ranked = sorted(held, key=lambda k: (-held[k][0], -held[k][1], k[0], _natural(k[1]), k[2]))
    keep = set(ranked[:top])
    return [s for s in chosen if (s.domain, s.entity, s.property) in keep]


def empty_reason(result: Optional[Mapping[str, Any]]) -> str:
    """Say why a timeline has no stays: policy none retains nothing, or nothing was encoded."""
    policies = {str(m.get("policy")) for m in (result or {}).get("memory", {}).values()}
    if policies == {"none"}:
        return "Working memory is empty throughout: policy none retains nothing (No WM, DIST-PIA)."
    return "No property entered working memory in this trace (or none of the selected lanes)."


def wm_timeline(
    events: Sequence[Mapping[str, Any]], out: Path, result: Optional[Mapping[str, Any]] = None, title: str = "",
    entities: Optional[Sequence[str]] = None, top: Optional[int] = None,
) -> list[Segment]:
    """Draw the WM timeline of ``events`` into the PNG ``out``; return the segments drawn.

    ``entities`` keeps those entities' lanes only; ``top`` keeps the N lanes longest in WM.
    """
    turns = turn_times(events, result)
    every = wm_segments(events)
    last = max([s.end or s.start for s in every] + [t for t, _, _ in turns] + [1.0])
    end_of_plot = last * 1.05
    segments = select_lanes(every, entities, top, end_of_plot)
    lanes: dict[tuple, int] = {}
    for s in sorted(segments, key=lambda s: (s.domain, _natural(s.entity), s.property)):
        lanes.setdefault((s.domain, s.entity, s.property), len(lanes))
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(12, max(3.0, 0.18 * len(lanes) + 1.8)))
    causes: dict[str, None] = {}
    for s in segments:
        y = lanes[(s.domain, s.entity, s.property)]
        stop = s.end if s.end is not None else end_of_plot
        ax.broken_barh([(s.start, max(stop - s.start, 1e-3))], (y - 0.35, 0.7), color="lightsteelblue")
        ax.plot(s.start, y, marker=">", color=CAUSE_COLOURS.get(s.encoded_by, "magenta"), markersize=5)
        causes[s.encoded_by] = None
        if s.forgotten_by is not None:
            ax.plot(stop, y, marker="x", color=CAUSE_COLOURS.get(s.forgotten_by, "magenta"), markersize=5)
            causes[s.forgotten_by] = None
    speakers: dict[Any, None] = {}
    for time, turn, speaker in turns:
        colour, style = TURN_STYLE.get(speaker, TURN_STYLE[None])
        speakers[speaker] = None
        ax.axvline(time, color=colour, linestyle=style, linewidth=0.9)
        if turn is not None:  # the turn number above the lanes: H3 = human turn 3, R4 = robot turn 4
            mark = {"human": "H", "robot": "R"}.get(str(speaker), "")
            ax.text(time, -1.0, f"{mark}{turn}", color="black", fontsize=7, ha="center", va="bottom")
    if lanes:
        ax.set_yticks(range(len(lanes)))
        ax.set_yticklabels([f"{entity}: {prop}" for (_, entity, prop) in lanes], fontsize=7)
        ax.set_ylim(len(lanes), -2.0)
    else:
        ax.set_yticks([])
        ax.set_ylim(1, -2.0)
        ax.text(end_of_plot / 2, 0.2, empty_reason(result) if not every else empty_reason(None), ha="center",
                va="center", fontsize=10)
    ax.set_xlim(0, end_of_plot)
    ax.set_xlabel("time (s); vertical lines: the dialogue's turns (H = human, R = robot), numbered on top")
    handles = [plt.Line2D([], [], marker="o", linestyle="", color=CAUSE_COLOURS.get(c, "magenta"), label=c)
               for c in sorted(causes, key=lambda c: list(CAUSE_COLOURS).index(c) if c in CAUSE_COLOURS else 99)]
    handles += [plt.Line2D([], [], color=TURN_STYLE[s][0], linestyle=TURN_STYLE[s][1],
                           label={"human": "human turn", "robot": "robot turn"}.get(s, "turn"))
                for s in speakers if s in TURN_STYLE]
    if handles:
        ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  title="cause (> encode, x forget)" if causes else None, title_fontsize=7)
    shown = f"{len(lanes)} of {len({(s.domain, s.entity, s.property) for s in every})} lanes"
    ax.set_title((title or "Working memory over time") + (f" ({shown})" if len(lanes) < len(set(
        (s.domain, s.entity, s.property) for s in every)) else ""))
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return segments


def _natural(name: str) -> tuple:
    digits = "".join(ch for ch in name if ch.isdigit())
    return (name.rstrip("0123456789"), int(digits) if digits else -1, name)
