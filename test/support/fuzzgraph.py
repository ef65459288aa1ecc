"""Fuzzing the running node graph: the inputs of :mod:`fuzzinputs` sent to each endpoint, and the checks on each.

Used by ``test/ros/test_fuzz_graph.py`` (bounded, fixed seed) and ``scripts/fuzz.py``
(longer runs).  The graph is the runner's (``graph.graph_nodes``) in one process on
sim time (``rosutil.RosSession``), the player left out; the test talks through the probe.

Every input is one of:

* random JSON (any value, any object) or non-JSON text;
* a structure-aware mutation of a valid message of that endpoint: a required field
  dropped or given the wrong type, a known name replaced by an unknown one, a number
  replaced by a hostile one (``1e999``, ``NaN``, ``Infinity``, 1e308, 2**64, a 401-digit
  integer, also as a certainty in ``ltm/assert``), a lone surrogate, a very long string,
  deep nesting, extra fields;
* each hostile input right after a malformed message on the same endpoint
  (:func:`fuzz_after_malformed`: a node once died when one logging call site saw a
  warning and then an error).

Each input carries whether it MUST be rejected (``invalid``) or may be accepted.  The
checks (:meth:`Fuzzer.check`): the call or message is answered (topics: a message on
the reply topic; ``/ltm/assert`` naming no consultant's domain has no reply by
contract), an invalid input is rejected with a reason (an ``error`` field), a
rejected input leaves every domain's WM and LTM and the WM Manager's status exactly
as they were (a consultant's liveliness lapse under load, which the WM Manager's status
shows and heals with a configure, is not counted: after a lapse, or a difference only in
the liveliness and configuration flags, the fuzzer waits until the graph is ready with every
consultant reachable and configured and compares what matters, :meth:`Fuzzer.healed`), and no callback
raised (an exception out of a callback is a node that dies in a real process).  A message
that has no reply by contract (``consultant/announce``, an ``ltm/assert`` for no consultant's
domain) is followed by one that must be answered or seen after it on the same topic, so the
check never waits on a silence.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Optional

import itertools

from hypothesis import HealthCheck, given, settings

from rosutil import RosSession, Timeout

from fsreg_ros import contract
from fsreg_ros.ros.carrier import CarrierError
from fsreg_ros.core.scenario import Scenario, load_scenario

from fuzzinputs import ALIVE, ANNOUNCE, CONSULTANT, DEBUG, INCARNATION, LTM_ASSERT, MANAGE, READY, REG_EXPRESSION, \
    REG_REQUEST, REPLY_TOPIC, SESSION, STATUS, SYNC, TIME, Input, catalogue, hostile, inputs, templates

REPLY_TIMEOUT = 5.0
HEAL_TIMEOUT = 15.0  # at most this long for the graph to be ready again after a consultant's liveliness lapse


@dataclass
class Outcome:
    """What one endpoint did with the inputs it was sent."""

    tried: int = 0
    rejected: int = 0
    accepted: int = 0
    unanswered: list[str] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    accepted_invalid: list[str] = field(default_factory=list)
    changed_by_rejected: list[str] = field(default_factory=list)
    reasonless: list[str] = field(default_factory=list)

    def failures(self) -> list[str]:
        return [
            *(f"unanswered: {s}" for s in self.unanswered),
            *(f"crash: {s}" for s in self.crashes),
            *(f"accepted an invalid input: {s}" for s in self.accepted_invalid),
            *(f"a rejected input changed memory: {s}" for s in self.changed_by_rejected),
            *(f"rejected without a reason: {s}" for s in self.reasonless),
        ]


# ---------------------------------------------------------------------- runner
class Fuzzer:
    """Sends inputs to one in-process graph and checks what it does with them."""

    def __init__(self, start: Callable[[], RosSession], scenario: Scenario) -> None:
        self.start = start
        self.scenario = scenario
        self.domains = list(scenario.domains)
        self.outcomes: dict[str, Outcome] = {}
        self.restarts = 0
        self._markers = itertools.count()
        self.state: Optional[dict] = None  # the last snapshot, while nothing has been accepted since
        self._open()
        spec = scenario.domains[self.domains[0]]
        self.seed_wm = {"op": "encode", "entity": next(iter(spec.entities)), "properties": list(spec.preference[:2]),
                        "cause": "speaker", "time": TIME}

    def _open(self) -> None:
        self.state = None
        self.g = self.start()
        self.inboxes = {topic: self.g.listen(topic) for topic in set(REPLY_TOPIC.values()) if topic is not None}
        # Every readiness the WM Manager publishes (a deeper reader than the latched writer's 1: none is missed).
        self.readiness = self.g.listen(READY, replace(contract.READY_QOS, depth=100))
        self._lapses_seen = 0

    def restart(self) -> None:
        """Start a fresh graph after a callback raised (a real node process would have died)."""
        self.close()
        self.restarts += 1
        self._open()

    def close(self) -> None:
        self.g.close()

    def session(self, service: str) -> str:
        """Open a REG session at ``service`` (its target: the first entity); return its id."""
        spec = self.scenario.domains[self.domains[0]]
        return self.g.call(service, {"op": "open", "target": next(iter(spec.entities))},
                           timeout=REPLY_TIMEOUT)["session"]

    # ----------------------------------------------------------- memory state
    def snapshot(self) -> dict:
        """Every domain's WM queues and LTM, and the WM Manager's status.

        LTM is seen through ``info``: its ``version`` changes whenever LTM does, and it
        lists the entities, the preference order, the threshold and the events published.
        """
        state: dict[str, Any] = {"status": self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)}
        for domain in self.domains:
            service, debug = CONSULTANT.format(domain=domain), DEBUG.format(domain=domain)
            state[domain] = {"info": self.g.call(service, {"op": "info"}, timeout=REPLY_TIMEOUT),
                             "wm": self.g.call(debug, {"op": "snapshot"}, timeout=REPLY_TIMEOUT)}
        return state

    def lapsed(self) -> bool:
        """Whether the WM Manager found a consultant's liveliness lapsed since the last call.

        In this one-process graph a consultant's liveliness shows only through its alive
        writes (every 0.25 s, lease 1 s), which wait on the one executor: under load the
        lease can run out and heal, the status flipping to unreachable and back.
        """
        lapses = sum(1 for ready in self.readiness for dom in ready["domains"].values() if dom["reachable"] is False)
        seen, self._lapses_seen = self._lapses_seen, lapses
        return lapses > seen

    def healed(self) -> dict:
        """Return a snapshot taken while the graph is ready, every consultant reachable and configured.

        Waits (at most ``HEAL_TIMEOUT`` s) until the snapshot's own status shows it: a lapse
        that heals is followed by a configure, and under load another lapse may begin while
        a snapshot is taken, so the status is judged inside the snapshot compared.
        """
        taken: list[dict] = []

        def steady() -> bool:
            taken[:] = [self.snapshot()]
            return _healthy(taken[0])
        self.g.spin_until(steady, HEAL_TIMEOUT, what="the graph ready, every consultant reachable and configured")
        self.lapsed()
        return taken[0]

    def state_before(self) -> dict:
        """Return the snapshot before an input, with something in WM so that a change to it can be seen."""
        if self.state is None or not _healthy(self.state):  # never compare with a snapshot taken in a lapse
            self.state = self.healed()
        domain = self.domains[0]
        if not self.state[domain]["wm"]["queues"]:
            self.g.call(MANAGE.format(domain=domain),
                        {"op": "configure", "policy": {"policy": "decay", "decay_period": 10.0}, "time": TIME})
            self.g.call(DEBUG.format(domain=domain), self.seed_wm)
            self.state = self.healed()
        return self.state

    # ------------------------------------------------------------------ sending
    def call(self, service: str, text: str) -> tuple[Optional[dict], Optional[str]]:
        """Call ``service`` with raw JSON text: (reply, None) or (None, error reason); Timeout if unanswered."""
        from diagnostic_msgs.srv import AddDiagnostics

        if SESSION in text:
            text = text.replace(SESSION, self.session(service))
        client = self.g.client(service)
        self.g.wait_service(service, REPLY_TIMEOUT)
        future = client.client.call_async(AddDiagnostics.Request(load_namespace=text))
        try:
            return self.g.run(client.result(future, REPLY_TIMEOUT), REPLY_TIMEOUT + 1.0), None
        except CarrierError as err:
            if err.kind == "timeout":
                raise Timeout(f"{service}: no answer in {REPLY_TIMEOUT} s") from None
            return None, str(err)

    def publish(self, topic: str, text: str) -> tuple[Optional[dict], Optional[str]]:
        """Publish raw text on ``topic``; (reply, None), (None, reason), or (None, None) if no reply is due.

        A message with no reply by contract is followed by one that must be answered
        (or seen) after it, so that it has been handled when this returns.
        """
        if topic == ANNOUNCE:
            self.g.publish(topic, text.replace(str(INCARNATION), str(self.incarnation())), contract.ANNOUNCE.qos)
            self._announce_marker()
            return None, None
        if topic == ALIVE:  # read by RR's and REG's consultant ports: a REG answer comes after it
            self.g.publish(topic, text.replace(str(INCARNATION), str(self.incarnation())), contract.ALIVE.qos)
            self._reg_marker()
            return None, None
        inbox = self.inboxes[REPLY_TOPIC[topic]]
        before = len(inbox)
        self.g.publish(topic, text)
        if topic == LTM_ASSERT and not self._names_a_consultant(text):
            self._ltm_marker(inbox)
            return None, None
        self.g.spin_until(lambda: len(inbox) > before, REPLY_TIMEOUT, what=f"a reply on {REPLY_TOPIC[topic]}")
        reply = inbox[before]
        if reply.get("error"):
            return None, str(reply["error"])
        return reply, None

    def incarnation(self) -> int:
        """Return the current incarnation of the first domain's consultant (the WM Manager's view)."""
        return self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)["incarnation"][self.domains[0]]

    def _ltm_marker(self, inbox) -> None:
        """Publish an assertion the consultant must refuse (no entity) and wait for its refusal."""
        marker = f"fuzz-sync-{next(self._markers)}"
        self.g.publish(LTM_ASSERT, {"domain": self.domains[0], "id": marker})
        self.g.spin_until(lambda: inbox.latest(id=marker) is not None, REPLY_TIMEOUT, what=f"the reply to {marker}")

    def _reg_marker(self) -> None:
        """Ask REG for a description (through its consultant port) and wait for the answer."""
        marker = f"fuzz-sync-{next(self._markers)}"
        inbox = self.inboxes[REG_EXPRESSION]
        entity = next(iter(self.scenario.domains[self.domains[0]].entities))
        self.g.publish(REG_REQUEST, {"id": marker, "target": entity, "time": TIME})
        self.g.spin_until(lambda: inbox.latest(id=marker) is not None, REPLY_TIMEOUT, what=f"the reply to {marker}")
        self.state = None  # REG encoded what it said

    def _announce_marker(self) -> None:
        """Announce the current incarnation with a marked setting; wait until the WM Manager reports it."""
        marker = next(self._markers)
        domain = self.domains[0]
        self.g.publish(ANNOUNCE, {"domain": domain, "incarnation": self.incarnation(), "ready": True,
                                  "memory": {"policy": "none", "fuzz_marker": marker}}, contract.ANNOUNCE.qos)
        self.g.spin_until(
            lambda: (self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)["running"][domain] or {}).get("fuzz_marker")
            == marker, REPLY_TIMEOUT, what=f"announce marker {marker}")
        self.state = None  # the status now reports the marker

    def _configured(self, incarnation: int) -> None:
        """After an accepted ``reset``: wait until the WM Manager has configured the new incarnation.

        (The reset's reply comes before that configure, so a snapshot taken at once would
        see the graph become ready again and blame the next input.)
        """
        domain = self.domains[0]

        def configured() -> bool:
            status = self.g.call(STATUS, {}, timeout=REPLY_TIMEOUT)
            return status["incarnation"][domain] == incarnation and status["ready"] is True
        self.g.spin_until(configured, REPLY_TIMEOUT, what=f"incarnation {incarnation} configured after a reset")

    def _names_a_consultant(self, text: str) -> bool:
        """Whether an ``/ltm/assert`` message is due a reply: malformed, or for a known domain."""
        try:
            data = json.loads(text)
        except (ValueError, RecursionError):
            return True
        if not isinstance(data, dict) or not isinstance(data.get("domain"), str):
            return True
        return data["domain"] in self.domains

    # ------------------------------------------------------------------ checking
    def check(self, endpoint: str, given: Input, verify_memory: bool = True) -> None:
        """Send one input to ``endpoint`` and record what happened (never raises for a finding).

        ``verify_memory`` false: a rejection is not compared with a snapshot (for inputs
        whose effect on memory is checked elsewhere).
        """
        outcome = self.outcomes.setdefault(endpoint, Outcome())
        outcome.tried += 1
        label = f"{given.how}: {_clip(given.text)}"
        try:
            before = self.state_before()
        except Exception as err:  # noqa: BLE001 - the graph was already broken by an earlier input
            outcome.crashes.append(f"before {label}: {type(err).__name__}: {_clip(str(err))}")
            self.restart()
            return
        try:
            send = self.publish if endpoint in REPLY_TOPIC else self.call
            reply, reason = send(endpoint, given.text)
        except Timeout as err:
            outcome.unanswered.append(f"{label} ({err})")
            return
        except Exception as err:  # noqa: BLE001 - a callback raised: the node would have died
            outcome.crashes.append(f"{label}: {type(err).__name__}: {_clip(str(err))}")
            self.restart()
            return
        if reply is None and reason is None:  # nobody's message: no reply by contract
            return
        if reason is None:
            outcome.accepted += 1
            self.state = None
            if endpoint == MANAGE.format(domain=self.domains[0]) and "cleared" in reply:
                self._configured(reply["incarnation"])
            if given.invalid:
                outcome.accepted_invalid.append(f"{label} -> {_clip(json.dumps(reply))}")
            return
        outcome.rejected += 1
        if not reason.strip():
            outcome.reasonless.append(label)
        if not verify_memory:
            return
        try:
            after = self.snapshot()
        except Exception as err:  # noqa: BLE001
            outcome.crashes.append(f"after {label}: {type(err).__name__}: {_clip(str(err))}")
            self.restart()
            return
        was, now = before, after
        lapsed = self.lapsed()  # (always asked: a lapse is counted once, at the first check after it)
        if after != before and (lapsed or not _healthy(after) or _reconfigured(after) == _reconfigured(before)):
            # a lapse under load is no change of state: compare what matters once healed and configured
            try:
                after = self.healed()
            except Timeout as err:  # never healed: the input left the graph unready
                outcome.changed_by_rejected.append(f"{label} ({_diff(before, after)}; {err})")
                self.state = None
                return
            was, now = _reconfigured(before), _reconfigured(after)
        self.state = after
        if now != was:
            outcome.changed_by_rejected.append(f"{label} ({_diff(was, now)})")

    def report(self, endpoints: Optional[list[str]] = None) -> str:
        lines = []
        for endpoint, o in sorted(self.outcomes.items()):
            if endpoints is not None and endpoint not in endpoints:
                continue
            lines.append(f"{endpoint}: {o.tried} inputs, {o.rejected} rejected, {o.accepted} accepted, "
                         f"{len(o.crashes)} crashes, {len(o.unanswered)} unanswered, "
                         f"{len(o.accepted_invalid)} invalid accepted, "
                         f"{len(o.changed_by_rejected)} changed by rejected")
            lines += [f"    {f}" for f in _dedupe(o.failures())]
        return "\n".join(lines)


#: The status fields a consultant's liveliness lapse and the configure after it change by themselves.
LIVELINESS_FIELDS = ("ready", "configured", "reachable", "running")


def _healthy(state: dict) -> bool:
    """Whether a snapshot's status shows the graph ready, every consultant reachable and configured."""
    status = state["status"]
    return (status["ready"] is True and all(v is True for v in status["reachable"].values())
            and all(v is True for v in status["configured"].values()))


def _reconfigured(state: dict) -> dict:
    """``state`` without what a consultant's liveliness lapse and the WM Manager's configure after it change.

    The status's liveliness and configuration flags (``ready``, ``configured``,
    ``reachable``), its ``running`` (the consultant announces what it runs after a
    configure, over the fuzzer's own announcements), and each domain's ``wm_version`` (a
    configure is a call that touches WM).  What matters is still compared: each domain's
    WM queues (the same policy keeps them), LTM (``info``), and the status's configuration
    values (``memory``, ``incarnation``, ...).
    """
    return {key: {**value, **dict.fromkeys(LIVELINESS_FIELDS)} if key == "status"
            else {**value, "info": {**value["info"], "wm_version": None}} for key, value in state.items()}


def _clip(text: str, limit: int = 160) -> str:
    text = text.encode("unicode_escape", "backslashreplace").decode("ascii")
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} chars)"


def _diff(before: dict, after: dict) -> str:
    keys = [f"{k}.{j}" for k in before for j in before[k] if before[k][j] != after.get(k, {}).get(j)]
    return "changed: " + ", ".join(keys)


def _dedupe(lines: list[str], limit: int = 12) -> list[str]:
    counts = Counter(lines)
    out = [f"{line}" + (f" (x{n})" if n > 1 else "") for line, n in counts.items()]
    return out[:limit] + ([f"... {len(out) - limit} more"] if len(out) > limit else [])


def start_graph(scenario_path: Path, tmp_path: Path, service_timeout: float = 2.0) -> RosSession:
    """Start the runner's nodes (not the player) in one in-process graph on sim time, at TIME, synced.

    The WM Manager's deadline per consultant call is short, so a stuck call costs the
    fuzz little.
    """
    from fsreg_ros.core.simulation.simulator import Options
    from fsreg_ros.tools.graph import graph_nodes
    from test_graph import NODE_CLASSES

    g = RosSession()
    scenario = load_scenario(scenario_path)
    for spec in graph_nodes(scenario, scenario_path, Options(memory={"policy": "decay"}), tmp_path / "r.json")[:-1]:
        params = dict(spec.parameters)
        if spec.executable == "wm_manager":
            params["service_timeout"] = service_timeout
        if spec.executable == "consultant":
            params["debug"] = True  # the fuzzer reads WM and LTM through the debug service
        sim_time = params.pop("use_sim_time", False)
        g.add(NODE_CLASSES[spec.executable], use_sim_time=sim_time, name=spec.name, **params)
    g.set_time(TIME)
    g.call(SYNC, {"time": TIME}, timeout=10.0)
    return g


#: Sent before each hostile input by :func:`fuzz_after_malformed`.
MALFORMED = Input("{", True, "malformed (before a hostile input)")


def fuzz_after_malformed(fuzzer: Fuzzer, endpoint: str, first_id: int = 50_000) -> None:
    """Send each hostile input of ``endpoint`` right after a malformed message."""
    ids = itertools.count(first_id)
    for i, template in enumerate(templates(fuzzer.scenario)[endpoint]):
        for given_input in hostile(template, ids, extra=i == 0):  # extra fields: the endpoint's, once
            fuzzer.check(endpoint, MALFORMED, verify_memory=False)  # the catalogue checks it changes nothing
            fuzzer.check(endpoint, given_input)


def fuzz_catalogue(fuzzer: Fuzzer, endpoint: str, first_id: int = 10_000) -> None:
    """Send every catalogued hostile input to ``endpoint``."""
    ids = itertools.count(first_id)
    for i, template in enumerate(templates(fuzzer.scenario)[endpoint]):
        for given_input in catalogue(template, ids, raw=i == 0):
            fuzzer.check(endpoint, given_input)


def fuzz_generated(fuzzer: Fuzzer, endpoint: str, examples: int, first_id: int = 30_000) -> None:
    """Send ``examples`` generated inputs (fixed seed) to ``endpoint``."""
    strategy = inputs(templates(fuzzer.scenario)[endpoint], itertools.count(first_id))

    @settings(max_examples=examples, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def fuzz(given_input):
        fuzzer.check(endpoint, given_input)

    fuzz()


def fuzz_endpoint(fuzzer: Fuzzer, endpoint: str, examples: int, first_id: int = 10_000) -> None:
    """Send every catalogued hostile input, then ``examples`` generated ones (fixed seed), to ``endpoint``."""
    fuzz_catalogue(fuzzer, endpoint, first_id)
    fuzz_generated(fuzzer, endpoint, examples, first_id + 500)
