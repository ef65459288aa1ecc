"""Merging finished sweeps: shards of one split (``--shard K/N``) or sweeps of disjoint seeds, as one sweep.

``fsreg-sweep merge OUT DIR...`` (:func:`merge`) checks that the inputs are finished
sweeps of one configuration, code and columns whose seeds do not overlap, then writes
the files one sweep would (:func:`fsreg_ros.research.sweep.write_results`) and a
manifest recording every shard.
"""

from __future__ import annotations

import json
import os
from dataclasses import fields
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

from ..core.io.input_file import InputFileError, read_text
from .ledger import Ledger, LedgerError, code_label, difference
from .listener import ListenerOptions
from .sweep import SweepConfig, assemble, manifest, write_results


def _config_from(configuration: Mapping[str, Any], seeds: Sequence[int]) -> SweepConfig:
    """Rebuild a SweepConfig from a games file's configuration (JSON lists back to tuples)."""
    values = {}
    for f in fields(SweepConfig):
        if f.name == "seeds":
            continue
        value = configuration.get(f.name)
        if f.name == "listener" and value is not None:  # a ListenerOptions, as a JSON object
            value = ListenerOptions(**value)
        values[f.name] = tuple(value) if isinstance(value, list) else value
    return SweepConfig(seeds=tuple(seeds), **values)


def merge(out: Path, shards: Sequence[Path], plots: bool = True,
          argv: Optional[Sequence[str]] = None) -> tuple[list[dict], list[dict], SweepConfig]:
    """Combine finished sweeps of one configuration and code into ``out``, as if run as one sweep.

    The inputs are shards (``--shard K/N``: every K of one N) or sweeps of disjoint seeds;
    LedgerError names the first input that is unfinished, of another configuration,
    another code or columns, or whose seeds overlap another's.  Writes the same files
    as :func:`run` (runs.csv, summary.csv and the intervals byte-identical to one
    sweep's), games.jsonl and a manifest recording every shard.
    """
    if not shards:
        raise LedgerError("merge: give at least one sweep directory")
    resolved = [Path(d).resolve() for d in shards]
    if Path(out).resolve() in resolved:
        raise LedgerError(f"merge: the output {out} is one of the inputs")
    if len(set(resolved)) != len(resolved):
        raise LedgerError("merge: a directory is given twice")
    books, manifests = [], []
    for directory in shards:
        written = Path(directory) / "manifest.json"
        if not os.path.lexists(written):
            raise LedgerError(f"merge: {directory} is not a finished sweep (no manifest.json); finish it with its "
                              "command and --resume")
        try:
            done = json.loads(read_text(written))
        except InputFileError as err:
            raise LedgerError(f"merge: {err}") from None
        except (json.JSONDecodeError, RecursionError):
            raise LedgerError(f"merge: {directory}/manifest.json is not JSON") from None
        book = Ledger.read(Path(directory))
        if book.missing():
            raise LedgerError(f"merge: {directory} is not finished ({len(book.missing())} of "
                              f"{len(book.header['seeds'])} games missing); finish it with --resume")
        books.append(book)
        manifests.append(done)
    first, name0 = books[0].header, shards[0]
    owner: dict[int, Path] = {}
    for book, directory in zip(books, shards):
        head = book.header
        if head["configuration"] != first["configuration"]:
            raise LedgerError(f"merge: {directory} and {name0} are sweeps of different configurations: "
                              f"{difference(head['configuration'], first['configuration'])}")
        if head["code"] != first["code"]:
            raise LedgerError(f"merge: {directory} and {name0} ran different code: {code_label(head['code'])} vs "
                              f"{code_label(first['code'])}")
        if head["columns"] != first["columns"]:
            raise LedgerError(f"merge: {directory} and {name0} have different runs.csv columns")
        overlap = sorted(s for s in head["seeds"] if s in owner)
        if overlap:
            shown = ", ".join(map(str, overlap[:5])) + (", ..." if len(overlap) > 5 else "")
            raise LedgerError(f"merge: {directory} and {owner[overlap[0]]} overlap: both have seed"
                              f"{'s' if len(overlap) > 1 else ''} {shown}")
        owner.update({s: directory for s in head["seeds"]})
    _check_split([m.get("execution", {}).get("shard") for m in manifests], shards)
    seeds = sorted(owner)
    config = _config_from(first["configuration"], seeds)
    out.mkdir(parents=True, exist_ok=True)
    (out / "manifest.json").unlink(missing_ok=True)
    merged = Ledger.start(out, {**first, "seeds": seeds})
    try:
        for seed in seeds:
            merged.append(next(b.games[seed] for b in books if seed in b.games))
    finally:
        merged.close()
    rows, curves, hashes = assemble(merged.games, seeds)
    summary, files = write_results(config, out, rows, curves, plots)
    execution = {"engine": "merge", "shards": [
        {"directory": str(directory), "shard": (m.get("execution") or {}).get("shard"),
         "execution": {k: v for k, v in (m.get("execution") or {}).items() if k != "shard"},
         "games": len(b.header["seeds"]), "seeds": [min(b.header["seeds"]), max(b.header["seeds"])],
         "command": m.get("command"), "started": m.get("started"), "finished": m.get("finished"),
         "git": m.get("git"), "environment": m.get("environment")}
        for directory, b, m in zip(shards, books, manifests)]}
    started = min((m.get("started") or "") for m in manifests)
    (out / "manifest.json").write_text(json.dumps(
        manifest(config, hashes, 0, files, len(rows), started, argv, manifests[0].get("git"), execution,
                 command="fsreg-sweep merge"), indent=2) + "\n")
    return rows, summary, config


def _check_split(records: Sequence[Optional[dict]], shards: Sequence[Path]) -> None:
    """Refuse shards of different splits, or a split with a shard missing (sweeps that are no shards pass)."""
    split = [r for r in records if r]
    if not split:
        return
    if len(split) != len(records):
        loose = next(d for d, r in zip(shards, records) if not r)
        raise LedgerError(f"merge: {loose} is no shard (no --shard) but other inputs are; merge shards of one "
                          "split, or sweeps without --shard")
    kinds = {(r["count"], tuple(r["all_seeds"])) for r in split}
    if len(kinds) > 1:
        raise LedgerError("merge: shards of different splits: " + ", ".join(
            f"{d} is {r['shard']} of seeds {r['all_seeds'][0]}-{r['all_seeds'][1] - 1}" for d, r in zip(shards, split)))
    count = split[0]["count"]
    missing = sorted(set(range(1, count + 1)) - {r["index"] for r in split})
    if missing:
        raise LedgerError(f"merge: shard{'s' if len(missing) > 1 else ''} "
                          f"{', '.join(f'{k}/{count}' for k in missing)} missing")
