"""Play a scenario's dialogue on a simulated clock.

The simulator wires the core together exactly as the ROS graph does: one
:class:`Consultant` per domain, a :class:`WMManager` applying each domain's
forgetting policy, reference resolution for human turns and REG plus realisation
for robot turns.  Before each dialogue event at time T, every decay tick due at or
before T is applied ("a tick at time T is applied before any
dialogue event stamped T").

The records built here (:func:`human_record`, :func:`robot_record`) are also what
the ROS ``dialogue_player`` emits, so ``fsreg-graph --json`` and ``fsreg-sim
--json`` can be compared byte for byte.
"""

from __future__ import annotations

import json
from json.encoder import encode_basestring as _string
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional

from ..consultant.local_port import LocalPort
from ..algorithms.port import run_sync
from ..forgetting.policies import ForgettingPolicy
from ..algorithms.generation import algorithm_for, generate
from ..memory import WMEvent
from ..lexicon import Lexicon
from ..algorithms.resolution import resolve
from ..scenario import Scenario, Turn
from ..forgetting.wm_manager import WMManager


@dataclass
class Options:
    """What a user can change from the command line.

    ``memory`` overrides every domain's ``memory:`` settings key by key.
    ``algorithm`` None means: SD-PIA, or DIST-PIA for a domain whose policy is none.
    """

    memory: dict[str, Any] = field(default_factory=dict)
    algorithm: Optional[str] = None
    wm_order: str = "lru-first"


def effective_policies(scenario: Scenario, options: Options) -> dict[str, ForgettingPolicy]:
    return {d: scenario.policy_for(d, options.memory or None) for d in scenario.domains}


def human_record(turn: Turn, resolution: Mapping[str, Any], unknown_words: Optional[list[str]]) -> dict:
    """One human turn's output record; ``unknown_words`` for text turns."""
    record: dict[str, Any] = {"turn": turn.index, "time": turn.time, "speaker": "human"}
    if turn.target is not None:
        record["target"] = turn.target
    if turn.text is not None:
        record["text"] = turn.text
        record["unknown_words"] = list(unknown_words or [])
    for key in ("description", "status", "resolved", "candidates", "domain"):
        record[key] = resolution.get(key)
    if "error" in resolution:
        record["error"] = resolution["error"]
    return record


def robot_record(turn: Turn, expression: Mapping[str, Any]) -> dict:
    """One robot turn's output record."""
    record: dict[str, Any] = {"turn": turn.index, "time": turn.time, "speaker": "robot", "target": turn.target}
    if turn.context is not None:
        record["context"] = list(turn.context)
    for key in (
        "wm_before",
        "description",
        "sources",
        "distinguishing",
        "distractors_left",
        "text",
        "domain",
        "algorithm",
        "origins",
    ):
        record[key] = expression.get(key)
    if "error" in expression:
        record["error"] = expression["error"]
    return record


class Simulation:
    """The core's whole pipeline for one scenario, on a simulated clock."""

    def __init__(
        self,
        scenario: Scenario,
        options: Optional[Options] = None,
        lexicon: Optional[Lexicon] = None,
        trace: bool = False,
    ):
        """Wire the core for ``scenario``; with ``trace``, keep every WM event for :meth:`trace`."""
        self.scenario = scenario
        self.options = options or Options()
        self.lexicon = lexicon or Lexicon.load()
        self.policies = effective_policies(scenario, self.options)
        self.events: Optional[list[WMEvent]] = [] if trace else None
        self.consultants = scenario.consultants(sink=self.events.append if self.events is not None else None)
        self.ports = {d: LocalPort(c) for d, c in self.consultants.items()}
        self.manager = WMManager()
        for domain, consultant in self.consultants.items():
            self.manager.manage(consultant.wm, self.policies[domain], now=0.0)
        self._properties = scenario.properties()

    def run(self) -> dict:
        """Play every turn; return the result object."""
        turns = [self.play(turn) for turn in self.scenario.dialogue]
        return {"scenario": self.scenario.name, "memory": self.manager.effective(), "turns": turns}

    def play(self, turn: Turn) -> dict:
        self.manager.advance(turn.time)  # ticks at or before T come first
        if turn.speaker == "human":
            unknown_words = None
            description = list(turn.description or ())
            if turn.text is not None:
                parsed = self.lexicon.parse(turn.text, self._properties)
                description, unknown_words = parsed.properties, parsed.unknown_words
            resolution = run_sync(
                resolve(description, self.ports, domain=turn.domain, time=turn.time, turn=turn.index)
            )
            return human_record(turn, resolution.to_json(), unknown_words)
        domain = self.scenario.domain_of(turn.target)  # type: ignore[arg-type]
        expression = run_sync(
            generate(
                turn.target,  # type: ignore[arg-type]
                self.ports[domain],
                algorithm_for(self.policies[domain].retains, self.options.algorithm),
                context=turn.context,
                wm_order=self.options.wm_order,
                time=turn.time,
                turn=turn.index,
            )
        )
        expression.text = self.lexicon.realise(expression.description, domain)
        return robot_record(turn, expression.to_json())

    def trace(self) -> list[dict]:
        """Return every encode/forget event so far, in the order they happened (needs ``trace=True``)."""
        if self.events is None:
            raise ValueError("this simulation keeps no trace: build it with trace=True")
        for consultant in self.consultants.values():
            consultant.wm.flush()
        return trace_order(self.scenario, [e.to_json() for e in self.events])


#: Forget causes driven by the clock alone, reported at their own time (:func:`trace_order`).
CLOCK_CAUSES = ("decay", "activation")


def trace_order(scenario: Scenario, events: list[dict]) -> list[dict]:
    """Events in the order an eager buffer would have emitted them.

    Lazy decay emits a queue's decay events when the queue is next touched, with the
    tick's own time (lazy activation likewise, with the crossing time), and a graph
    delivers events from several consultants in any interleaving.  Sorting by time,
    clock-driven forgetting (decay, activation) first at equal times (ticks at T come
    before events stamped T), those of one time in domain and entity order, and
    otherwise in arrival order, gives one canonical trace for both.
    """
    domain_rank = {d: i for i, d in enumerate(scenario.domains)}
    entity_rank = {e: i for spec in scenario.domains.values() for i, e in enumerate(spec.entities)}

    def key(i: int) -> tuple:
        event = events[i]
        decay = event.get("cause") in CLOCK_CAUSES
        place = (0, 0)
        if decay:
            place = (
                domain_rank.get(event.get("domain"), len(domain_rank)),
                entity_rank.get(event.get("entity"), len(entity_rank)),
            )
        return (event.get("time") or 0.0, not decay, place, i)

    return [events[i] for i in sorted(range(len(events)), key=key)]


def simulate(scenario: Scenario, options: Optional[Options] = None, lexicon: Optional[Lexicon] = None) -> dict:
    """Run a scenario and return the result object."""
    return Simulation(scenario, options, lexicon).run()


def dumps(result: Mapping[str, Any]) -> str:
    """Return the canonical JSON text of a result: byte-identical for equal results.

    The text is exactly what ``json.dumps(result, sort_keys=True, indent=2,
    ensure_ascii=False)`` returns, and a line break.  The standard library writes an indented text with
    its pure-Python encoder, one generator step per value; a large world's result holds
    hundreds of thousands of entity names (candidate and distractor lists), so
    :func:`_indented` writes the same bytes with each list of strings joined at once.
    Anything it does not know (a key that is not a string, a value of another type)
    goes to ``json.dumps`` whole.
    """
    try:
        parts: list[str] = []
        _indented(result, "\n", parts)
    except _Unusual:
        return json.dumps(result, sort_keys=True, indent=2, ensure_ascii=False) + "\n"
    parts.append("\n")
    return "".join(parts)


class _Unusual(Exception):
    """A value :func:`_indented` leaves to ``json.dumps``."""


_FLOAT_WORDS = {float("inf"): "Infinity", float("-inf"): "-Infinity"}


def _indented(value: Any, newline: str, out: list[str]) -> None:
    """Append ``value`` as ``json.dumps(sort_keys=True, indent=2, ensure_ascii=False)`` writes it.

    ``newline`` is the line break and indentation of the value's own level.
    """
    kind = value.__class__
    if kind is str:
        out.append(_string(value))
    elif kind is dict:
        if not value:
            out.append("{}")
            return
        inner = newline + "  "
        for key in value:
            if key.__class__ is not str:
                raise _Unusual
        opened = "{"
        for key in sorted(value):
            out.append(opened + inner + _string(key) + ": ")
            _indented(value[key], inner, out)
            opened = ","
        out.append(newline + "}")
    elif kind is list or kind is tuple:
        if not value:
            out.append("[]")
            return
        inner = newline + "  "
        try:  # the common case: a list of names, joined at C speed
            out.append("[" + inner + ("," + inner).join(map(_string, value)) + newline + "]")
            return
        except TypeError:
            pass
        opened = "["
        for item in value:
            out.append(opened + inner)
            _indented(item, inner, out)
            opened = ","
        out.append(newline + "]")
    elif value is None:
        out.append("null")
    elif value is True:
        out.append("true")
    elif value is False:
        out.append("false")
    elif kind is int:
        out.append(int.__repr__(value))
    elif kind is float:
        if value != value:
            out.append("NaN")
        elif value in _FLOAT_WORDS:
            out.append(_FLOAT_WORDS[value])
        else:
            out.append(float.__repr__(value))
    else:
        raise _Unusual
