"""A recorded live session replayed through the simulator, turn by turn: the graph against the model.

:func:`session_of` turns a recording (:mod:`fsreg_ros.core.io.recording`) into the simulator's
input: the knowledge base the graph ran with (copied into the recording, or given), each
domain's memory setting (from ``wm_manager/ready``), REG's options, and in recorded order the
human utterances (``dialogue/human``), REG requests (``reg/request``) and accepted LTM
assertions (``ltm/assert`` whose ``ltm/assert/result`` is ok), each with the answer the graph
gave and the time it used (the answer's ``time``).  Resent requests (one id) count once.
A request the recording lacks (its sender left before the recorder heard it) is rebuilt
from what the graph's long-lived nodes forwarded: an utterance from the parser's
``dialogue/semantics`` (its text or properties, its domain) or RR's answer, a REG request
from REG's ``reg/expression`` (id, target, time), an LTM assertion of one entity from its
``ltm/assert/result`` (what it changed); the replay says how many it rebuilt.

:func:`replay` plays them through the core (:class:`~fsreg_ros.core.simulation.simulator.Simulation`)
and compares, per turn, the answer (RR: status, resolved entity, candidates, description;
REG: description, text, sources, WM before, distinguishing, distractors left) and every
domain's working memory after the turn.  The WM on both sides is rebuilt the same way,
from the encode/forget events (the graph's ``wm/events``, the simulator's trace) in the
canonical trace order, up to the turn's time: so several turns at one time are compared
after the last of them.

A recording that cannot be replayed faithfully is refused with one line
(:class:`ReplayError`): no knowledge base, no human utterance or REG request (nothing
would be compared), WM not empty when the recording began, a memory
setting changed mid-session, a gap in a consultant's events, answers from two graphs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Optional

from ..lexicon import Lexicon
from ..io.recording import Message, Recording
from .replay_world import world_mismatch
from ..scenario import Scenario, Turn, load_scenario
from .simulator import Options, Simulation, trace_order

#: The answer fields compared per kind of turn.
HUMAN_FIELDS = ("status", "resolved", "candidates", "description")
ROBOT_FIELDS = ("description", "text", "sources", "wm_before", "distinguishing", "distractors_left")
#: Each kind of step: the role of the topic its requests are recorded on, and of its answers'.
REQUESTS = {"human": ("human", "rr"), "robot": ("request", "expression"), "assert": ("assert", "assert_result")}
#: The kinds of request a replay can rebuild from the graph's answer when the request itself is not recorded.
REBUILT = REQUESTS


class ReplayError(ValueError):
    """A recording that cannot be replayed (one line naming the recording and why)."""


@dataclass
class Step:
    """One recorded request (``human``, ``robot``) or accepted LTM assertion (``assert``) with the graph's answer."""

    kind: str
    request: dict
    answer: Optional[dict]
    time: float


@dataclass
class Session:
    """What a recording says the graph was asked, what it answered, and what it ran with."""

    path: Path
    scenario: Scenario
    lexicon: Lexicon
    memory: dict[str, dict]
    options: Options
    steps: list[Step]
    events: list[dict]
    graph: Optional[str] = None
    notes: list[str] = field(default_factory=list)


def _data(messages: list[Message]) -> list[dict]:
    return [m.data for m in messages if isinstance(m.data, dict)]


def session_of(recording: Recording, scenario_path: Optional[Path] = None,
               lexicon_path: Optional[Path] = None) -> Session:
    """Return the replayable session a recording holds (see the module docstring); ReplayError if there is none."""
    where = str(recording.path)
    given = scenario_path
    scenario_path = scenario_path or recording.attached("scenario")
    if scenario_path is None:
        raise ReplayError(f"{where}: the recording carries no knowledge base (fsreg-ctl record found no graph to ask); "
                          "give it with --scenario FILE")
    lexicon_path = lexicon_path or recording.attached("lexicon")
    lexicon = Lexicon.load(lexicon_path)
    scenario = load_scenario(scenario_path, lexicon)
    ready = [d for d in _data(recording.on("ready")) if d.get("ready")]
    graphs = {d.get("graph") for d in ready if d.get("graph")} | (
        {recording.custom["fsreg.graph"]} if recording.custom.get("fsreg.graph") else set())
    if len(graphs) > 1:
        raise ReplayError(f"{where}: messages of {len(graphs)} graphs ({', '.join(sorted(graphs))}): "
                          "a replay needs one")
    graph = next(iter(graphs), None)

    def ours(data: dict) -> bool:
        return graph is None or data.get("graph") in (None, graph)

    memory = _memory(where, ready, scenario)
    _check_empty_start(where, recording)
    answers: dict[tuple[str, str], dict] = {}
    for kind, (_, answered_on) in REQUESTS.items():
        for data in _data(recording.on(answered_on)):
            if "id" in data and ours(data):
                answers.setdefault((kind, str(data["id"])), data)
    steps: list[Step] = []
    seen: set[tuple[str, str]] = set()
    asked = {(kind, str(d.get("id"))) for kind, (asked_on, _) in REQUESTS.items()
             for d in _data(recording.on(asked_on))}
    forwarded = {str(d.get("id")): d for d in _data(recording.on("semantics")) if ours(d)}
    rebuilt = 0
    clock = 0.0
    for message in recording.messages:
        role = recording.role(message)
        if role == "clock" and isinstance(message.data, float):
            clock = message.data
            continue
        kind = next((k for k, (asked_on, _) in REQUESTS.items() if asked_on == role), None)
        data = message.data
        if kind is None and isinstance(data, dict) and "id" in data and ours(data):
            kind = next((k for k, (_, answered_on) in REBUILT.items() if answered_on == role), None)
            key = (kind, str(data["id"]))
            if kind is None or key in asked or key in seen:
                continue
            data = _rebuilt(kind, data, forwarded.get(key[1]))
            if not data:
                continue
            rebuilt += 1
        if kind is None or not isinstance(data, dict):
            continue
        key = (kind, str(data.get("id")))
        if data.get("id") is not None and key in seen:
            continue  # sent again (at-least-once delivery): one request
        seen.add(key)
        answer = answers.get(key)
        if kind == "assert":
            if answer is not None and answer.get("ok"):
                steps.append(Step(kind, data, answer, clock))
            continue
        when = (answer or {}).get("time", data.get("time", clock))
        steps.append(Step(kind, data, answer, float(when if isinstance(when, (int, float)) else clock)))
    if not any(step.kind != "assert" for step in steps):
        raise ReplayError(f"{where}: the recording holds no human utterance or REG request with its graph "
                          "(nothing to replay: did the graph fail before its first turn?)")
    events = [d for d in _data(recording.on("events")) if ours(d)]
    check_events(where, events)
    algorithm = recording.custom.get("fsreg.algorithm")
    options = Options(algorithm=None if algorithm in (None, "", "auto") else algorithm,
                      wm_order=recording.custom.get("fsreg.wm_order") or "lru-first")
    notes = [recording.lost] if recording.lost else []
    other = world_mismatch(scenario, scenario_path, recording.attached("scenario") if given else None, steps,
                           events, ready)
    if rebuilt:
        notes.append(f"{where}: {rebuilt} request(s) not in the recording were rebuilt from what the graph's nodes "
                     "forwarded (dialogue/semantics, rr/result, reg/expression, ltm/assert/result): their sender left "
                     "before the recorder heard them")
    if other:
        notes.append(other)
    return Session(recording.path, scenario, lexicon, memory, options, steps, events, graph, notes)


def _rebuilt(kind: str, answer: dict, semantics: Optional[dict]) -> dict:
    """Return the request an answer (with the parser's forward of an utterance, if any) says was made."""
    request = {k: answer[k] for k in ("id", "time", "turn", "client") if answer.get(k) is not None}
    if kind == "assert":  # what the fact changed (asserting the rest again would change nothing)
        return {**request, "domain": answer.get("domain"), "entity": answer.get("entity"),
                "properties": dict(answer.get("updated") or {})} if answer.get("entity") else {}
    if kind == "robot":
        request["target"] = answer.get("target")
        if answer.get("context") is not None:
            request["context"] = answer["context"]
        return request
    said = semantics or answer
    if said.get("text") is not None:
        request["text"] = said["text"]
    else:
        request["description"] = list(said.get("description") or [])
    if said.get("domain") is not None and semantics is not None:
        request["domain"] = said["domain"]
    return request


def _memory(where: str, ready: list[dict], scenario: Scenario) -> dict[str, dict]:
    """Each domain's memory setting from ``wm_manager/ready``; the scenario's own if the recording has none."""
    settings: dict[str, dict] = {}
    for message in ready:
        for domain, state in (message.get("domains") or {}).items():
            running = (state or {}).get("running")
            if not isinstance(running, dict):
                continue
            if domain in settings and settings[domain] != running:
                raise ReplayError(f"{where}: the memory setting of '{domain}' changed during the recording "
                                  f"({settings[domain]} -> {running}): a replay plays one setting")
            settings[domain] = running
    return {d: settings.get(d) or scenario.policy_for(d).to_json() for d in scenario.domains}


def _check_empty_start(where: str, recording: Recording) -> None:
    first: dict[str, dict] = {}
    for data in _data(recording.on("state")):
        first.setdefault(str(data.get("domain")), data)
    for domain, state in first.items():
        if state.get("queues"):
            raise ReplayError(f"{where}: the WM of '{domain}' was not empty when the recording began "
                              f"({len(state['queues'])} entities at t={state.get('time')}); a replay starts from the "
                              "knowledge base: record from the graph's start (fsreg-up --record)")


def check_events(where: str, events: list[dict]) -> None:
    """Raise ReplayError if a consultant's recorded ``wm/events`` have a gap in ``seq`` (messages lost)."""
    last: dict[tuple, int] = {}
    for event in events:
        key = (event.get("domain"), event.get("incarnation"))
        seq = event.get("seq")
        if not isinstance(seq, int):
            continue
        before = last.get(key, 0)
        if seq == before:
            continue  # heard twice
        if seq != before + 1:
            raise ReplayError(f"{where}: wm/events of '{key[0]}' miss seq {before + 1}..{seq - 1} "
                              "(the recording lost messages): WM cannot be compared")
        last[key] = seq


def _turn(index: int, step: Step) -> Turn:
    data = step.request
    if step.kind == "human":
        description = data.get("description")
        return Turn(index, step.time, "human", text=data.get("text"),
                    description=tuple(description) if description is not None else None, domain=data.get("domain"))
    context = data.get("context")
    return Turn(index, step.time, "robot", target=data.get("target"),
                context=tuple(context) if context is not None else None)


def wm_at(events: list[dict], time: float) -> dict[str, dict[str, list[str]]]:
    """Return every domain's non-empty queues after the events stamped at or before ``time`` (in list order)."""
    queues: dict[str, dict[str, list[str]]] = {}
    for event in events:
        if float(event.get("time") or 0.0) > time + 1e-9:
            continue
        queue = queues.setdefault(str(event["domain"]), {}).setdefault(str(event["entity"]), [])
        prop = event["property"]
        if prop in queue:
            queue.remove(prop)
        if event["op"] == "encode":
            queue.append(prop)
    return {d: {e: q for e, q in qs.items() if q} for d, qs in queues.items() if any(qs.values())}


def _plain(event: dict) -> dict:
    return {k: event.get(k) for k in ("op", "domain", "entity", "property", "cause", "time")}


@dataclass
class TurnReport:
    """One replayed turn: what was asked, what the graph and the simulator answered, and what differs."""

    index: int
    kind: str
    time: float
    request: str
    live: str
    differences: list[str]


def replay(session: Session) -> list[TurnReport]:
    """Play the session through the core; return one report per turn (LTM assertions are applied, not reported)."""
    # each domain's entities copied: an asserted new entity joins this replay's scenario (REG looks targets up there)
    domains = {d: replace(spec, memory=session.memory[d], entities=dict(spec.entities))
               for d, spec in session.scenario.domains.items()}
    turns = [_turn(i, s) for i, s in enumerate(s for s in session.steps if s.kind != "assert")]
    scenario = replace(session.scenario, memory=None, domains=domains, dialogue=tuple(turns))
    sim = Simulation(scenario, session.options, session.lexicon, trace=True)
    played: list[tuple[Turn, Step, Optional[dict], Optional[str]]] = []
    index = 0
    for step in session.steps:
        if step.kind == "assert":
            data = step.request
            if data["domain"] in sim.consultants:
                sim.consultants[data["domain"]].assert_facts(data["entity"], data["properties"], step.time)
                scenario.domains[data["domain"]].entities.setdefault(data["entity"], dict(data["properties"]))
            continue
        turn = turns[index]
        index += 1
        try:
            record, error = sim.play(turn), None
        except ValueError as err:  # the simulator refuses it (an unknown entity, ...)
            record, error = None, str(err)
        played.append((turn, step, record, error))
    sim_events = sim.trace()
    live_events = trace_order(scenario, [_plain(e) for e in session.events])
    reports = []
    for position, (turn, step, record, error) in enumerate(played):
        later = played[position + 1][0].time if position + 1 < len(played) else None
        last_at_time = later is None or later > turn.time + 1e-9
        differences = _compare(step, record, error)
        if last_at_time:
            live_wm, sim_wm = wm_at(live_events, turn.time), wm_at(sim_events, turn.time)
            differences += _wm_differences(live_wm, sim_wm)
        reports.append(TurnReport(turn.index, step.kind, turn.time, _request_text(step), _answer_text(step),
                                  differences))
    return reports


def _compare(step: Step, record: Optional[dict], error: Optional[str]) -> list[str]:
    live = step.answer
    if live is None:
        return ["the graph's answer is not in the recording"]
    live_error = live.get("error") if (live.get("status") == "error" or "error" in live) else None
    sim_error = error or (record or {}).get("error")
    if live_error or sim_error:
        if live_error and sim_error:
            return []
        return [f"live {'refused: ' + str(live_error) if live_error else 'answered'}, replay "
                f"{'refused: ' + str(sim_error) if sim_error else 'answered'}"]
    fields = HUMAN_FIELDS + (("unknown_words",) if step.request.get("text") is not None else ()) \
        if step.kind == "human" else ROBOT_FIELDS
    out = []
    for name in fields:
        a, b = live.get(name), (record or {}).get(name)
        if name == "unknown_words":
            a, b = a or [], b or []
        if a != b:
            out.append(f"{name}: live {_short(a)}, replay {_short(b)}")
    return out


def _wm_differences(live: dict, sim: dict) -> list[str]:
    out = []
    for domain in sorted(set(live) | set(sim)):
        a, b = live.get(domain, {}), sim.get(domain, {})
        for entity in sorted(set(a) | set(b)):
            if a.get(entity, []) != b.get(entity, []):
                live_q, sim_q = _short(a.get(entity, [])), _short(b.get(entity, []))
                out.append(f"WM {domain}/{entity}: live {live_q}, replay {sim_q}")
    return out


def _short(value: Any, limit: int = 120) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _request_text(step: Step) -> str:
    data = step.request
    if step.kind == "human":
        return f'"{data["text"]}"' if data.get("text") is not None else ", ".join(data.get("description") or [])
    return str(data.get("target")) + (f" among {', '.join(data['context'])}" if data.get("context") else "")


def _answer_text(step: Step) -> str:
    answer = step.answer or {}
    if "error" in answer:
        return f"error: {answer['error']}"
    if step.kind == "human":
        resolved = f"{answer.get('resolved')} " if answer.get("status") == "resolved" else ""
        return f"{resolved}({answer.get('status')})"
    return str(answer.get("text"))


def render(session: Session, reports: list[TurnReport]) -> str:
    """Return the replay's report: one line per turn (and one per difference), then the verdict."""
    lines = [f"replay of {session.path}: {len(reports)} turns, memory "
             + "; ".join(f"{d}: {m}" for d, m in session.memory.items())]
    lines += [f"note: {note}" for note in session.notes]
    lines.append("turn  time      speaker  request -> live answer: replay")
    for r in reports:
        speaker = "human" if r.kind == "human" else "robot"
        verdict = "equal" if not r.differences else "DIFF"
        lines.append(f"{r.index:4}  {r.time:8.2f}  {speaker:7}  {r.request} -> {r.live}: {verdict}")
        lines += [f"      {d}" for d in r.differences]
    differ = [r for r in reports if r.differences]
    if differ:
        first = differ[0]
        lines.append(f"replay: {len(differ)} of {len(reports)} turns differ from the live graph (first: turn "
                     f"{first.index} at t={first.time:g})")
    else:
        lines.append(f"replay: all {len(reports)} turns equal the live graph (answers and WM)")
    return "\n".join(lines) + "\n"
