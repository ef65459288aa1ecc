"""A consultant's durable state: one SQLite database (WAL mode) per domain.

What a consultant learns at run time must survive a crash (SIGKILL, power loss):
facts accepted on ``ltm/assert`` and the WM buffer as of the last acknowledged
change.  The consultant writes them here *before* it replies, one transaction per
request, so a restarted consultant resumes exactly where the last reply left off.
The KB file itself is not stored: it is read again at start.

Schema (``PRAGMA user_version`` = :data:`SCHEMA_VERSION`)

``meta(key, value)``
    JSON values: ``kb`` (fingerprint of the domain's KB, :func:`fingerprint`),
    ``incarnation`` (incremented at every start), ``policy`` (the installed
    forgetting policy's settings, or absent), ``stamp`` and ``ticks`` (the WM
    buffer's encoding stamp counter and the number of decay ticks applied),
    ``decay_until`` (time of the last decay tick applied: a tick at or before it is
    never applied again).
``entities(seq, name)``
    Entities added at run time, in the order they joined the domain.
``facts(entity, property, certainty)``
    The latest certainty asserted at run time for each (entity, property); 0 is a
    retraction (it overrides the KB).
``queues(entity, items)``
    Each non-empty WM queue, ``items`` a JSON list of ``[property, stamp, hits]``
    LRU first; the rowid orders the queues as they (last) became non-empty.

The module does I/O but imports nothing from ROS; the consultant node calls it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sqlite3
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

SCHEMA_VERSION = 1
#: File name of a domain's database inside the state directory.
SUFFIX = ".sqlite3"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS entities (seq INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE);
CREATE TABLE IF NOT EXISTS facts (
    entity TEXT NOT NULL, property TEXT NOT NULL, certainty REAL NOT NULL, PRIMARY KEY (entity, property));
CREATE TABLE IF NOT EXISTS queues (entity TEXT PRIMARY KEY, items TEXT NOT NULL);
"""

QueueItems = Sequence[tuple[str, int, int]]


class StoreError(RuntimeError):
    """The state database cannot be opened, read or written (the message names the file)."""


def default_state_dir() -> Path:
    """Return the per-user state directory: ``$XDG_STATE_HOME/fsreg_ros`` (``~/.local/state/fsreg_ros``)."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "fsreg_ros"


def fingerprint(preference: Sequence[str], entities: Mapping[str, Mapping[str, float]], threshold: float,
                attributes: Mapping[str, str]) -> str:
    """Return a digest of a domain's KB: a store made for another KB is not reused."""
    text = json.dumps([list(preference), {e: dict(f) for e, f in entities.items()}, threshold, dict(attributes)],
                      sort_keys=True)
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


@dataclass
class StoredState:
    """What a consultant restores at start."""

    incarnation: int
    policy: Optional[dict] = None
    stamp: int = 0
    ticks: int = 0
    decay_until: float = -math.inf
    entities: list[str] = field(default_factory=list)  # runtime-added, in order
    facts: dict[str, dict[str, float]] = field(default_factory=dict)  # entity -> {property: certainty}
    queues: dict[str, list[tuple[str, int, int]]] = field(default_factory=dict)  # in creation order
    #: Set when a store made for another KB was moved aside (its new path).
    discarded: Optional[Path] = None


class DomainStore:
    """The durable state of one domain's consultant (one SQLite file, WAL mode)."""

    def __init__(self, path: Path, kb: str) -> None:
        """Open (creating it and its directory on first use) the database at ``path`` for KB fingerprint ``kb``."""
        self.path = Path(path)
        self.kb = kb
        self._db: Optional[sqlite3.Connection] = None

    # ---------------------------------------------------------------- opening
    def open(self) -> StoredState:
        """Open the database, count a new incarnation, and return the stored state.

        A database written for another KB is renamed aside (``<name>.<time>.old``)
        and a fresh one started; :attr:`StoredState.discarded` names it.
        """
        discarded = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._connect()
            stored_kb = self._meta("kb")
            if stored_kb is not None and stored_kb != self.kb:
                self.close()
                discarded = self.path.with_name(f"{self.path.name}.{int(time.time())}.old")
                for suffix in ("", "-wal", "-shm"):
                    src = Path(str(self.path) + suffix)
                    if src.exists():
                        src.rename(Path(str(discarded) + suffix))
                self._connect()
            with self._tx() as db:
                incarnation = int(self._meta("incarnation") or 0) + 1
                self._put(db, "incarnation", incarnation)
                self._put(db, "kb", self.kb)
            state = self._read(incarnation)
        except (sqlite3.Error, OSError, ValueError, TypeError) as err:
            self.close()
            raise StoreError(f"state database {self.path}: {err}") from None
        state.discarded = discarded
        return state

    def close(self) -> None:
        if self._db is not None:
            self._db.close()
            self._db = None

    # ---------------------------------------------------------------- writing
    def save_facts(self, entity: str, facts: Mapping[str, float], new_entity: bool,
                   queues: Optional[Mapping[str, QueueItems]] = None,
                   counters: Optional[tuple[int, int]] = None) -> None:
        """Record an accepted ``ltm/assert`` (and the WM queues it changed), in one transaction."""
        self._write(lambda db: self._facts(db, entity, facts, new_entity), queues or {}, counters)

    def save_wm(self, queues: Mapping[str, QueueItems], counters: tuple[int, int],
                decay_until: Optional[float] = None, policy: Optional[dict] = None) -> None:
        """Record the WM queues a request changed (empty ones are deleted) and the buffer's counters."""
        def extra(db: sqlite3.Connection) -> None:
            if decay_until is not None:
                self._put(db, "decay_until", decay_until)
            if policy is not None:
                self._put(db, "policy", policy)
        self._write(extra, queues, counters)

    # -------------------------------------------------------------- internals
    def _connect(self) -> None:
        db = sqlite3.connect(str(self.path), isolation_level=None, check_same_thread=False)
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")  # an acknowledged change survives power loss too
        db.executescript(_SCHEMA)
        version = db.execute("PRAGMA user_version").fetchone()[0]
        if version not in (0, SCHEMA_VERSION):
            db.close()
            raise ValueError(f"schema version {version}, this program knows {SCHEMA_VERSION}")
        db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
        self._db = db

    def _tx(self) -> "_Transaction":
        if self._db is None:
            raise StoreError(f"state database {self.path} is not open")
        return _Transaction(self._db)

    def _meta(self, key: str) -> Any:
        row = self._db.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return json.loads(row[0]) if row else None

    @staticmethod
    def _put(db: sqlite3.Connection, key: str, value: Any) -> None:
        db.execute("INSERT INTO meta (key, value) VALUES (?, ?) ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                   (key, json.dumps(value)))

    @staticmethod
    def _facts(db: sqlite3.Connection, entity: str, facts: Mapping[str, float], new_entity: bool) -> None:
        if new_entity:
            db.execute("INSERT OR IGNORE INTO entities (name) VALUES (?)", (entity,))
        db.executemany(
            "INSERT INTO facts (entity, property, certainty) VALUES (?, ?, ?) "
            "ON CONFLICT(entity, property) DO UPDATE SET certainty = excluded.certainty",
            [(entity, prop, float(c)) for prop, c in facts.items()])

    def _write(self, extra, queues: Mapping[str, QueueItems], counters: Optional[tuple[int, int]]) -> None:
        try:
            with self._tx() as db:
                extra(db)
                db.executemany("DELETE FROM queues WHERE entity = ?",
                               [(entity,) for entity, items in queues.items() if not items])
                db.executemany(
                    "INSERT INTO queues (entity, items) VALUES (?, ?) "
                    "ON CONFLICT(entity) DO UPDATE SET items = excluded.items",
                    [(entity, json.dumps(items, separators=(",", ":"))) for entity, items in queues.items() if items])
                if counters is not None:
                    self._put(db, "stamp", counters[0])
                    self._put(db, "ticks", counters[1])
        except (sqlite3.Error, UnicodeEncodeError) as err:
            raise StoreError(f"state database {self.path}: {err}") from None

    def _read(self, incarnation: int) -> StoredState:
        db = self._db
        decay_until = self._meta("decay_until")
        state = StoredState(
            incarnation,
            policy=self._meta("policy"),
            stamp=int(self._meta("stamp") or 0),
            ticks=int(self._meta("ticks") or 0),
            decay_until=-math.inf if decay_until is None else float(decay_until),
            entities=[name for (name,) in db.execute("SELECT name FROM entities ORDER BY seq")],
        )
        for entity, prop, certainty in db.execute("SELECT entity, property, certainty FROM facts ORDER BY rowid"):
            state.facts.setdefault(entity, {})[prop] = certainty
        for entity, items in db.execute("SELECT entity, items FROM queues ORDER BY rowid"):
            state.queues[entity] = [(str(p), int(s), int(h), *origin) for p, s, h, *origin in json.loads(items)]
        return state


class _Transaction:
    """``with``: BEGIN IMMEDIATE ... COMMIT, or ROLLBACK on an exception."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self.db = db

    def __enter__(self) -> sqlite3.Connection:
        self.db.execute("BEGIN IMMEDIATE")
        return self.db

    def __exit__(self, kind, value, traceback) -> None:
        self.db.execute("ROLLBACK" if kind is not None else "COMMIT")
