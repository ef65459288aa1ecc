"""A consultant's durable state: one SQLite database (WAL mode) per consultant, locked by one process.

What a consultant learns at run time must survive a restart: facts accepted on
``ltm/assert``, the installed forgetting policy, the last decay tick applied, and the
WM buffer.  Durability is chosen per kind of data (docs/deployment.md, "State"):

* **facts** told by perception are written with ``synchronous=FULL`` (fsynced) in
  their own transaction *before* memory changes and before the acknowledgement, so an
  acknowledged fact survives a power loss, and a refused write changes nothing;
* **WM** (which decays within seconds) is written with ``synchronous=NORMAL`` in WAL
  mode: a commit survives the process being killed at any point; a power loss can
  lose the WM commits since the last WAL checkpoint of SQLite (at most about 1,000
  pages, typically the last few seconds).

WM is kept as a *checkpoint* (every queue as of some moment) plus a *journal* of the
buffer operations since (one row per consultant call: a rule-3 burst over thousands
of distractors is one row, not thousands): a restarted consultant loads the
checkpoint and replays the journal (:mod:`fsreg_ros.core.state.journal` defines the records
and their replay; :mod:`fsreg_ros.core.consultant.persistence` writes and restores them).  A
checkpoint rewrites the queues changed since the previous one and empties the
journal, in one transaction.

Schema (``PRAGMA user_version`` = :data:`SCHEMA_VERSION`)

``meta(key, value)``
    JSON values: ``kb`` (fingerprint of the domain's KB, :func:`fingerprint`),
    ``incarnation`` (incremented at every start), ``policy`` (the installed
    forgetting policy's settings), ``decay_until`` (time of the last decay tick
    applied: a tick at or before it is never applied again), ``clock`` (``sim`` or
    ``system``: the kind of clock WM's times are on) and ``latest`` (the latest time
    WM reflects), ``checkpoint`` (``{"stamp", "ticks", "policy", "episodes"}``: the
    buffer's counters, limits and reference episodes as of the checkpoint; ``episodes``
    is :meth:`WMBuffer.export_episodes`'s dict, absent in files written before it).
``entities(seq, name)``
    Entities added at run time, in the order they joined the domain.
``facts(entity, property, certainty)``
    The latest certainty asserted at run time for each (entity, property); 0 is a
    retraction (it overrides the KB).
``queues(entity, items)``
    The checkpoint: each non-empty WM queue, ``items`` a JSON list of ``[property,
    stamp, hits, cause, turn]`` LRU first (under rule ``activation``, a sixth field: the
    entry's encoding history ``[n, first, recent times...]``); the rowid orders the
    queues as they (last) became non-empty.
``journal(seq, record)``
    The buffer operations since the checkpoint, in order (JSON).

Opening checks the file (empty, not a database, damaged pages, missing tables or
columns, malformed rows) and refuses it with one line naming the file and the way
out (:data:`WAY_OUT`); it never starts afresh silently, and a path that is not a
regular file (a FIFO, socket, device or directory) is refused as what it is
(:func:`fsreg_ros.core.io.input_file.file_kind`).  A lock file beside the database
(``<file>.lock``, :mod:`fsreg_ros.core.state.lock`) keeps a second opener away while the
first lives, and a refused opener is told who holds it.

The module does I/O but imports nothing from ROS; the consultant service calls it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sqlite3
import stat
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

from ..io.input_file import file_kind
from ..memory import UNKNOWN_ORIGIN
from ..memory.trace import Trace
from .lock import HeldLock, LockHeld, LockNotRegular, take_lock

SCHEMA_VERSION = 2
#: File name suffix of a consultant's database.
SUFFIX = ".sqlite3"
#: What a refused database's message tells the user to do.
WAY_OUT = ("start the consultant with -p reset_state:=true to move it aside and start afresh, "
           "or move the file away yourself")
#: Every table and the columns it must have.
TABLES = {
    "meta": ("key", "value"),
    "entities": ("seq", "name"),
    "facts": ("entity", "property", "certainty"),
    "queues": ("entity", "items"),
    "journal": ("seq", "record"),
}

_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE entities (seq INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE);
CREATE TABLE facts (
    entity TEXT NOT NULL, property TEXT NOT NULL, certainty REAL NOT NULL, PRIMARY KEY (entity, property));
CREATE TABLE queues (entity TEXT PRIMARY KEY, items TEXT NOT NULL);
CREATE TABLE journal (seq INTEGER PRIMARY KEY, record TEXT NOT NULL);
"""

#: One stored queue entry: property, stamp, LFU hits, cause and turn of the encoding that made it enter
#: (and, under rule ``activation``, its encoding history).
Item = tuple


class StoreError(RuntimeError):
    """The state database cannot be opened, read or written (the message names the file)."""


class StateInUse(StoreError):
    """Another live process holds the database (the message names it and its PID)."""


class StateDamaged(StoreError):
    """The database is not what this program wrote (the message names the file and the way out)."""


def damaged(path: Path, problem: str) -> StateDamaged:
    """Return the one-line error for a database refused at start."""
    return StateDamaged(f"state database {path}: {problem}; {WAY_OUT}")


def default_state_dir() -> Path:
    """Return the per-user state directory: ``$XDG_STATE_HOME/fsreg_ros`` (``~/.local/state/fsreg_ros``)."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "fsreg_ros"


def state_path(base: Path, domain_id: int, node_name: str, domain: str) -> Path:
    """Return a consultant's database: ``<base>/ros_domain_<id>/<namespace>/<node>/<domain>.sqlite3``.

    ``node_name`` is the node's fully qualified name (its namespace included), so two
    robots told apart by ROS domain id or by namespace never share a file.
    """
    return Path(base) / f"ros_domain_{int(domain_id)}" / node_name.strip("/") / f"{domain}{SUFFIX}"


def legacy_state_path(base: Path, node_name: str, domain: str) -> Path:
    """Return where versions before the ROS domain id was part of the path kept the database."""
    return Path(base) / node_name.strip("/") / f"{domain}{SUFFIX}"


def fingerprint(preference: Sequence[str], entities: Mapping[str, Mapping[str, float]], threshold: float,
                attributes: Mapping[str, str], exclusive: Sequence[Sequence[str]] = ()) -> str:
    """Return a digest of a domain's KB: a store made for another KB is migrated, not reused as is.

    Declared ``exclusive`` groups count only when there are some (a KB without any keeps its digest).
    """
    kb: list = [list(preference), {e: dict(f) for e, f in entities.items()}, threshold, dict(attributes)]
    if exclusive:
        kb.append([list(group) for group in exclusive])
    text = json.dumps(kb, sort_keys=True)
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


@dataclass
class Checkpoint:
    """WM as of one moment: the queues changed since the last checkpoint, the counters and the limits' policy.

    ``queues`` maps entity -> items (an empty list deletes the queue); ``clear``
    deletes every stored queue first.  Writing it empties the journal.
    """

    queues: Mapping[str, Sequence[Item]]
    stamp: int
    ticks: int
    policy: Optional[dict]
    clear: bool = False
    episodes: Mapping[str, Any] = field(default_factory=dict)  # WMBuffer.export_episodes(), whole


@dataclass
class Batch:
    """Everything one consultant call writes, in one transaction.

    ``facts``: LTM updates, each (entity, {property: certainty}, new entity), in order
    (one such tuple is taken as a list of one); any makes the batch durable (fsynced
    before :meth:`DomainStore.commit` returns); ``records`` are appended to the journal
    (after the ``checkpoint``, if any); ``meta`` keys are set (``policy``, ``decay_until``,
    ``clock``, ``latest``).
    """

    facts: Sequence[tuple[str, Mapping[str, float], bool]] = ()
    records: Sequence[Any] = ()
    checkpoint: Optional[Checkpoint] = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.facts is None:
            self.facts = ()
        elif isinstance(self.facts, tuple) and self.facts and isinstance(self.facts[0], str):
            self.facts = [self.facts]  # one update

    @property
    def durable(self) -> bool:
        return bool(self.facts)


@dataclass
class StoreContents:
    """What a consultant finds in its database at start (what it reports of it is the contract's ``StoredState``)."""

    incarnation: int
    policy: Optional[dict] = None
    decay_until: float = -math.inf
    clock: Optional[str] = None
    latest: float = -math.inf
    entities: list[str] = field(default_factory=list)  # runtime-added, in order
    facts: dict[str, dict[str, float]] = field(default_factory=dict)  # entity -> {property: certainty}
    queues: dict[str, list[Item]] = field(default_factory=dict)  # the checkpoint, in creation order
    stamp: int = 0  # the checkpoint's counters and limits
    ticks: int = 0
    limits: Optional[dict] = None
    episodes: dict[str, Any] = field(default_factory=dict)  # the checkpoint's reference episodes
    journal: list[Any] = field(default_factory=list)
    #: The KB's entities in entity order when the database was written (None: not recorded).
    kb_entities: Optional[list[str]] = None
    #: The database was written for another KB (its fingerprint differs): migrate it.
    other_kb: bool = False
    #: The database was created by this open (nothing stored before).
    created: bool = False
    #: Where ``reset`` moved the old database (None: nothing moved).
    moved_aside: Optional[Path] = None
    #: The schema version found (1: upgraded in place).
    found_version: int = SCHEMA_VERSION


class DomainStore:
    """The durable state of one consultant (one SQLite file in WAL mode, one lock file)."""

    def __init__(self, path: Path, kb: str) -> None:
        """Name the database at ``path`` for KB fingerprint ``kb``; :meth:`open` opens it."""
        self.path = Path(path)
        self.kb = kb
        self.lock_path = self.path.with_name(self.path.name + ".lock")
        self._db: Optional[sqlite3.Connection] = None
        self._lock: Optional[HeldLock] = None
        #: Transactions :meth:`commit` committed since this object was made (fsynced ones in ``durable_commits``).
        self.commits = 0
        self.durable_commits = 0
        #: One transaction at a time: a consultant's facts are committed on a writer thread of their own.
        self._writing = threading.Lock()

    # ---------------------------------------------------------------- opening
    def open(self, reset: bool = False, after: int = 0) -> StoreContents:
        """Lock, check and open the database (creating it on first use); count a new incarnation.

        ``reset`` moves an existing database aside (``<file>.<time>.old``) and starts
        afresh; the new incarnation is above ``after`` too (a reset while serving
        keeps the numbering going up, so everyone sees a new incarnation).  Raises
        :class:`StateInUse` when another process holds it, :class:`StateDamaged` when
        it is not what this program wrote, and :class:`StoreError` for any other I/O
        problem; the message names the file.
        """
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._take_lock()
            moved = self._move_aside() if reset and self.path.exists() else None
            created = not self.path.exists()
            if created:
                self._create()
            else:
                for suffix in ("", "-wal", "-shm"):
                    self._check_kind(Path(str(self.path) + suffix))
            if not created and self.path.stat().st_size == 0:
                raise damaged(self.path, "the file is empty (0 bytes), so the runtime facts it held are gone")
            found = self._connect()
            with self._tx() as db:
                incarnation = max(int(self._meta("incarnation") or 0), after) + 1
                self._put(db, "incarnation", incarnation)
            state = self._read(incarnation)
        except StoreError:
            self.close()
            raise
        except (sqlite3.Error, OSError, ValueError, TypeError, KeyError, IndexError) as err:
            self.close()
            raise StoreError(f"state database {self.path}: {err}") from None
        state.created, state.moved_aside, state.found_version = created, moved, found
        return state

    def close(self) -> None:
        """Close the database and release the lock."""
        if self._db is not None:
            with self._writing:
                self._db.close()
                self._db = None
        if self._lock is not None:
            self._lock.release()  # the flock and the record lock
            self._lock = None

    # ---------------------------------------------------------------- writing
    def commit(self, batch: Batch) -> None:
        """Write one call's changes in one transaction (fsynced first when ``batch.durable``).

        Raises :class:`StoreError` (nothing written) when SQLite refuses, e.g. a full disk.
        Safe to call from several threads: one commit at a time.
        """
        with self._writing:
            self._commit(batch)

    def _commit(self, batch: Batch) -> None:
        db = self._require()
        try:
            if batch.durable:
                db.execute("PRAGMA synchronous=FULL")
            try:
                with _Transaction(db):
                    if batch.facts:
                        self._many_facts(db, batch.facts)
                    if batch.checkpoint is not None:
                        self._checkpoint(db, batch.checkpoint)
                    if batch.records:
                        db.executemany("INSERT INTO journal (record) VALUES (?)",
                                       [(_dumps(record),) for record in batch.records])
                    for key, value in batch.meta.items():
                        self._put(db, key, value)
            finally:
                if batch.durable:
                    db.execute("PRAGMA synchronous=NORMAL")
        except (sqlite3.Error, UnicodeEncodeError, ValueError) as err:
            raise StoreError(f"state database {self.path}: {err}") from None
        self.commits += 1
        self.durable_commits += batch.durable

    def rewrite(self, state: StoreContents, backup: bool = True) -> Optional[Path]:
        """Replace everything stored with ``state`` (a migration to this KB); return the backup's path.

        The old database is first copied aside (``<file>.<time>.old``) when ``backup``.
        """
        with self._writing:
            return self._rewrite(state, backup)

    def _rewrite(self, state: StoreContents, backup: bool) -> Optional[Path]:
        db = self._require()
        copy = None
        try:
            if backup:
                copy = self._aside_name()
                target = sqlite3.connect(str(copy))
                try:
                    db.backup(target)
                finally:
                    target.close()
            db.execute("PRAGMA synchronous=FULL")
            with _Transaction(db):
                for table in ("entities", "facts", "queues", "journal"):
                    db.execute(f"DELETE FROM {table}")  # noqa: S608 - fixed table names
                db.executemany("INSERT INTO entities (name) VALUES (?)", [(e,) for e in state.entities])
                for entity, facts in state.facts.items():
                    self._facts(db, entity, facts, False)
                self._checkpoint(db, Checkpoint(state.queues, state.stamp, state.ticks, state.limits,
                                                episodes=state.episodes))
                self._put(db, "kb", self.kb)
                for key, value in (("policy", state.policy), ("clock", state.clock),
                                   ("kb_entities", state.kb_entities)):
                    self._put(db, key, value)
                self._put(db, "latest", state.latest if math.isfinite(state.latest) else None)
                self._put(db, "decay_until", state.decay_until if math.isfinite(state.decay_until) else None)
            db.execute("PRAGMA synchronous=NORMAL")
        except (sqlite3.Error, OSError, UnicodeEncodeError, ValueError) as err:
            raise StoreError(f"state database {self.path}: {err}") from None
        return copy

    def journal_length(self) -> int:
        """Return how many records the journal holds."""
        with self._writing:  # not inside another thread's transaction on this connection
            return int(self._require().execute("SELECT count(*) FROM journal").fetchone()[0])

    def execute(self, sql: str) -> None:
        """Run one SQL statement on the connection (tests: ``PRAGMA max_page_count`` to fill the disk)."""
        with self._writing:
            self._require().execute(sql)

    # -------------------------------------------------------------- internals
    def _take_lock(self) -> None:
        try:
            self._lock = take_lock(self.lock_path, self.path)
        except LockHeld as err:
            raise self._in_use(err.holder) from None
        except LockNotRegular as err:
            raise damaged(self.lock_path, f"the lock file is {err.kind}, not a regular file") from None

    def _in_use(self, holder: str) -> StateInUse:
        return StateInUse(
            f"state database {self.path} is in use by {holder} (a consultant with the same ROS domain id, "
            "namespace and node name is running); stop it, or give this one another node name, namespace or "
            "state_dir")

    def _check_kind(self, path: Path) -> None:
        """Refuse a database (or its WAL or shared-memory file) that is not a regular file, naming what it is."""
        try:
            mode = os.stat(path).st_mode
        except FileNotFoundError:
            return
        if not stat.S_ISREG(mode):
            raise damaged(path, f"it is {file_kind(mode)}, not a database file")

    def _aside_name(self) -> Path:
        stamp = time.strftime("%Y%m%dT%H%M%S", time.gmtime())
        candidate = self.path.with_name(f"{self.path.name}.{stamp}.old")
        n = 1
        while candidate.exists():
            n += 1
            candidate = self.path.with_name(f"{self.path.name}.{stamp}-{n}.old")
        return candidate

    def _move_aside(self) -> Path:
        target = self._aside_name()
        for suffix in ("", "-wal", "-shm"):
            src = Path(str(self.path) + suffix)
            if src.exists():
                src.rename(Path(str(target) + suffix))
        return target

    def _create(self) -> None:
        """Create the database under a temporary name, then move it in place (never a half-made file)."""
        tmp = self.path.with_name(self.path.name + ".new")
        tmp.unlink(missing_ok=True)
        db = sqlite3.connect(str(tmp), isolation_level=None)
        try:
            db.execute("PRAGMA journal_mode=WAL")
            db.executescript(_SCHEMA)
            db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            db.execute("INSERT INTO meta (key, value) VALUES ('kb', ?), ('incarnation', '0')", (json.dumps(self.kb),))
            db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        finally:
            db.close()
        for suffix in ("-wal", "-shm"):
            Path(str(tmp) + suffix).unlink(missing_ok=True)
        os.replace(tmp, self.path)
        dir_fd = os.open(self.path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)

    def _connect(self) -> int:
        """Connect and check the file; upgrade a version-1 database in place; return the version found."""
        try:
            db = sqlite3.connect(str(self.path), isolation_level=None, check_same_thread=False)
            self._db = db
            check = db.execute("PRAGMA quick_check").fetchone()[0]
        except sqlite3.DatabaseError as err:
            raise damaged(self.path, f"not a readable SQLite database ({err})") from None
        if check != "ok":
            raise damaged(self.path, f"damaged ({check})")
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=NORMAL")
        version = db.execute("PRAGMA user_version").fetchone()[0]
        if version not in (1, SCHEMA_VERSION):
            raise damaged(self.path, f"schema version {version}; this program reads versions 1 and {SCHEMA_VERSION}")
        self._check_tables(version)
        if self._meta("kb") is None or self._meta("incarnation") is None:
            raise damaged(self.path, "meta has no 'kb' or 'incarnation' entry")
        if version == 1:
            self._upgrade_v1()
        return version

    def _check_tables(self, version: int) -> None:
        db = self._db
        for table, columns in TABLES.items():
            if version == 1 and table == "journal":
                continue
            found = [row[1] for row in db.execute(f"PRAGMA table_info({table})")]  # noqa: S608 - fixed names
            if not found:
                raise damaged(self.path, f"table '{table}' is missing")
            missing = [c for c in columns if c not in found]
            if missing:
                raise damaged(self.path, f"table '{table}' lacks column(s) {', '.join(missing)}")

    def _upgrade_v1(self) -> None:
        """Version 1 kept ``[property, stamp, hits]`` items and no journal: add both (origins unknown)."""
        db = self._db
        with _Transaction(db):
            db.execute("CREATE TABLE journal (seq INTEGER PRIMARY KEY, record TEXT NOT NULL)")
            rows = db.execute("SELECT entity, items FROM queues").fetchall()
            db.executemany("UPDATE queues SET items = ? WHERE entity = ?",
                           [(_dumps([[*item[:3], *UNKNOWN_ORIGIN] for item in json.loads(items)]), entity)
                            for entity, items in rows])
            stamp, ticks = self._meta("stamp") or 0, self._meta("ticks") or 0
            self._put(db, "checkpoint", {"stamp": stamp, "ticks": ticks, "policy": self._meta("policy")})
            db.execute("DELETE FROM meta WHERE key IN ('stamp', 'ticks')")
            db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")

    def _require(self) -> sqlite3.Connection:
        if self._db is None:
            raise StoreError(f"state database {self.path} is not open")
        return self._db

    def _tx(self) -> "_Transaction":
        return _Transaction(self._require())

    def _meta(self, key: str) -> Any:
        row = self._db.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        if row is None:
            return None
        try:
            return json.loads(row[0])
        except ValueError:
            raise damaged(self.path, f"meta '{key}' is not JSON") from None

    @staticmethod
    def _put(db: sqlite3.Connection, key: str, value: Any) -> None:
        db.execute("INSERT INTO meta (key, value) VALUES (?, ?) ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                   (key, _dumps(value)))

    @staticmethod
    def _facts(db: sqlite3.Connection, entity: str, facts: Mapping[str, float], new_entity: bool) -> None:
        if new_entity:
            db.execute("INSERT OR IGNORE INTO entities (name) VALUES (?)", (entity,))
        db.executemany(
            "INSERT INTO facts (entity, property, certainty) VALUES (?, ?, ?) "
            "ON CONFLICT(entity, property) DO UPDATE SET certainty = excluded.certainty",
            [(entity, prop, float(c)) for prop, c in facts.items()])

    @staticmethod
    def _many_facts(db: sqlite3.Connection, updates: Sequence[tuple[str, Mapping[str, float], bool]]) -> None:
        """Store LTM updates in order: one statement for the new entities, one for every fact."""
        db.executemany("INSERT OR IGNORE INTO entities (name) VALUES (?)", [(e,) for e, _, new in updates if new])
        db.executemany(
            "INSERT INTO facts (entity, property, certainty) VALUES (?, ?, ?) "
            "ON CONFLICT(entity, property) DO UPDATE SET certainty = excluded.certainty",
            [(entity, prop, float(c)) for entity, facts, _ in updates for prop, c in facts.items()])

    def _checkpoint(self, db: sqlite3.Connection, checkpoint: Checkpoint) -> None:
        if checkpoint.clear:
            db.execute("DELETE FROM queues")
        queues = checkpoint.queues
        db.executemany("DELETE FROM queues WHERE entity = ?", [(e,) for e, items in queues.items() if not items])
        db.executemany(
            "INSERT INTO queues (entity, items) VALUES (?, ?) ON CONFLICT(entity) DO UPDATE SET items = excluded.items",
            [(e, _dumps([list(item) for item in items])) for e, items in queues.items() if items])
        db.execute("DELETE FROM journal")
        self._put(db, "checkpoint", {"stamp": checkpoint.stamp, "ticks": checkpoint.ticks,
                                     "policy": checkpoint.policy, "episodes": dict(checkpoint.episodes)})

    def _read(self, incarnation: int) -> StoreContents:
        db, path = self._db, self.path
        decay_until, latest = self._meta("decay_until"), self._meta("latest")
        checkpoint = self._meta("checkpoint") or {}
        if not isinstance(checkpoint, dict):
            raise damaged(path, "meta 'checkpoint' is not an object")
        state = StoreContents(
            incarnation,
            policy=self._meta("policy"),
            decay_until=-math.inf if decay_until is None else float(decay_until),
            clock=self._meta("clock"),
            latest=-math.inf if latest is None else float(latest),
            stamp=_whole(checkpoint.get("stamp", 0), path, "checkpoint stamp"),
            ticks=_whole(checkpoint.get("ticks", 0), path, "checkpoint ticks"),
            limits=checkpoint.get("policy"),
            episodes=checkpoint.get("episodes") or {},
            entities=[name for (name,) in db.execute("SELECT name FROM entities ORDER BY seq")],
            other_kb=self._meta("kb") != self.kb,
            kb_entities=self._meta("kb_entities"),
        )
        if not isinstance(state.episodes, dict):
            raise damaged(path, "meta 'checkpoint' episodes is not an object")
        if state.kb_entities is not None and not (isinstance(state.kb_entities, list)
                                                  and all(isinstance(e, str) for e in state.kb_entities)):
            raise damaged(path, "meta 'kb_entities' is not a list of names")
        for entity, prop, certainty in db.execute("SELECT entity, property, certainty FROM facts ORDER BY rowid"):
            if not isinstance(certainty, (int, float)) or not 0.0 <= certainty <= 1.0:
                raise damaged(path, f"fact {entity!r}.{prop!r} has certainty {certainty!r}, not a number in [0, 1]")
            state.facts.setdefault(entity, {})[prop] = float(certainty)
        for entity, items in db.execute("SELECT entity, items FROM queues ORDER BY rowid"):
            state.queues[entity] = _items(entity, items, path)
        for seq, record in db.execute("SELECT seq, record FROM journal ORDER BY seq"):
            try:
                state.journal.append(json.loads(record))
            except ValueError:
                raise damaged(path, f"journal record {seq} is not JSON") from None
        return state


def _dumps(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"), allow_nan=False)


def _whole(value: Any, path: Path, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise damaged(path, f"{what} is {value!r}, not a whole number >= 0")
    return value


def _items(entity: str, text: str, path: Path) -> list[Item]:
    """Parse one stored queue, refusing anything malformed."""
    try:
        raw = json.loads(text)
    except ValueError:
        raw = None
    items: list[Item] = []
    for item in raw if isinstance(raw, list) else [None]:
        if not (isinstance(item, list) and len(item) in (5, 6) and isinstance(item[0], str)
                and all(isinstance(x, int) and not isinstance(x, bool) for x in item[1:3])
                and isinstance(item[3], str) and (item[4] is None or isinstance(item[4], int))):
            raise damaged(path, f"the WM queue of {entity!r} is malformed ({text[:80]!r})")
        if len(item) == 6:
            try:
                Trace.from_json(item[5])
            except ValueError as err:
                raise damaged(path, f"the WM queue of {entity!r}: {err}") from None
        items.append(tuple(item))  # type: ignore[arg-type]  # a sixth field: the activation trace
    if not items:
        raise damaged(path, f"the WM queue of {entity!r} is stored empty")
    return items


class _Transaction:
    """``with``: BEGIN IMMEDIATE ... COMMIT, or ROLLBACK on an exception."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self.db = db

    def __enter__(self) -> sqlite3.Connection:
        self.db.execute("BEGIN IMMEDIATE")
        return self.db

    def __exit__(self, kind, value, traceback) -> None:
        if kind is not None:
            try:
                self.db.execute("ROLLBACK")
            except sqlite3.Error:
                pass  # the failed statement may have rolled back already
            return
        try:
            self.db.execute("COMMIT")
        except sqlite3.Error:
            try:
                self.db.execute("ROLLBACK")
            except sqlite3.Error:
                pass
            raise
