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

from ..core.forgetting import settings
from .grid import BOUNDS, DEFAULT_WM_ORDER, NUMERIC
from .stats import METHOD, bootstrap_ci

#: One colour per cause; the turn lines use grey and black line styles no cause uses.  Encodings are
#: named as the alignment table names origins (:data:`fsreg_ros.core.algorithms.alignment.ORIGINS`).
CAUSE_COLOURS = {
    "human-speech": "tab:blue",
    "robot-speech": "darkgoldenrod",
    "rr": "tab:green",
    "reg-distractor": "tab:orange",
    "decay": "tab:red",
    "activation": "tab:gray",
    "displacement": "tab:purple",
    "similarity": "tab:pink",
    "global-capacity": "tab:brown",
    "shared-capacity": "tab:olive",
    "reset": "tab:cyan",
    "retract": "black",
}
TURN_STYLE = {"human": ("dimgray", ":"), "robot": ("darkgray", "--"), None: ("silver", "-")}
#: Names of the grid parameters on plot axes, with units.
AXIS = {row.name: row.axis for row in settings.parameters()}
#: Each grid parameter's short name in legends and titles: ``δ = 10``.
SHORT = {row.name: row.symbol for row in settings.parameters()}
INTEGER = tuple(row.name for row in settings.parameters() if row.kind is int)
#: What each policy plot shows, panel by panel: (metric, title, y-axis label with its unit); dynamic games add one.
PANELS = (
    ("entrainment_gain", "entrainment gain over none", "Δ Dice with the human's\nlast description"),
    ("length_change", "length change over none", "Δ length\n(properties per description)"),
    ("mean_wm_occupancy", "WM occupancy", "properties in WM before\nthe robot speaks"),
    ("divergence", "divergence from none", "share of descriptions\ndiffering from none"),
)
DYNAMIC_PANELS = (("outdated_rate", "outdated information", "share of properties said\nno longer true"),)
#: The listener's panels (sweeps with a listener): metric, title, y-axis label with its unit.
LISTENER_PANELS = (
    ("success", "success", "share of robot turns"),
    ("turns_to_success", "turns to success", "attempts (1 = at once)"),
    ("said_length", "length said", "properties per turn"),
    ("entrainment", "entrainment", "Dice"),
)
#: A two-column paper's full text width and its font sizes (points).
PAGE_WIDTH = 7.0
STYLE = {"font.size": 8, "axes.titlesize": 8, "axes.labelsize": 7.5, "xtick.labelsize": 7, "ytick.labelsize": 7,
         "legend.fontsize": 6.5, "legend.title_fontsize": 6.5, "figure.titlesize": 9, "lines.linewidth": 1.2,
         "lines.markersize": 3.5, "errorbar.capsize": 2, "pdf.fonttype": 42, "ps.fonttype": 42}
#: Every figure is written as PNG (at this resolution) and PDF.
DPI = 200


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _style():
    """Return a context in which figures are drawn at a two-column paper's sizes."""
    return _pyplot().rc_context(STYLE)


def _caption(fig, text: str) -> None:
    fig.text(0.01, 0.005, text, fontsize=6, ha="left", va="bottom", wrap=True)


def _save(fig, out: Path, name: str) -> list[str]:
    """Write ``fig`` as ``name`` (a .png) and the same name in PDF into ``out``; return both names."""
    pdf = Path(name).with_suffix(".pdf").name
    fig.savefig(out / name, dpi=DPI)
    fig.savefig(out / pdf)
    _pyplot().close(fig)
    return [name, pdf]


def _file_name(policy: str) -> str:
    return "policy-" + "".join(ch if ch.isalnum() or ch in "+-" else "_" for ch in policy) + ".png"


def _grid_parameters(entries: Sequence[dict]) -> list[str]:
    return [p for p in NUMERIC if any(getattr(e["setting"], p) is not None for e in entries)]


def _x_axis(ax, x_param: Optional[str], xs_all: Sequence[float]) -> None:
    """Ticks at the grid's values; a logarithmic axis (said in its label) for positive values over decades."""
    label = AXIS.get(x_param, "") if x_param else ""
    if x_param not in INTEGER and len(xs_all) > 2 and xs_all[0] > 0 and xs_all[-1] / xs_all[0] > 8:
        ax.set_xscale("log")  # values (decay periods) spread over decades: equal steps for doublings
        ax.minorticks_off()
        label += ", log scale"
    ax.set_xticks(xs_all)
    if x_param in INTEGER or x_param is None:
        ax.set_xticklabels([str(int(x)) for x in xs_all] if x_param else ["(no parameter)"])
    else:
        ax.set_xticklabels([f"{x:g}" for x in xs_all])
    ax.set_xlabel(label)


def _layout(fig, bottom: float = 0.45, top: float = 0.0) -> None:
    """Tight layout leaving ``bottom`` inches for the caption (and legend), ``top`` more above the title."""
    height = fig.get_size_inches()[1]
    fig.tight_layout(rect=(0, bottom / height, 1, 1 - top / height))


def _panel_grid(count: int, columns: int, height: float):
    plt = _pyplot()
    rows = (count + columns - 1) // columns
    fig, axes = plt.subplots(rows, columns, figsize=(PAGE_WIDTH, height * rows + 0.9), squeeze=False)
    for ax in axes.flat[count:]:
        ax.set_visible(False)
    return fig, axes


def policy_plot(policy: str, entries: Sequence[dict], none: Optional[dict], out: Path, dynamic: bool,
                panels: Sequence[tuple] = PANELS, name: Optional[str] = None) -> list[str]:
    """Draw one policy's metrics against the parameters it reads into ``out``; return the files (PNG, PDF)."""
    params = _grid_parameters(entries)
    x_param = params[0] if params else None
    line_params = params[1:]
    panels = tuple(panels) + (DYNAMIC_PANELS if dynamic else ())
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for entry in entries:
        s = entry["setting"]
        groups[(tuple(getattr(s, p) for p in line_params), s.retraction)].append(entry)
    xs_all = sorted({getattr(e["setting"], x_param) for e in entries}) if x_param else [0]
    n = max(e["n"] for e in entries)
    colours = {values: f"C{i % 10}" for i, values in enumerate(dict.fromkeys(v for v, _ in groups))}
    with _style():
        fig, axes = _panel_grid(len(panels), 2, 1.8)
        for ax, (metric, title, ylabel) in zip(axes.flat, panels):
            for (line_values, told), group in groups.items():
                group = sorted(group, key=lambda e: getattr(e["setting"], x_param) if x_param else 0)
                xs = [getattr(e["setting"], x_param) if x_param else 0 for e in group]
                est = [e["estimates"][metric] for e in group]
                label = ", ".join(f"{SHORT[p]} = {_value(v)}" for p, v in zip(line_params, line_values)) or policy
                if dynamic:
                    label += "" if told else " (WM not told)"
                ax.errorbar(xs, [e.mean for e in est],
                            yerr=[[e.mean - e.low for e in est], [e.high - e.mean for e in est]],
                            marker="o" if told else "s", linestyle="-" if told else "--", label=label,
                            color=colours[line_values])
            if metric.endswith("_gain") or metric.endswith("_change"):
                ax.axhline(0.0, color="gray", linewidth=0.8)
            elif none is not None and metric in none["estimates"] and none["estimates"][metric].mean:
                ax.axhline(none["estimates"][metric].mean, color="gray", linestyle="--", label="policy none")
            ax.set_title(title)
            ax.set_ylabel(ylabel)
            _x_axis(ax, x_param, xs_all)
            ax.grid(alpha=0.3)
        handles = {}
        for ax in axes.flat[:len(panels)]:
            for handle, label in zip(*ax.get_legend_handles_labels()):
                handles.setdefault(label, handle)
        columns = min(len(handles), 4)
        rows = (len(handles) + columns - 1) // max(columns, 1)
        if len(handles) > 1:
            fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=columns,
                       bbox_to_anchor=(0.5, 0.33 / fig.get_size_inches()[1]), frameon=False)
        fig.suptitle(f"{policy}: each metric against its own parameters")
        _caption(fig, f"Points: mean over n = {n} games; bars: {METHOD}. Gains and changes are paired by game "
                      "against the same game under policy none.")
        _layout(fig, 0.45 + (0.16 * rows if len(handles) > 1 else 0))
        return _save(fig, out, name or _file_name(policy))


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


def divergence_panels(settings: Sequence[Any]) -> list[tuple[str, list]]:
    """Group settings into the divergence plot's panels: per policy, per value of its second parameter.

    Every setting is in exactly one panel; a panel's lines are its first parameter's
    values (grid order), WM told of fact changes or not.
    """
    panels: dict[tuple, list] = {}
    for setting in settings:
        params = [p for p in NUMERIC if getattr(setting, p) is not None]
        rest = tuple((p, getattr(setting, p)) for p in params[1:])
        panels.setdefault((_group(setting), rest), []).append(setting)
    out = []
    for (policy, rest), mine in panels.items():
        title = policy + (": " + ", ".join(f"{SHORT[p]} = {_value(v)}" for p, v in rest) if rest else "")
        out.append((title, mine))
    return out


def _value(value: Any) -> str:
    """Return an axis value as a label shows it (a number as ``%g``, the activation clock as is)."""
    return value if isinstance(value, str) else f"{value:g}"


def _group(setting: Any) -> str:
    """Return what a plot groups a setting by: its policy, and REG's WM order unless it is the paper's."""
    order = getattr(setting, "wm_order", DEFAULT_WM_ORDER)
    return setting.policy if order == DEFAULT_WM_ORDER else f"{setting.policy} ({order} order)"


def _line_label(setting: Any) -> str:
    params = [p for p in NUMERIC if getattr(setting, p) is not None]
    label = f"{SHORT[params[0]]} = {_value(getattr(setting, params[0]))}" if params else setting.policy
    return label if setting.retraction else label + " (not told)"


def divergence_plot(curves: Mapping[tuple, Sequence[int]], out: Path) -> list[str]:
    """Draw the divergence from ``none`` by robot turn: every setting, one panel per policy and second parameter.

    Returns the files written (PNG, PDF; none without a setting other than ``none``).
    """
    settings = list(dict.fromkeys(s for s, _ in curves if s.policy != "none"))
    if not settings:
        return []
    panels = divergence_panels(settings)
    turns = max(len(f) for f in curves.values())
    window = max(1, turns // 20)
    games = len({seed for _, seed in curves})
    columns = 2 if len(panels) > 1 else 1
    plt = _pyplot()
    with _style():
        fig, axes = _panel_grid(len(panels), columns, 1.85)
        for ax, (title, mine) in zip(axes.flat, panels):
            firsts = list(dict.fromkeys(_line_label(s).removesuffix(" (not told)") for s in mine))
            cmap = plt.get_cmap("viridis")
            colour = {f: cmap(0.9 * i / max(len(firsts) - 1, 1)) for i, f in enumerate(firsts)}
            for setting in mine:
                curve = divergence_curve(curves, setting, window)
                xs = [j for j, _, _, _ in curve]
                c = colour[_line_label(setting).removesuffix(" (not told)")]
                if setting.retraction:  # bands for the told family only, under every line
                    ax.fill_between(xs, [lo for _, _, lo, _ in curve], [hi for _, _, _, hi in curve], alpha=0.12,
                                    color=c, linewidth=0, zorder=1)
                ax.plot(xs, [m for _, m, _, _ in curve], color=c, zorder=3,
                        label=_line_label(setting) if setting.retraction else "_not told",  # dashed: caption
                        linestyle="-" if setting.retraction else "--")
            ax.set_title(title)
            ax.set_xlabel(f"robot turn (blocks of {window})")
            ax.set_ylabel("share of descriptions\ndiffering from none")
            ax.set_ylim(0, 1)
            ax.set_xlim(0, turns)
            ax.grid(alpha=0.3)
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, handlelength=1.6,
                      borderaxespad=0.0)
        fig.suptitle("Divergence from No-WM by robot turn")
        untold = " Dashed: WM not told of fact changes (bands omitted)." if any(not s.retraction for s in settings) \
            else ""
        _caption(fig, f"Lines: mean over n = {games} games of each game's share of differing descriptions in the "
                      f"block; bands: {METHOD}.{untold} Every setting is drawn.")
        _layout(fig)
        return _save(fig, out, "divergence_by_turn.png")


def tradeoff_plot(summary: Sequence[dict], out: Path, bounds: Sequence[float]) -> list[str]:
    """Draw entrainment against the outdated rate, one panel per WM configuration, bounds as vertical lines."""
    configurations = list(dict.fromkeys(e["setting"].wm for e in summary if e["setting"].policy != "none"))
    none = [e for e in summary if e["setting"].policy == "none"]
    n = max(e["n"] for e in summary)
    worst = max(e["estimates"]["outdated_rate"].high for e in summary)
    with _style():
        columns = 2 if len(configurations) > 1 else 1
        fig, axes = _panel_grid(len(configurations), columns, 2.3)
        for ax in axes.flat[1:len(configurations)]:
            ax.sharex(axes.flat[0])
            ax.sharey(axes.flat[0])
        for ax, wm in zip(axes.flat, configurations):
            mine = [e for e in summary if e["setting"].wm == wm and e["setting"].policy != "none"]
            for i, policy in enumerate(dict.fromkeys(e["setting"].policy for e in summary
                                                     if e["setting"].policy != "none")):
                points = [e for e in mine if e["setting"].policy == policy]
                if not points:
                    continue
                x = [e["estimates"]["outdated_rate"] for e in points]
                y = [e["estimates"]["entrainment"] for e in points]
                ax.errorbar([e.mean for e in x], [e.mean for e in y],
                            xerr=[[e.mean - e.low for e in x], [e.high - e.mean for e in x]],
                            yerr=[[e.mean - e.low for e in y], [e.high - e.mean for e in y]],
                            marker="o", linestyle="", label=policy, color=f"C{i % 10}")
            for e in none:
                ax.axhline(e["estimates"]["entrainment"].mean, color="gray", linestyle="--", label="policy none")
            for bound in bounds:
                ax.axvline(bound, color="black", linewidth=0.8, linestyle=":")
                ax.text(bound, 0.02, f" {bound:.0%}", fontsize=6, va="bottom", transform=ax.get_xaxis_transform())
            ax.set_title(f"WM: {wm}")
            ax.set_xlim(-0.002, max(worst, max(bounds)) * 1.1)
            ax.set_xlabel("outdated rate (share of properties\nsaid no longer true)")
            ax.set_ylabel("entrainment (Dice with the\nhuman's last description)")
            ax.grid(alpha=0.3)
        handles: dict = {}
        for ax in axes.flat[:len(configurations)]:
            for handle, label in zip(*ax.get_legend_handles_labels()):
                handles.setdefault(label, handle)
        fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=min(len(handles), 4),
                   bbox_to_anchor=(0.5, 0.33 / fig.get_size_inches()[1]), frameon=False)
        rows = (len(handles) + 3) // 4
        fig.suptitle("Entrainment against outdated information, one point per setting")
        _caption(fig, f"Points: means over n = {n} games; bars: {METHOD}; dotted lines: the recommendation's "
                      "bounds.")
        _layout(fig, 0.45 + 0.16 * rows)
        return _save(fig, out, "tradeoff.png")


def listener_plot(summary: Sequence[dict], out: Path) -> list[str]:
    """Draw the listener's success, turns to success, length and entrainment per setting, with intervals."""
    plt = _pyplot()
    labels = [e["setting"].label() for e in summary]
    n = max(e["n"] for e in summary)
    with _style():
        fig, axes = plt.subplots(1, len(LISTENER_PANELS), sharey=True, squeeze=False,
                                 figsize=(PAGE_WIDTH, 1.5 + 0.16 * len(summary)))
        ys = list(range(len(summary)))
        for ax, (metric, title, xlabel) in zip(axes.flat, LISTENER_PANELS):
            est = [e["estimates"][metric] for e in summary]
            ax.errorbar([e.mean for e in est], ys, xerr=[[e.mean - e.low for e in est], [e.high - e.mean for e in est]],
                        marker="o", linestyle="", color="C0")
            ax.set_xlabel(xlabel)
            ax.set_title(title)
            ax.grid(alpha=0.3, axis="x")
        first = axes.flat[0]
        first.set_yticks(ys)
        first.set_yticklabels(labels)
        first.set_ylim(len(summary) - 0.5, -0.5)
        first.set_ylabel("robot memory setting")
        fig.suptitle("The listener: success, turns to success, length and entrainment per setting")
        _caption(fig, "Success: share of robot turns whose referent the listener identified, repairs included; "
                      "turns to success: attempts over the identified ones; length said: properties the robot said "
                      "per turn, repairs included; entrainment: Dice with the human's last description of the "
                      f"referent. Points: means over n = {n} games; bars: {METHOD}.")
        _layout(fig)
        return _save(fig, out, "listener.png")


def sweep_plots(rows: Sequence[dict], summary: Sequence[dict], curves: Mapping[tuple, Sequence[int]], out: Path,
                dynamic: bool = False, listener: bool = False) -> list[str]:
    """Write the sweep's plots (PNG and PDF each) into ``out``; return their file names (each written once)."""
    files = []
    none = next((e for e in summary if e["setting"].policy == "none"), None)
    for policy in dict.fromkeys(_group(e["setting"]) for e in summary):
        if policy == "none":
            continue
        entries = [e for e in summary if _group(e["setting"]) == policy]
        files += policy_plot(policy, entries, none, out, dynamic)
    files += divergence_plot(curves, out)
    if dynamic and any(e["setting"].policy != "none" for e in summary):
        files += tradeoff_plot(summary, out, BOUNDS)
    if listener:
        files += listener_plot(summary, out)
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


def named_segments(events: Sequence[Mapping[str, Any]], result: Optional[Mapping[str, Any]] = None) -> list[Segment]:
    """Return :func:`wm_segments` with each stay's encoding named as the alignment table names origins.

    ``speaker`` becomes ``human-speech`` or ``robot-speech`` (the turn's speaker, from
    ``result``, else: a turn in which RR encoded anything is a human turn); an ``rr``
    entry of a property the human said of the turn's referent is ``human-speech``
    (:func:`fsreg_ros.core.algorithms.alignment.origin_name`): RR affirms the human's words for
    every candidate before rule 1 encodes them for the referent, so the stay of the
    referent's property began with RR, but it is the human's own words.  ``rr`` is
    left for what RR affirmed of the other candidates.
    """
    from ..core.algorithms.alignment import origin_name

    turns: dict[Any, dict] = {}
    if result is not None:
        turns = {t.get("turn"): dict(t) for t in result.get("turns", ())}
    else:  # from the events alone: rule 1 encodes the human's words for the referent (cause speaker)
        rr_turns = {e.get("turn") for e in events if e.get("op") == "encode" and e.get("cause") == "rr"}
        for event in events:
            turn = event.get("turn")
            if turn is None or event.get("op") != "encode":
                continue
            record = turns.setdefault(turn, {"speaker": "human" if turn in rr_turns else "robot", "description": []})
            if event.get("cause") == "speaker":
                record["target"] = event.get("entity")
                record["description"].append(event.get("property"))
    opened: dict[tuple, Any] = {}  # (domain, entity, property, start) -> the turn of the encoding that opened it
    inside: set = set()
    for event in events:
        key = (event.get("domain"), event.get("entity"), event.get("property"))
        if event.get("op") == "encode" and key not in inside:
            inside.add(key)
            opened[(*key, float(event.get("time") or 0.0))] = event.get("turn")
        elif event.get("op") == "forget":
            inside.discard(key)
    named = []
    for s in wm_segments(events):
        turn = opened.get((s.domain, s.entity, s.property, s.start))
        name = origin_name({"cause": s.encoded_by, "turn": turn}, s.property, s.entity, turns)
        named.append(Segment(s.domain, s.entity, s.property, s.start, s.end, name, s.forgotten_by))
    return named


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
    """Draw the WM timeline of ``events`` into ``out`` and the same name in the other format (PNG, PDF).

    Returns the segments drawn, each encoding named as the alignment table names
    origins (:func:`named_segments`).

    ``entities`` keeps those entities' lanes only; ``top`` keeps the N lanes longest in WM.
    """
    turns = turn_times(events, result)
    every = named_segments(events, result)
    last = max([s.end or s.start for s in every] + [t for t, _, _ in turns] + [1.0])
    end_of_plot = last * 1.05
    segments = select_lanes(every, entities, top, end_of_plot)
    lanes: dict[tuple, int] = {}
    for s in sorted(segments, key=lambda s: (s.domain, _natural(s.entity), s.property)):
        lanes.setdefault((s.domain, s.entity, s.property), len(lanes))
    plt = _pyplot()
    with _style():
        fig, ax = plt.subplots(figsize=(PAGE_WIDTH, max(2.4, 0.12 * len(lanes) + 1.4)))
        _draw_timeline(plt, fig, ax, segments, every, lanes, turns, end_of_plot, result, title)
        fig.tight_layout()
        other = out.with_suffix(".png" if out.suffix.lower() == ".pdf" else ".pdf")
        fig.savefig(out, dpi=DPI)
        fig.savefig(other, dpi=DPI)
        plt.close(fig)
    return segments


def _draw_timeline(plt, fig, ax, segments, every, lanes, turns, end_of_plot, result, title) -> None:
    """Draw a timeline's stays, turns and legend on ``ax`` (see :func:`wm_timeline`)."""
    causes: dict[str, None] = {}
    for s in segments:
        y = lanes[(s.domain, s.entity, s.property)]
        stop = s.end if s.end is not None else end_of_plot
        ax.broken_barh([(s.start, max(stop - s.start, 1e-3))], (y - 0.35, 0.7), color="lightsteelblue")
        ax.plot(s.start, y, marker=">", color=CAUSE_COLOURS.get(s.encoded_by, "magenta"), markersize=4)
        causes[s.encoded_by] = None
        if s.forgotten_by is not None:
            ax.plot(stop, y, marker="x", color=CAUSE_COLOURS.get(s.forgotten_by, "magenta"), markersize=4)
            causes[s.forgotten_by] = None
    speakers: dict[Any, None] = {}
    for time, turn, speaker in turns:
        colour, style = TURN_STYLE.get(speaker, TURN_STYLE[None])
        speakers[speaker] = None
        ax.axvline(time, color=colour, linestyle=style, linewidth=0.9)
        if turn is not None:  # the turn number above the lanes: H3 = human turn 3, R4 = robot turn 4
            mark = {"human": "H", "robot": "R"}.get(str(speaker), "")
            ax.text(time, -1.0, f"{mark}{turn}", color="black", fontsize=5.5, ha="center", va="bottom")
    if lanes:
        ax.set_yticks(range(len(lanes)))
        ax.set_yticklabels([f"{entity}: {prop}" for (_, entity, prop) in lanes], fontsize=5.5)
        ax.set_ylim(len(lanes), -2.0)
    else:
        ax.set_yticks([])
        ax.set_ylim(1, -2.0)
        ax.text(end_of_plot / 2, 0.2, empty_reason(result) if not every else empty_reason(None), ha="center",
                va="center", fontsize=8)
    ax.set_xlim(0, end_of_plot)
    ax.set_xlabel("time (s); vertical lines: the dialogue's turns (H = human, R = robot), numbered on top")
    ax.set_ylabel("entity: property (one lane each)")
    handles = [plt.Line2D([], [], marker="o", linestyle="", color=CAUSE_COLOURS.get(c, "magenta"), label=c)
               for c in sorted(causes, key=lambda c: list(CAUSE_COLOURS).index(c) if c in CAUSE_COLOURS else 99)]
    handles += [plt.Line2D([], [], color=TURN_STYLE[s][0], linestyle=TURN_STYLE[s][1],
                           label={"human": "human turn", "robot": "robot turn"}.get(s, "turn"))
                for s in speakers if s in TURN_STYLE]
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False,
                  title="cause (> encode, x forget)" if causes else None)
    shown = f"{len(lanes)} of {len({(s.domain, s.entity, s.property) for s in every})} lanes"
    ax.set_title((title or "Working memory over time") + (f" ({shown})" if len(lanes) < len(set(
        (s.domain, s.entity, s.property) for s in every)) else ""))


def _natural(name: str) -> tuple:
    digits = "".join(ch for ch in name if ch.isdigit())
    return (name.rstrip("0123456789"), int(digits) if digits else -1, name)
