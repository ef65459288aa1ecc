"""Sweep forgetting settings over many generated Guess-Who games.

Every seed is one game (:func:`fsreg_ros.research.games.make_game`); it is played
once under policy ``none`` (the No-WM baseline) and once per setting (policy x
decay period x capacity).  Seeds run in parallel worker processes; a seed's rows
depend only on the seed and the settings, so ``runs.csv`` is the same for any
``--jobs``.

Metrics per game and setting (pooled over the robot's turns):

* ``alignment``: share of the robot's properties the human had already used for
  that referent (:mod:`fsreg_ros.core.alignment`); ``alignment_gain`` is minus
  the same game's under ``none``;
* ``mean_length``; ``overspecification``: mean of (length - length of the
  shortest distinguishing description, Full Brevity); ``distinguishing_rate``;
* ``mean_wm_occupancy``: properties in the robot's WM just before its turns;
* ``divergence``: share of robot turns whose description (as a set) differs from
  the one under ``none``; ``divergence_kK``: the same over the first K robot turns.
"""

from __future__ import annotations

import csv
import json
import multiprocessing
import subprocess
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

from ..core.forgetting import parse_rules
from ..core.lexicon import Lexicon
from .games import DOMAIN, make_game, play, scenario_of, shortest_lengths

CHECKPOINTS = (10, 25, 50, 100)
METRICS = (
    "alignment",
    "alignment_gain",
    "mean_length",
    "overspecification",
    "distinguishing_rate",
    "mean_wm_occupancy",
    "divergence",
)
COLUMNS = (
    ("policy", "decay_period", "capacity", "seed", "turns", "robot_turns")
    + METRICS
    + tuple(f"divergence_k{k}" for k in CHECKPOINTS)
    + ("from_wm_share", "gap", "human_order")
)


@dataclass(frozen=True)
class SweepConfig:
    """Every parameter of a sweep (written to manifest.json)."""

    policies: tuple
    decay_periods: tuple
    capacities: tuple
    seeds: tuple
    turns: int
    memory: dict = field(default_factory=dict)  # extra memory settings for every non-none run
    human_memory: Optional[dict] = None  # the human's own WM settings (None: a no-WM human)


@dataclass(frozen=True)
class Setting:
    """One robot memory setting of the grid (``none`` has no parameters)."""

    policy: str
    decay_period: Optional[float] = None
    capacity: Optional[int] = None

    def memory(self, extra: dict, seed: int = 0) -> dict:
        """Return the memory settings a simulation of game ``seed`` gets for this setting.

        The grid's capacity also bounds the pool rules (``global-capacity``,
        ``shared-capacity``) unless ``extra`` names their limits, and random
        displacement draws from the game's seed unless ``extra`` names one, so every
        game is reproducible on its own.
        """
        if self.policy == "none":
            return {"policy": "none"}
        out = dict(extra)
        out.update(policy=self.policy, decay_period=self.decay_period, capacity=self.capacity)
        rules = parse_rules(self.policy)
        if "global-capacity" in rules and "global_capacity" not in extra:
            out["global_capacity"] = self.capacity
        if "shared-capacity" in rules and "shared_capacity" not in extra:
            out["shared_capacity"] = self.capacity
        if "displacement-random" in rules and "seed" not in extra:
            out["seed"] = seed
        return out


def settings(config: SweepConfig) -> list[Setting]:
    """Return the grid: each policy x decay period x capacity (``none`` once)."""
    out = []
    for policy in config.policies:
        if policy == "none":
            out.append(Setting("none"))
            continue
        out += [Setting(policy, d, c) for d in config.decay_periods for c in config.capacities]
    return out


def check(config: SweepConfig) -> None:
    """Raise a one-line error if any setting of the grid is invalid (before any game runs)."""
    scenario = scenario_of(make_game(0, 2))
    for setting in settings(config):
        scenario.policy_for(DOMAIN, setting.memory(config.memory))
    if config.human_memory is not None:
        scenario.policy_for(DOMAIN, config.human_memory)


def _descriptions(played) -> list:
    return [frozenset(t["description"] or ()) for t in played.result["turns"] if t["speaker"] == "robot"]


def _share(flags: Sequence[int]) -> float:
    return sum(flags) / len(flags) if flags else 0.0


def run_seed(task: tuple) -> tuple[list[dict], dict, str]:
    """Play one seed's game under ``none`` and every setting; return rows, divergence curves, KB hash."""
    config, seed = task
    lexicon = Lexicon.load()
    game = make_game(seed, config.turns)
    shortest = shortest_lengths(game)
    baseline = play(game, {"policy": "none"}, lexicon, config.human_memory)
    base_descriptions = _descriptions(baseline)
    rows, curves = [], {}
    for setting in settings(config):
        played = (
            baseline
            if setting.policy == "none"
            else play(game, setting.memory(config.memory, seed), lexicon, config.human_memory)
        )
        robot = [t for t in played.result["turns"] if t["speaker"] == "robot"]
        summary = played.alignment
        flags = [int(a != b) for a, b in zip(_descriptions(played), base_descriptions)]
        lengths = [len(t["description"] or ()) for t in robot]
        row: dict[str, Any] = {
            "policy": setting.policy,
            "decay_period": setting.decay_period,
            "capacity": setting.capacity,
            "seed": seed,
            "turns": config.turns,
            "robot_turns": len(robot),
            "alignment": summary.alignment,
            "alignment_gain": summary.alignment - baseline.alignment.alignment,
            "mean_length": _share(lengths),
            "overspecification": _share([n - shortest[t["target"]] for n, t in zip(lengths, robot)]),
            "distinguishing_rate": _share([int(bool(t["distinguishing"])) for t in robot]),
            "mean_wm_occupancy": _share([t.wm_size for t in summary.turns]),
            "divergence": _share(flags),
            "from_wm_share": summary.wm_share,
            "gap": game.gap,
            "human_order": " ".join(game.human_order),
        }
        for k in CHECKPOINTS:
            row[f"divergence_k{k}"] = _share(flags[:k]) if len(flags) >= k else None
        rows.append(row)
        curves[(setting.policy, setting.decay_period, setting.capacity, seed)] = flags
    return rows, curves, game.kb_hash()


def sweep(config: SweepConfig, jobs: int = 1, progress: bool = True) -> tuple[list[dict], dict, dict]:
    """Run every seed (in ``jobs`` processes); return rows, curves and KB hashes, in seed order."""
    from tqdm import tqdm

    tasks = [(config, seed) for seed in config.seeds]
    bar = tqdm(total=len(tasks), desc="fsreg-sweep", unit="game", disable=not progress)
    rows, curves, hashes = [], {}, {}
    try:
        if jobs <= 1:
            results = map(run_seed, tasks)
            pool = None
        else:
            pool = multiprocessing.get_context("fork").Pool(jobs)
            results = pool.imap(run_seed, tasks)  # ordered: seed order whatever the worker timing
        for (seed_rows, seed_curves, kb_hash), (_, seed) in zip(results, tasks):
            rows += seed_rows
            curves.update(seed_curves)
            hashes[seed] = kb_hash
            bar.update(1)
        if pool is not None:
            pool.close()
            pool.join()
    finally:
        bar.close()
    return rows, curves, hashes


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6f}"
    return str(value)


def write_runs(path: Path, rows: list[dict]) -> None:
    """Write runs.csv: one row per game and setting, fixed column order and number format."""
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(COLUMNS)
        for row in rows:
            writer.writerow([_cell(row.get(c)) for c in COLUMNS])


def write_curves(path: Path, curves: dict) -> None:
    """Write divergence.csv: per setting, seed and robot turn, 1 if the description differs from none's."""
    with path.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(("policy", "decay_period", "capacity", "seed", "robot_turn", "diverged"))
        for (policy, period, capacity, seed), flags in curves.items():
            for j, flag in enumerate(flags, 1):
                writer.writerow((policy, _cell(period), _cell(capacity), seed, j, flag))


def git_commit() -> Optional[str]:
    """Return the repository's HEAD commit, or None outside a git checkout."""
    try:
        done = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True, text=True, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return (done.stdout.strip() or None) if done.returncode == 0 else None


def package_version() -> str:
    """Return fsreg_ros's installed version (or "unknown")."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fsreg_ros")
    except PackageNotFoundError:
        return "unknown"


def manifest(config: SweepConfig, hashes: dict, jobs: int, files: list[str]) -> dict:
    """Return manifest.json's content: version, commit, every parameter, seeds and KB hashes."""
    return {
        "tool": "fsreg-sweep",
        "version": package_version(),
        "git_commit": git_commit(),
        "parameters": {**asdict(config), "seeds": list(config.seeds), "jobs": jobs, "checkpoints": list(CHECKPOINTS)},
        "game": {"board_size": 16, "generator": "fsreg_ros.research.games.make_game"},
        "seeds": list(config.seeds),
        "kb_sha256": {str(seed): h for seed, h in hashes.items()},
        "files": files,
    }


def run(config: SweepConfig, out: Path, jobs: int = 1, progress: bool = True, plots: bool = True) -> list[dict]:
    """Run a sweep and write runs.csv, divergence.csv, manifest.json and the plots into ``out``."""
    check(config)
    out.mkdir(parents=True, exist_ok=True)
    rows, curves, hashes = sweep(config, jobs, progress)
    write_runs(out / "runs.csv", rows)
    write_curves(out / "divergence.csv", curves)
    files = ["runs.csv", "divergence.csv"]
    if plots:
        from .plot import sweep_plots

        files += sweep_plots(rows, curves, out, METRICS)
    (out / "manifest.json").write_text(json.dumps(manifest(config, hashes, jobs, files), indent=2) + "\n")
    return rows
