"""A sweep's finished games on disk: the append-only ``games.jsonl`` that ``--resume`` reads and merge combines.

The first line is the header: the sweep's configuration (every parameter but the
seeds), its seeds, the columns of runs.csv and the code that ran (commit and diff hash,
:func:`fsreg_ros.research.provenance.git_state`).  Every further line is one finished game:
its seed, knowledge-base hash, its rows (values in column order; floats exactly as
JSON round-trips them, so a summary computed from the file is the one computed from
memory) and per row the divergence flags as a string of 0 and 1.  A line is written,
flushed and fsync'd as its game finishes, in the process that collects the results,
so a kill loses at most the game being written; a torn last line is dropped when the
file is read again.  Every game a sweep writes is read back from its line before it
is used, so a fresh, a resumed and a merged sweep compute from the same values.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

GAMES = "games.jsonl"
FORMAT = 1


class LedgerError(ValueError):
    """A games file cannot be used as asked; the message is one line naming the file and why."""


@dataclass(frozen=True)
class GameRecord:
    """One finished game: its seed, KB hash, rows (dicts over the columns) and per row the divergence flags."""

    seed: int
    kb_sha256: str
    rows: tuple
    flags: tuple  # per row: "0110..." (1: the robot's description differed from none's at that robot turn)


def configuration(config: Any) -> dict:
    """Return a sweep configuration's parameters as JSON values, seeds left out (they differ between shards)."""
    values = json.loads(json.dumps(asdict(config)))
    values.pop("seeds", None)
    return values


def header(config: Any, columns: Sequence[str], code: Mapping[str, Any]) -> dict:
    """Return the header line of a sweep's games file."""
    return {"format": FORMAT, "tool": "fsreg-sweep", "configuration": configuration(config),
            "seeds": list(config.seeds), "columns": list(columns),
            "code": {"commit": code.get("commit"), "diff_sha256": code.get("diff_sha256")}}


def difference(mine: Mapping[str, Any], theirs: Mapping[str, Any]) -> Optional[str]:
    """Return the first parameter whose value differs, as ``name (A vs B)``, or None."""
    for key in list(mine) + [k for k in theirs if k not in mine]:
        if mine.get(key) != theirs.get(key):
            return f"{key} ({json.dumps(mine.get(key))} vs {json.dumps(theirs.get(key))})"
    return None


def code_label(code: Mapping[str, Any]) -> str:
    """Return e.g. ``commit 76b2ec0`` or ``commit 76b2ec0 + diff 1f2e3d4c``."""
    commit = (code.get("commit") or "unknown")[:12]
    diff = code.get("diff_sha256")
    return f"commit {commit}" + (f" + diff {diff[:12]}" if diff else "")


def _encode(record: GameRecord, columns: Sequence[str]) -> str:
    return json.dumps({"seed": record.seed, "kb_sha256": record.kb_sha256,
                       "rows": [[row.get(c) for c in columns] for row in record.rows],
                       "flags": list(record.flags)}, separators=(",", ":"))


def _decode(line: str, columns: Sequence[str]) -> GameRecord:
    data = json.loads(line)
    rows = tuple(dict(zip(columns, values)) for values in data["rows"])
    if any(len(values) != len(columns) for values in data["rows"]) or len(data["flags"]) != len(rows):
        raise ValueError("rows do not match the header's columns")
    return GameRecord(int(data["seed"]), str(data["kb_sha256"]), rows, tuple(data["flags"]))


class Ledger:
    """The games file of one sweep directory: its header and the games finished so far, by seed."""

    def __init__(self, path: Path, head: dict, games: dict, end: int) -> None:
        self.path = path
        self.header = head
        self.games: dict[int, GameRecord] = games
        self._end = end  # bytes up to the last complete line
        self._file: Optional[Any] = None

    @property
    def columns(self) -> list:
        return self.header["columns"]

    # ----------------------------------------------------------------- opening
    @classmethod
    def start(cls, directory: Path, head: dict) -> "Ledger":
        """Begin a fresh games file in ``directory`` (an earlier one there is replaced)."""
        path = directory / GAMES
        text = json.dumps(head, separators=(",", ":")) + "\n"
        tmp = path.with_suffix(".jsonl.tmp")
        with tmp.open("w", encoding="utf-8") as out:
            out.write(text)
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)
        _sync_directory(directory)
        return cls(path, head, {}, len(text.encode()))

    @classmethod
    def read(cls, directory: Path) -> "Ledger":
        """Read ``directory``'s games file (a torn last line is left out); LedgerError if there is none or it is bad."""
        from ..core.io.input_file import MAX_CORPUS_BYTES, InputFileError, read_bytes

        path = directory / GAMES
        if not os.path.lexists(path):
            raise LedgerError(f"{path}: no games file (not a sweep directory of this version)")
        try:
            data = read_bytes(path, MAX_CORPUS_BYTES)
        except InputFileError as err:
            raise LedgerError(str(err)) from None
        lines = data.split(b"\n")
        complete = lines[:-1]  # the part after the last newline is torn (or empty)
        if not complete:
            raise LedgerError(f"{path}: no header line")
        try:
            head = json.loads(complete[0])
            if head.get("format") != FORMAT or head.get("tool") != "fsreg-sweep":
                raise ValueError
        except (ValueError, AttributeError):
            raise LedgerError(f"{path}:1: not an fsreg-sweep games header (format {FORMAT})") from None
        games: dict[int, GameRecord] = {}
        for number, line in enumerate(complete[1:], 2):
            try:
                record = _decode(line.decode("utf-8"), head["columns"])
            except (ValueError, KeyError, TypeError):
                raise LedgerError(f"{path}:{number}: not a game record (the file is damaged)") from None
            if record.seed in games:
                raise LedgerError(f"{path}:{number}: seed {record.seed} recorded twice")
            games[record.seed] = record
        return cls(path, head, games, len(data) - len(lines[-1]))

    @classmethod
    def resume(cls, directory: Path, head: dict) -> "Ledger":
        """Reopen ``directory``'s games file to go on with the same sweep; LedgerError naming what differs."""
        ledger = cls.read(directory)
        found = ledger.header
        what = None
        if found["configuration"] != head["configuration"]:
            what = "configuration: " + str(difference(found["configuration"], head["configuration"]))
        elif found["seeds"] != head["seeds"]:
            what = "seeds"
        elif found["columns"] != head["columns"]:
            what = "columns of runs.csv"
        elif found["code"] != head["code"]:
            what = f"code ({code_label(found['code'])} there, {code_label(head['code'])} here)"
        if what is not None:
            raise LedgerError(f"--resume: {ledger.path} holds another sweep (it differs in {what}); "
                              "rerun without --resume to start afresh, or use another --out")
        extra = sorted(set(ledger.games) - set(head["seeds"]))
        if extra:
            raise LedgerError(f"{ledger.path}: seeds {extra[:5]} are not of this sweep")
        return ledger

    # ----------------------------------------------------------------- writing
    def append(self, record: GameRecord) -> GameRecord:
        """Write one finished game durably; return it as read back from its line."""
        if record.seed in self.games:
            raise LedgerError(f"{self.path}: seed {record.seed} is already recorded")
        line = _encode(record, self.columns) + "\n"
        if self._file is None:
            self._file = self.path.open("r+b")
            self._file.truncate(self._end)  # a torn last line goes before anything follows it
            self._file.seek(self._end)
        self._file.write(line.encode())
        self._file.flush()
        os.fsync(self._file.fileno())
        self._end += len(line.encode())
        stored = _decode(line, self.columns)
        self.games[record.seed] = stored
        return stored

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def missing(self) -> list:
        """Return the header's seeds with no finished game, in order."""
        return [s for s in self.header["seeds"] if s not in self.games]


def _sync_directory(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
