"""WM operations as journal records, and their replay: the redo log of a consultant's working memory.

A consultant persists WM as a checkpoint (every queue as of some moment) plus a journal
of what its buffer did since, one record per buffer operation (:mod:`fsreg_ros.core.state.store`).
Writing what was *done* rather than every queue it touched is what keeps persistence
cheap: a rule-3 narrowing encodes one property for thousands of distractors (docs/semantics.md
section 2) and is one record here.  Replaying the records in order on the checkpoint
calls the very buffer operations the live consultant called, with the same arguments,
so the result is the same WM (queues, stamps, LFU counts, origins, counters): the WM
mechanism keeps one owner (:mod:`fsreg_ros.core.memory`, Algorithms 1-3).

Records are JSON lists whose first item names the operation:

``["each", property, [entity, ...], cause, time, turn]``
    ``WMBuffer.encode_each``: Encode(e, [property]) for each entity, in order (rules 2 and 3).
``["bits", property, hex, cause, time, turn]``
    the same, for the entities whose bits are set in ``hex`` (bit i = the i-th entity in
    entity order): how a narrowing is written, without naming thousands of entities;
    :func:`decode` turns it into ``each`` with the entity order it was written under.
``["encode", entity, [property, ...], cause, time, turn]``
    ``WMBuffer.encode``: Encode(entity, properties), Algorithm 1 (rule 1).
``["decay", {"origin", "period", "first", "count"}]``
    decay ticks applied at once (Algorithm 2, :meth:`~fsreg_ros.core.memory.WMBuffer.decay_now`).
``["limits", settings, time]``
    a forgetting policy installed (its limits trim at once, Algorithm 3 included).
``["advance", time]``
    the clock reached ``time`` (``WMBuffer.advance``: rule ``activation``'s pops).
``["evict", count, time]``
    the shared pool's trim of this domain (cause ``shared-capacity``).
``["remove", entity, [property, ...], time]``
    properties retracted from Q[entity] because they stopped holding in LTM.
``["refer", entity, [property, ...], time, turn]``
    an act of referring to ``entity``: ``WMBuffer.begin_episode`` (its next reference
    episode; rule ``episodes`` forgets then), then ``WMBuffer.encode`` of the properties
    with cause ``speaker`` -- RR's rule 1 at a view's close, or, with no properties,
    REG's open of a view of its target (whose close then writes an ``encode`` record).

Only a policy with random displacement victims is not journalled: the generator's
state is not part of the record, so such a consultant writes a checkpoint per call.
"""

from __future__ import annotations

from typing import Any, Callable, Optional, Sequence

from ..memory import bitset
from ..memory.ticks import TickError, TickRun, check_time
from ..forgetting.policies import ForgettingPolicy, PolicyError
from ..memory import ENCODE_CAUSES, WMBuffer
from ..forgetting.wm_manager import configure_buffer

Record = list


class JournalError(ValueError):
    """A journal record that is not one this program writes (the message says what is wrong)."""


# ------------------------------------------------------------------ records
def each(prop: str, entities: Sequence[str], cause: str, time: float, turn: Optional[int]) -> Record:
    """Return the record of encoding ``prop`` for each of ``entities`` (``WMBuffer.encode_each``)."""
    return ["each", prop, list(entities), cause, time, turn]


def bits(prop: str, members: int, cause: str, time: float, turn: Optional[int]) -> Record:
    """Return the record of encoding ``prop`` for each entity of a bitset (entity order), in order."""
    return ["bits", prop, format(members, "x"), cause, time, turn]


def decode(record: Any, order: Optional[Sequence[str]]) -> Any:
    """Return a ``bits`` record as the ``each`` record it stands for (other records unchanged).

    ``order`` is the entity order the journal was written under; JournalError if a bit
    names no entity of it (or there is no order).
    """
    if not (isinstance(record, list) and record and record[0] == "bits"):
        return record
    if len(record) != 6 or not isinstance(record[2], str):
        raise JournalError(f"malformed 'bits' record {str(record)[:80]}")
    try:
        members = int(record[2], 16)
    except ValueError:
        raise JournalError(f"malformed 'bits' record {str(record)[:80]}") from None
    if order is None or members < 0 or members.bit_length() > len(order):
        raise JournalError("a 'bits' record names entities beyond the stored entity order")
    return ["each", record[1], bitset.names(members, order), *record[3:]]


def encode(entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]) -> Record:
    """Return the record of encoding ``properties`` for ``entity`` (``WMBuffer.encode``)."""
    return ["encode", entity, list(properties), cause, time, turn]


def decay(ticks: TickRun) -> Record:
    """Return the record of decay ticks applied at once."""
    return ["decay", ticks.to_json()]


def limits(policy: ForgettingPolicy, time: float) -> Record:
    """Return the record of installing ``policy`` at ``time``."""
    return ["limits", policy.settings(), time]


def advance(time: float) -> Record:
    """Return the record of the clock reaching ``time``."""
    return ["advance", time]


def evict(count: int, time: float) -> Record:
    """Return the record of the shared pool's trim of ``count`` fronts."""
    return ["evict", count, time]


def remove(entity: str, properties: Sequence[str], time: float) -> Record:
    """Return the record of retracting ``properties`` from Q[entity]."""
    return ["remove", entity, list(properties), time]


def refer(entity: str, properties: Sequence[str], time: float, turn: Optional[int]) -> Record:
    """Return the record of an act of referring: ``entity``'s next episode begins, ``properties`` are encoded."""
    return ["refer", entity, list(properties), time, turn]


def names_in(record: Record) -> int:
    """Return how many entity names a record carries (what its size grows with; a bitset counts 1 per 8)."""
    if record and record[0] == "each":
        return len(record[2])
    if record and record[0] == "bits":
        return len(record[2]) // 2 + 1
    return 1


def time_of(record: Record) -> float:
    """Return the latest robot-clock time a (checked) record's operation happened at."""
    kind = record[0]
    if kind in ("each", "encode"):
        return float(record[4])
    if kind == "refer":
        return float(record[3])
    if kind == "decay":
        return TickRun.from_json(record[1]).last
    return float(record[-1])  # limits, evict, remove, advance


# ------------------------------------------------------------------ replay
def replay(buffer: WMBuffer, entity_order: Sequence[str], record: Record) -> None:
    """Apply one (checked) record to ``buffer`` as the live consultant did.

    ``entity_order`` is the domain's entity order (decay ticks pop in that order).
    """
    kind = record[0]
    if kind == "each":
        buffer.encode_each(record[2], record[1], record[3], record[4], record[5])
    elif kind == "encode":
        buffer.encode(record[1], record[2], record[3], record[4], record[5])
    elif kind == "decay":
        buffer.decay_now(TickRun.from_json(record[1]), entity_order)
    elif kind == "limits":
        configure_buffer(buffer, ForgettingPolicy.from_settings(record[1]), record[2])
    elif kind == "advance":
        buffer.advance(record[1])
    elif kind == "evict":
        buffer.evict_oldest(record[1], "shared-capacity", record[2])
    elif kind == "remove":
        for prop in record[2]:
            buffer.remove(record[1], prop, "retract", record[3])
    elif kind == "refer":
        buffer.begin_episode(record[1], record[3], record[4])
        buffer.encode(record[1], record[2], "speaker", record[3], record[4])
    else:  # check() refuses anything else
        raise JournalError(f"unknown journal record {kind!r}")


def check(record: Any, knows_entity: Callable[[str], bool], knows_property: Callable[[str], bool],
          keep_known: bool = False) -> Optional[Record]:
    """Return ``record`` if it is well formed and names only known entities and properties.

    Raises :class:`JournalError` naming the problem.  With ``keep_known`` (a migration
    to another KB), unknown names are dropped instead: the record is returned without
    them, or None when nothing is left of it.
    """
    if not isinstance(record, list) or not record or not isinstance(record[0], str):
        raise JournalError(f"malformed record {str(record)[:80]}")
    kind, shape = record[0], _SHAPES.get(record[0])
    if shape is None or len(record) != len(shape) + 1:
        raise JournalError(f"malformed {kind!r} record {str(record)[:80]}")
    for value, expected in zip(record[1:], shape):
        if not _fits(value, expected):
            raise JournalError(f"malformed {kind!r} record {str(record)[:80]}")
    try:
        if kind in ("each", "encode"):
            check_time("time", record[4])
            if record[3] not in ENCODE_CAUSES:
                raise JournalError(f"{kind!r} record with cause {record[3]!r}")
        elif kind == "decay":
            TickRun.from_json(record[1])
        elif kind == "limits":
            ForgettingPolicy.from_settings(record[1])
            check_time("time", record[2])
        elif kind == "evict":
            check_time("time", record[2])
        elif kind == "advance":
            check_time("time", record[1])
        elif kind == "remove":
            check_time("time", record[3])
        elif kind == "refer":
            check_time("time", record[3])
    except (TickError, PolicyError) as err:
        raise JournalError(f"{kind!r} record: {err}") from None
    return _known(record, knows_entity, knows_property, keep_known)


# ------------------------------------------------------------------ internals
_NAMES = "names"
_SHAPES: dict[str, tuple] = {
    "each": (str, _NAMES, str, (int, float), (int, type(None))),
    "encode": (str, _NAMES, str, (int, float), (int, type(None))),
    "decay": (dict,),
    "limits": (dict, (int, float)),
    "evict": (int, (int, float)),
    "advance": ((int, float),),
    "remove": (str, _NAMES, (int, float)),
    "refer": (str, _NAMES, (int, float), (int, type(None))),
}


def _fits(value: Any, expected: Any) -> bool:
    if expected == _NAMES:
        return isinstance(value, list) and all(isinstance(v, str) for v in value)
    if isinstance(value, bool):
        return False
    return isinstance(value, expected)


def _known(record: Record, knows_entity: Callable[[str], bool], knows_property: Callable[[str], bool],
           keep_known: bool) -> Optional[Record]:
    kind = record[0]
    if kind == "each":
        entities, props = record[2], [record[1]]
    elif kind in ("encode", "remove", "refer"):
        entities, props = [record[1]], record[2]
    else:
        return record
    bad_entities = [e for e in entities if not knows_entity(e)]
    bad_props = [p for p in props if not knows_property(p)]
    if not bad_entities and not bad_props:
        return record
    if not keep_known:
        what = f"entity {bad_entities[0]!r}" if bad_entities else f"property {bad_props[0]!r}"
        raise JournalError(f"{kind!r} record names an unknown {what}")
    if kind == "each":
        kept = [e for e in entities if knows_entity(e)]
        return None if bad_props or not kept else [kind, record[1], kept, *record[3:]]
    kept = [p for p in props if knows_property(p)]
    return None if bad_entities or not kept else [kind, record[1], kept, *record[3:]]
