"""Sweep forgetting settings over many generated Guess-Who games.

Every seed is one game (:func:`fsreg_ros.research.games.make_game`); it is played
once under policy ``none`` (the No-WM baseline) and once per setting.  Each policy
runs over the grid of the parameters *it reads* and no other (``decay`` over decay
periods, ``displacement`` over capacities, ``decay+displacement`` over both, ...),
so no two runs of a sweep are the same run; with fact changes (``changes`` > 0) the
robot's WM is either told of them or not (``retraction``).  Seeds are independent
tasks run on any engine of :mod:`fsreg_ros.research.execution` (local processes or a
Dask cluster); a seed's rows depend only on the seed and the settings, and each
finished game is kept in ``games.jsonl`` (:mod:`fsreg_ros.research.ledger`) as it
arrives, so ``runs.csv`` is the same for any engine, after ``--resume``, and for
shards combined by :func:`merge`.

Metrics per game and setting (:data:`METRICS`; over the robot's turns):

* ``entrainment`` (the headline): mean Dice of the robot's description with the
  human's most recent description of the same referent, over the turns whose
  referent the human had described (:mod:`fsreg_ros.core.algorithms.alignment`);
  ``entrainment_gain``: minus the same game's under ``none``, paired by turn;
* ``recall`` of the human's last description; ``share``: share of the robot's
  properties the human had used for the referent (pooled), ``share_gain``;
  ``aligned_per_description``; ``length_matched_gain``: the gain in aligned
  properties on the turns where both runs' descriptions are as long;
* ``mean_length``, ``length_change`` (minus none's), ``overspecification``: mean of
  (length - length of the shortest distinguishing description then, Full Brevity);
  ``distinguishing_rate``;
* ``mean_wm_occupancy``: properties in the target domain's WM just before the turn;
* ``divergence``: share of robot turns whose description (as a set) differs from
  the one under ``none``; ``divergence_kK``: the same over the first K robot turns;
* ``outdated_rate``: share of the robot's properties that no longer held for the
  referent when said; ``outdated_descriptions``: share of descriptions with one;
* ``from_wm_share`` and, of the properties taken from WM, the share each origin put there.

With a listener (``SweepConfig.listener``, :mod:`fsreg_ros.research.listener`) each
row also has :data:`LISTENER_METRICS`: ``success`` (share of robot turns whose
referent the listener identified, repairs included), ``first_success`` (at the
first attempt), ``turns_to_success`` (mean attempts over the turns that succeeded),
``final_length`` (properties in the description last heard), ``said_length``
(properties the robot said, repairs included), ``repairs`` (per robot turn) and,
when a second fsreg agent plays the human (robot-robot), ``partner_resolved``: the
share of its descriptions the robot resolved to their referent.  Without a listener
the files are exactly as before.

:func:`summarise_runs` gives each setting's means with bootstrap intervals over
games (:mod:`fsreg_ros.research.stats`), and :func:`recommend` the follow-up study's
table: per WM configuration, the setting with the most entrainment whose outdated
rate stays within a bound.
"""

from __future__ import annotations

import csv
import json
import shlex
import sys
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from itertools import product
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

from ..core.algorithms.alignment import ORIGINS, entrainment_gain, length_matched
from ..core.forgetting.policies import RULE_PARAMETERS, parse_rules
from ..core.lexicon import Lexicon
from ..core.forgetting.settings import setting as memory_setting
from .execution import Engine, TaskRun, run_tasks
from .games import BOARD_SIZE, DOMAIN, make_game, play, scenario_of
from .grid import BOUNDS, DEFAULT_WM_ORDER, GRID, NUMERIC, axes
from .ledger import GAMES, GameRecord, Ledger, LedgerError, header
from .listener import ListenerOptions
from .provenance import environment, git_state, package_version
from .repetition import METRICS as REPETITION_METRICS, lengths_by_repetition
from .stats import METHOD, Estimate, bootstrap_ci

CHECKPOINTS = (10, 25, 50, 100)
METRICS = (
    "entrainment",
    "entrainment_gain",
    "recall",
    "share",
    "share_gain",
    "aligned_per_description",
    "length_matched_gain",
    "mean_length",
    "length_change",
    "overspecification",
    "distinguishing_rate",
    "mean_wm_occupancy",
    "divergence",
    "outdated_rate",
    "outdated_descriptions",
) + REPETITION_METRICS
#: Metrics of the listener (only with one; ``partner_resolved`` only in robot-robot mode).
LISTENER_METRICS = ("success", "first_success", "turns_to_success", "final_length", "said_length", "repairs")
PARTNER_METRICS = ("partner_resolved",)
COLUMNS = (
    ("policy", "wm") + GRID + ("retraction", "seed", "turns", "robot_turns", "described_turns",
                               "length_matched_turns")
    + METRICS
    + tuple(f"divergence_k{k}" for k in CHECKPOINTS)
    + ("from_wm_share",) + tuple(f"from_{o}" for o in ORIGINS)
    + ("gap", "human_order")
)
#: Parameters each grid policy reads come from the rules (``seed`` is drawn per game).
WORLD_DEFAULT = "faces"


@dataclass(frozen=True)
class SweepConfig:
    """Every parameter of a sweep (written to manifest.json)."""

    policies: tuple
    decay_periods: tuple
    capacities: tuple
    seeds: tuple
    turns: int
    global_capacities: tuple = (4, 8, 16)
    shared_capacities: tuple = (4, 8, 16)
    activation_thresholds: tuple = (-1.5, -1.15, -0.8)  # d = 0.5: one encoding stays 20, 10, 5 s
    episode_windows: tuple = (1, 2, 3, 4)  # k, for rule episodes
    activation_clocks: tuple = ()  # the clocks rule activation runs on (none given: its fallback, no column)
    wm_orders: tuple = (DEFAULT_WM_ORDER,)  # REG's order of the target's WM (every non-none policy runs each)
    memory: dict = field(default_factory=dict)  # extra memory settings for every non-none run
    human_memory: Optional[dict] = None  # the human's own WM settings (None: a no-WM human)
    board_size: int = BOARD_SIZE
    world: str = WORLD_DEFAULT
    changes: float = 0.0  # fact changes per 100 turns (0: static games)
    retraction: tuple = (True,)  # the robot's WM told of LTM changes (True), not told (False)
    wm_belief: bool = False  # REG takes the target's WM as true (games.BeliefPort)
    gap_range: tuple = (2.0, 12.0)
    listener: Optional[ListenerOptions] = None  # who resolves the robot's descriptions (None: nobody, as before)

    def values(self, parameter: str) -> tuple:
        """Return the grid's values of one parameter."""
        return {"decay_period": self.decay_periods, "capacity": self.capacities,
                "global_capacity": self.global_capacities, "shared_capacity": self.shared_capacities,
                "activation_threshold": self.activation_thresholds, "episode_window": self.episode_windows,
                "activation_clock": self.activation_clocks}[parameter]


@dataclass(frozen=True)
class Setting:
    """One robot setting of the grid: a policy, the parameters it reads, WM told of LTM changes or not, REG's order."""

    policy: str
    decay_period: Optional[float] = None
    capacity: Optional[int] = None
    global_capacity: Optional[int] = None
    shared_capacity: Optional[int] = None
    activation_threshold: Optional[float] = None
    activation_clock: Optional[str] = None
    episode_window: Optional[int] = None
    retraction: bool = True
    wm_order: str = DEFAULT_WM_ORDER

    @property
    def wm(self) -> str:
        """The WM configuration: one pool per domain or one shared by all, told of LTM changes or not."""
        pool = "shared" if self.policy != "none" and "shared-capacity" in parse_rules(self.policy) else "per-domain"
        return pool if self.retraction else f"{pool}, not told"

    def parameters(self) -> dict:
        """Return the grid parameters this setting sets (the ones its policy reads)."""
        return {p: getattr(self, p) for p in NUMERIC if getattr(self, p) is not None}

    def memory(self, extra: dict, seed: int = 0) -> dict:
        """Return the memory settings a simulation of game ``seed`` gets for this setting.

        Random displacement draws from the game's seed unless ``extra`` names one, so
        every game is reproducible on its own.
        """
        if self.policy == "none":
            return {"policy": "none"}
        out = dict(extra)
        out.update(policy=self.policy, **self.parameters())
        if "displacement-random" in parse_rules(self.policy) and "seed" not in extra:
            out["seed"] = seed
        return out

    def label(self) -> str:
        """Return e.g. ``decay delta=10``, ``displacement alpha=2 (not told)`` or ``episodes k=1, strength order``."""
        params = ", ".join(f"{memory_setting(p).word}={_number(v)}" for p, v in self.parameters().items())
        text = f"{self.policy} {params}".strip()
        if self.wm_order != DEFAULT_WM_ORDER:
            text += f"{',' if params else ''} {self.wm_order} order"
        return text if self.retraction else f"{text} (not told)"


def _number(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def reads(policy: str, extra: dict) -> tuple:
    """Return the grid parameters read by a policy, in column order (:data:`~.grid.NUMERIC`); ``extra`` fixes some."""
    if policy == "none":
        return ()
    wanted = {p for rule in parse_rules(policy) for p in RULE_PARAMETERS[rule]}
    return tuple(p for p in NUMERIC if p in wanted and p not in extra)


def settings(config: SweepConfig) -> list[Setting]:
    """Return the grid: each policy over the parameters it reads (``none`` once), each WM told or not, each WM order.

    Retraction is a dimension only when facts change (``changes`` > 0), and never for
    ``none``; nor is REG's WM order (``none`` has no WM to order).
    """
    told = config.retraction if config.changes > 0 else (True,)
    out = []
    for policy in config.policies:
        if policy == "none":
            out.append(Setting("none"))
            continue
        names = tuple(p for p in reads(policy, config.memory) if config.values(p))  # (no clocks given: no axis)
        for values in product(*(config.values(p) for p in names)):
            for retraction, order in product(told, config.wm_orders):
                out.append(Setting(policy, retraction=retraction, wm_order=order, **dict(zip(names, values))))
    return out


def check(config: SweepConfig) -> None:
    """Raise a one-line error if any setting of the grid is invalid (before any game runs)."""
    scenario = scenario_of(make_game(0, 2, board_size=config.board_size, world=config.world))
    for setting in settings(config):
        for domain in scenario.domains:
            scenario.policy_for(domain, setting.memory(config.memory))
    if config.human_memory is not None:
        scenario.policy_for(DOMAIN, config.human_memory)
    listener = config.listener
    if listener is not None and listener.partner_memory is not None:
        scenario.policy_for(DOMAIN, listener.partner_memory)


def metrics(config: SweepConfig) -> tuple:
    """Return the metrics a sweep summarises: :data:`METRICS`, and the listener's when it has one."""
    if config.listener is None:
        return METRICS
    return METRICS + LISTENER_METRICS + (PARTNER_METRICS if config.listener.partner == "robot" else ())


def columns(config: SweepConfig) -> tuple:
    """Return runs.csv's columns: :data:`COLUMNS` (with the sweep-only axes it uses), then the listener's metrics."""
    grid = axes(settings(config))
    return COLUMNS[:2] + grid + COLUMNS[2 + len(GRID):] + metrics(config)[len(METRICS):]


def listener_metrics(played) -> dict:
    """Return one game's listener metrics (:data:`LISTENER_METRICS`, and ``partner_resolved``) from a played game."""
    heard = played.heard or []
    succeeded = [h for h in heard if h.success]
    row = {
        "success": _share([int(h.success) for h in heard]),
        "first_success": _share([int(h.turns == 1) for h in heard]),
        "turns_to_success": _share([h.turns for h in succeeded]) if succeeded else None,
        "final_length": _share([h.final_length for h in heard]),
        "said_length": _share([h.said for h in heard]),
        "repairs": _share([len(h.repairs) for h in heard]),
    }
    partner = [t for t in played.result["turns"] if t["speaker"] == "human"]
    row["partner_resolved"] = _share([int(t.get("resolved") == t.get("target")) for t in partner])
    return row


def _descriptions(played) -> list:
    return [frozenset(t["description"] or ()) for t in played.result["turns"] if t["speaker"] == "robot"]


def _share(values: Sequence[float]) -> float:
    return sum(values) / len(values) if values else 0.0


def run_seed(task: tuple) -> tuple[list[dict], dict, str]:
    """Play one seed's game under ``none`` and every setting; return rows, divergence curves, KB hash."""
    config, seed = task
    lexicon = Lexicon.load()
    game = make_game(seed, config.turns, config.gap_range, config.board_size, config.world, config.changes)
    options = dict(human_memory=config.human_memory, wm_belief=config.wm_belief, listener=config.listener)
    baseline = play(game, {"policy": "none"}, lexicon, **options)
    base_descriptions = _descriptions(baseline)
    base_length = baseline.alignment.mean_length
    rows, curves = [], {}
    for setting in settings(config):
        played = (
            baseline if setting.policy == "none"
            else play(game, setting.memory(config.memory, seed), lexicon, retract=setting.retraction,
                      wm_order=setting.wm_order, **options)
        )
        summary = played.alignment
        robot = [t for t in played.result["turns"] if t["speaker"] == "robot"]
        flags = [int(a != b) for a, b in zip(_descriptions(played), base_descriptions)]
        lengths = [len(t["description"] or ()) for t in robot]
        delta, _ = entrainment_gain(summary, baseline.alignment)
        matched, matched_turns = length_matched(summary, baseline.alignment)
        outdated = sum(len(o) for o in played.outdated)
        row: dict[str, Any] = {
            "policy": setting.policy,
            "wm": setting.wm,
            **{p: getattr(setting, p) for p in NUMERIC},
            "wm_order": setting.wm_order,
            "retraction": "on" if setting.retraction else "off",
            "seed": seed,
            "turns": config.turns,
            "robot_turns": len(robot),
            "described_turns": len(summary.described),
            "length_matched_turns": matched_turns,
            "entrainment": summary.entrainment,
            "entrainment_gain": delta,
            "recall": summary.recall,
            "share": summary.alignment,
            "share_gain": summary.alignment - baseline.alignment.alignment,
            "aligned_per_description": summary.aligned / len(robot) if robot else 0.0,
            "length_matched_gain": matched,
            "mean_length": summary.mean_length,
            "length_change": summary.mean_length - base_length,
            "overspecification": _share([n - s for n, s in zip(lengths, game.shortest)]),
            "distinguishing_rate": _share([int(bool(t["distinguishing"])) for t in robot]),
            "mean_wm_occupancy": _share(played.wm_sizes),
            "divergence": _share(flags),
            "outdated_rate": outdated / summary.properties if summary.properties else 0.0,
            "outdated_descriptions": _share([int(bool(o)) for o in played.outdated]),
            **lengths_by_repetition(played.result["turns"]),
            "from_wm_share": summary.wm_share,
            "gap": game.gap,
            "human_order": " ".join(game.human_order),
        }
        for origin in ORIGINS:
            row[f"from_{origin}"] = summary.origins.get(origin, 0) / summary.from_wm if summary.from_wm else None
        for k in CHECKPOINTS:
            row[f"divergence_k{k}"] = _share(flags[:k]) if len(flags) >= k else None
        if config.listener is not None:
            row.update(listener_metrics(played))
        rows.append(row)
        curves[setting] = flags
    return rows, curves, game.kb_hash()


def record_of(seed: int, result: tuple) -> GameRecord:
    """Return :func:`run_seed`'s result as a game record (per row, its divergence flags as ``0``/``1``)."""
    rows, curves, kb_hash = result
    return GameRecord(seed, kb_hash, tuple(rows), tuple("".join(map(str, flags)) for flags in curves.values()))


def assemble(records: Mapping[int, GameRecord], seeds: Sequence[int]) -> tuple[list[dict], dict, dict]:
    """Return rows, divergence curves and KB hashes of the games of ``seeds``, in that order."""
    rows, curves, hashes = [], {}, {}
    for seed in seeds:
        record = records[seed]
        for row, flags in zip(record.rows, record.flags):
            rows.append(dict(row))
            curves[(setting_of(row), seed)] = [int(flag) for flag in flags]
        hashes[seed] = record.kb_sha256
    return rows, curves, hashes


def sweep(config: SweepConfig, jobs: int = 1, progress: bool = True, ledger: Optional[Ledger] = None,
          engine: Optional[Engine] = None) -> tuple[list[dict], dict, dict, TaskRun]:
    """Play every seed not yet in ``ledger`` (on ``engine``, else ``jobs`` local processes).

    Returns rows, curves and KB hashes in seed order, and the job's :class:`TaskRun`.
    ``curves`` maps (setting, seed) to the per-robot-turn divergence flags.  Each game
    is appended to ``ledger`` as it finishes and used as read back from it.
    """
    engine = engine or Engine("local", jobs)
    records: dict[int, GameRecord] = dict(ledger.games) if ledger is not None else {}
    todo = [seed for seed in config.seeds if seed not in records]

    def keep(index: int, result: tuple) -> None:
        record = record_of(todo[index], result)
        records[record.seed] = ledger.append(record) if ledger is not None else record

    job = run_tasks(run_seed, [(config, seed) for seed in todo], engine, progress=progress, desc="fsreg-sweep",
                    unit="game", done=len(config.seeds) - len(todo), on_result=keep)
    return (*assemble(records, config.seeds), job)


# ------------------------------------------------------------------ summaries
def setting_of(row: dict) -> Setting:
    """Return the setting a row of runs.csv was played under (a sweep-only axis it lacks: unset, lru-first)."""
    return Setting(row["policy"], **{p: row.get(p) for p in NUMERIC}, retraction=row["retraction"] == "on",
                   wm_order=row.get("wm_order") or DEFAULT_WM_ORDER)


def summarise_runs(rows: Sequence[dict], metrics: Sequence[str] = METRICS) -> list[dict]:
    """Return one entry per setting (grid order): its setting, n games and each metric's :class:`Estimate`."""
    by_setting: dict[Setting, list[dict]] = {}
    for row in rows:
        by_setting.setdefault(setting_of(row), []).append(row)
    return [
        {"setting": setting, "n": len(mine),
         "estimates": {m: bootstrap_ci([r[m] for r in mine if r[m] is not None]) for m in metrics}}
        for setting, mine in by_setting.items()
    ]


def write_summary(path: Path, summary: Sequence[dict]) -> None:
    """Write summary.csv: per setting, n games and each metric's mean and 95 % bootstrap interval."""
    metrics = list(summary[0]["estimates"]) if summary else []
    grid = axes(e["setting"] for e in summary)
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(["policy", "wm", *grid, "retraction", "games"]
                        + [f"{m}{suffix}" for m in metrics for suffix in ("", "_low", "_high")])
        for entry in summary:
            s: Setting = entry["setting"]
            cells = [s.policy, s.wm, *(_cell(getattr(s, p)) for p in grid), "on" if s.retraction else "off",
                     entry["n"]]
            for m in metrics:
                e: Estimate = entry["estimates"][m]
                cells += [_cell(e.mean), _cell(e.low), _cell(e.high)]
            writer.writerow(cells)


def recommend(summary: Sequence[dict], bounds: Sequence[float] = BOUNDS) -> list[dict]:
    """Return the follow-up study's recommendation: per WM configuration and outdated-rate bound, the best setting.

    Among the settings of one configuration (``none`` belongs to every one: no WM
    says nothing outdated) whose mean outdated rate is at most the bound, the one
    with the highest mean entrainment; ties go to the earlier setting in grid order.
    """
    configurations = list(dict.fromkeys(e["setting"].wm for e in summary if e["setting"].policy != "none"))
    none = [e for e in summary if e["setting"].policy == "none"]
    out = []
    for wm in configurations:
        candidates = [e for e in summary if e["setting"].wm == wm and e["setting"].policy != "none"] + none
        for bound in bounds:
            allowed = [e for e in candidates if e["estimates"]["outdated_rate"].mean <= bound + 1e-12]
            best = max(allowed, key=lambda e: e["estimates"]["entrainment"].mean, default=None)
            out.append({"wm": wm, "bound": bound, "best": best, "considered": len(candidates),
                        "allowed": len(allowed)})
    return out


def write_recommendation(path: Path, table: Sequence[dict]) -> None:
    """Write recommendation.csv (one row per WM configuration and bound)."""
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator="\n")
        metrics = ("entrainment", "entrainment_gain", "outdated_rate")
        grid = axes(e["best"]["setting"] for e in table if e["best"] is not None)
        writer.writerow(["wm", "max_outdated_rate", "policy", *grid]
                        + [f"{m}{suffix}" for m in metrics for suffix in ("", "_low", "_high")]
                        + ["settings_allowed", "settings_considered"])
        for entry in table:
            best = entry["best"]
            if best is None:
                writer.writerow([entry["wm"], entry["bound"], "", *[""] * len(grid), *[""] * 9, 0,
                                 entry["considered"]])
                continue
            s, e = best["setting"], best["estimates"]
            cells = [_cell(x) for m in metrics for x in (e[m].mean, e[m].low, e[m].high)]
            writer.writerow([entry["wm"], entry["bound"], s.policy, *(_cell(getattr(s, p)) for p in grid), *cells,
                             entry["allowed"], entry["considered"]])


# ---------------------------------------------------------------------- files
def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6f}"
    return str(value)


def write_runs(path: Path, rows: list[dict], names: Sequence[str] = COLUMNS) -> None:
    """Write runs.csv: one row per game and setting, fixed column order (``names``) and number format."""
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(names)
        for row in rows:
            writer.writerow([_cell(row.get(c)) for c in names])


def write_curves(path: Path, curves: dict) -> None:
    """Write divergence.csv: per setting, seed and robot turn, 1 if the description differs from none's."""
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator="\n")
        grid = axes(setting for setting, _ in curves)
        writer.writerow(("policy", *grid, "retraction", "seed", "robot_turn", "diverged"))
        for (setting, seed), flags in curves.items():
            cells = [setting.policy, *(_cell(getattr(setting, p)) for p in grid),
                     "on" if setting.retraction else "off", seed]
            for j, flag in enumerate(flags, 1):
                writer.writerow((*cells, j, flag))


def manifest(config: SweepConfig, hashes: dict, jobs: Optional[int], files: Sequence[str], runs: int,
             started: str, argv: Optional[Sequence[str]] = None, git: Optional[dict] = None,
             execution: Optional[dict] = None, command: str = "fsreg-sweep") -> dict:
    """Return manifest.json's content: what ran, where, with what, every parameter, seeds, KB hashes, files.

    ``execution`` records where the games ran (engine, workers, tasks retried, games
    found done by ``--resume``, the shard) or, for a merge, every shard.
    """
    return {
        "tool": "fsreg-sweep",
        "version": package_version(),
        "command": shlex.join([*command.split(), *(sys.argv[1:] if argv is None else argv)]),
        "started": started,
        "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "git": git_state() if git is None else git,
        "environment": environment(),
        "parameters": {**{k: v for k, v in asdict(config).items() if k != "listener" or v is not None},
                       "seeds": list(config.seeds), "jobs": jobs, "checkpoints": list(CHECKPOINTS)},
        "game": {"generator": "fsreg_ros.research.games.make_game", "world": config.world,
                 "board_size": config.board_size, "turns": config.turns, "gap_range": list(config.gap_range),
                 "changes_per_100_turns": config.changes},
        "execution": execution or {},
        "intervals": METHOD,
        "distinct_runs": runs,
        "seeds": list(config.seeds),
        "kb_sha256": {str(seed): h for seed, h in hashes.items()},
        "files": list(dict.fromkeys(files)),
    }


@dataclass(frozen=True)
class Shard:
    """Shard K of N of a sweep's seeds: every N-th seed from the K-th (``--shard K/N``)."""

    index: int
    count: int
    seeds: tuple  # every seed of the whole sweep

    def mine(self) -> tuple:
        """Return this shard's seeds."""
        return tuple(self.seeds[self.index - 1::self.count])

    def record(self) -> dict:
        """Return the manifest's record of the shard."""
        return {"shard": f"{self.index}/{self.count}", "index": self.index, "count": self.count,
                "all_seeds": [self.seeds[0], self.seeds[-1] + 1] if self.seeds else []}


def write_results(config: SweepConfig, out: Path, rows: list[dict], curves: dict, plots: bool) -> tuple[list, list]:
    """Write the result files and plots of a sweep's rows; return the summary and the files written.

    runs.csv, divergence.csv, summary.csv, recommendation.csv (dynamic games), the PNGs.
    """
    summary = summarise_runs(rows, metrics(config))
    write_runs(out / "runs.csv", rows, columns(config))
    write_curves(out / "divergence.csv", curves)
    write_summary(out / "summary.csv", summary)
    files = ["runs.csv", "divergence.csv", "summary.csv"]
    if config.changes > 0:
        write_recommendation(out / "recommendation.csv", recommend(summary))
        files.append("recommendation.csv")
    if plots:
        from .plot import sweep_plots

        files += sweep_plots(rows, summary, curves, out, dynamic=config.changes > 0,
                             listener=config.listener is not None)
    return summary, files + [GAMES]


def run(config: SweepConfig, out: Path, jobs: int = 1, progress: bool = True, plots: bool = True,
        argv: Optional[Sequence[str]] = None, engine: Optional[Engine] = None, resume: bool = False,
        shard: Optional[Shard] = None) -> tuple[list[dict], list[dict], dict]:
    """Run a sweep and write runs.csv, divergence.csv, summary.csv, games.jsonl, manifest.json and the plots.

    Every game goes to ``out/games.jsonl`` as it finishes; ``resume`` plays only the
    games missing there (the same sweep, same code, else :class:`LedgerError`), and
    without it an earlier games file in ``out`` is replaced.  manifest.json is written
    last (a directory with one holds a finished sweep).  Returns the rows, the
    per-setting summary and the manifest's execution record.
    """
    check(config)
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    out.mkdir(parents=True, exist_ok=True)
    code = git_state(exclude=[out])
    head = header(config, columns(config), code)
    if resume and (out / GAMES).exists():
        book = Ledger.resume(out, head)
    else:
        _refuse_to_discard(out)
        book = Ledger.start(out, head)
    (out / "manifest.json").unlink(missing_ok=True)  # written again when this sweep has finished
    resumed = len(book.games)
    try:
        rows, curves, hashes, job = sweep(config, jobs, progress, book, engine)
    finally:
        book.close()
    summary, files = write_results(config, out, rows, curves, plots)
    execution = {**job.describe(), "resumed_games": resumed, "played_games": len(config.seeds) - resumed,
                 "shard": shard.record() if shard is not None else None}
    (out / "manifest.json").write_text(json.dumps(
        manifest(config, hashes, job.engine.workers if job.engine.kind == "local" else None, files, len(rows),
                 started, argv, code, execution), indent=2) + "\n")
    return rows, summary, execution


def _refuse_to_discard(out: Path) -> None:
    """Refuse to start afresh over an unfinished sweep's games (--resume continues it)."""
    if not (out / GAMES).exists() or (out / "manifest.json").exists():
        return
    try:
        found = Ledger.read(out)
    except LedgerError:
        return  # not a games file this version can resume: nothing to keep
    if found.games:
        raise LedgerError(f"{out} holds an unfinished sweep ({len(found.games)} of {len(found.header['seeds'])} "
                          f"games in {GAMES}): --resume continues it; to start afresh, delete {out / GAMES}")
