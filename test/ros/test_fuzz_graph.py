"""Fuzz every topic and service of the running graph (in-process, sim time, fixed seed).

See ``fuzzgraph`` for the inputs and the checks.  The quick suite sends every hostile
input right after a malformed one on every endpoint; the catalogue (every hostile
mutation, field by field) and the generated inputs (``FUZZ_EXAMPLES`` per endpoint) are
marked slow, and ``scripts/fuzz.py`` runs the same fuzzer longer.  ``fuzzwire`` sends
what no schema can save (deep nesting, the oversized message of issue 38.1, huge strings,
bytes that are not UTF-8, ...) to every endpoint the contract declares, in this graph
and in a graph of node processes, which must all still be running and answering after.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from fuzzgraph import Fuzzer, Outcome, fuzz_after_malformed, fuzz_catalogue, fuzz_generated, start_graph
from fuzzinputs import CONSULTANT, DEBUG, ENDPOINTS, NOT_JSON, REPLY_TOPIC, Input, templates

from fuzzwire import TIME as WIRE_TIME, WireFuzz, endpoints

from fsreg_ros import contract
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.testing import LiveGraph

pytestmark = pytest.mark.graph
FUZZ_EXAMPLES = 20


@pytest.fixture(scope="module")
def fuzzer(table1_path, tmp_path_factory):
    scenario = load_scenario(table1_path)
    fuzzer = Fuzzer(lambda: start_graph(table1_path, tmp_path_factory.mktemp("fuzz")), scenario)
    yield fuzzer
    fuzzer.close()


#: Topics the graph only publishes (its answers and state): nothing in the graph (the player aside) reads them.
# What the graph publishes for others (its clients); the fuzzer attacks what the graph reads.
OUTPUTS = {contract.RR_RESULT, contract.REG_EXPRESSION, contract.WM_STATE, contract.WM_EVENTS,
           contract.LTM_ASSERT_RESULT, contract.READY}


def test_the_fuzzed_endpoints_are_every_endpoint(table1_path):
    assert sorted(templates(load_scenario(table1_path))) == sorted(ENDPOINTS)
    inputs = [t.name for t in contract.TOPICS if t not in OUTPUTS] + [s.name for s in contract.SERVICES]
    fuzzed = {e.lstrip("/").replace("/faces", "/<domain>") for e in ENDPOINTS}
    assert sorted(set(inputs) - fuzzed) == []  # every input of the graph is fuzzed


def check_outcome(fuzzer: Fuzzer, endpoint: str) -> Outcome:
    outcome = fuzzer.outcomes[endpoint]
    assert not outcome.failures(), "\n" + fuzzer.report([endpoint])
    assert fuzzer.restarts == 0, "a callback raised: " + fuzzer.report([endpoint])
    return outcome


@pytest.mark.slow
@pytest.mark.parametrize("endpoint", ENDPOINTS)
def test_every_catalogued_input_is_answered_and_rejections_change_nothing(fuzzer, endpoint):
    """Every hostile mutation of every valid message, field by field (deterministic)."""
    fuzzer.outcomes.pop(endpoint, None)
    fuzz_catalogue(fuzzer, endpoint, first_id=10_000 + 1_000 * ENDPOINTS.index(endpoint))
    outcome = check_outcome(fuzzer, endpoint)
    if REPLY_TOPIC.get(endpoint, "") is not None:  # consultant/announce has no replies by contract
        assert outcome.rejected >= len(NOT_JSON)


@pytest.mark.slow
@pytest.mark.parametrize("endpoint", ENDPOINTS)
def test_generated_inputs_are_answered_and_rejections_change_nothing(fuzzer, endpoint):
    """Generated inputs (fixed seed): mutations of valid messages, random JSON, text."""
    fuzzer.outcomes.pop(endpoint, None)
    fuzz_generated(fuzzer, endpoint, FUZZ_EXAMPLES, first_id=30_000 + 1_000 * ENDPOINTS.index(endpoint))
    assert check_outcome(fuzzer, endpoint).tried >= FUZZ_EXAMPLES


@pytest.mark.parametrize("endpoint", ENDPOINTS)
def test_hostile_inputs_after_a_malformed_one_are_answered(fuzzer, endpoint):
    """A malformed message and then each hostile one (oversized numbers, also as a
    certainty; non-finite numbers; surrogate and overlong names): the node answers both
    and lives on.  The logging of the first once made the second kill the node."""
    fuzzer.outcomes.pop(endpoint, None)
    fuzz_after_malformed(fuzzer, endpoint, first_id=50_000 + 1_000 * ENDPOINTS.index(endpoint))
    assert check_outcome(fuzzer, endpoint).tried >= 10


# Before the wire tests: their in-process graph answers on this fixture's graph's topics (same domain), and a
# message no JSON decoder can read (nested too deep) reaching the fixture's probe breaks its next spin.
def lapse(fuzzer, domain: str, readiness) -> None:
    """Stop spinning ``domain``'s consultant until the WM Manager finds its liveliness lapsed (in one process the
    alive topic's liveliness shows only through writes), then spin it again; ``readiness``: wm_manager/ready."""
    consultant = next(n for n in fuzzer.g.nodes if n.get_name() == f"consultant_{domain}")
    published = len(readiness)
    fuzzer.g.executor.remove_node(consultant)
    try:  # the status shows it only for a moment: the lapse heals at the next write of any node here
        fuzzer.g.spin_until(lambda: any(ready["domains"][domain]["reachable"] is False
                                        for ready in readiness[published:]), 10.0,
                            what=f"the WM Manager to find consultant '{domain}' unreachable")
    finally:
        fuzzer.g.executor.add_node(consultant)


def test_a_liveliness_lapse_that_heals_is_not_a_change_but_a_real_change_still_is(fuzzer):
    """Under load an in-process consultant's liveliness can lapse (its alive writes wait on the executor) and
    heal: the WM Manager's status flips to unreachable and back, and it configures the consultant again.  A
    rejected input sent meanwhile changed nothing; one beside a real change (WM written meanwhile) still did."""
    endpoint, domain = CONSULTANT.format(domain="faces"), fuzzer.domains[0]
    readiness = fuzzer.g.listen("/" + contract.READY.name, replace(contract.READY_QOS, depth=100))
    fuzzer.g.spin_until(lambda: readiness, what="the latched wm_manager/ready")
    rejected = Input('{"op": "info", "zz": ', True, "malformed")
    fuzzer.outcomes.pop(endpoint, None)
    fuzzer.state_before()
    lapse(fuzzer, domain, readiness)
    fuzzer.check(endpoint, rejected)
    assert fuzzer.outcomes[endpoint].rejected == 1 and not fuzzer.outcomes[endpoint].failures(), fuzzer.report()
    fuzzer.state_before()
    lapse(fuzzer, domain, readiness)
    spec = fuzzer.scenario.domains[domain]
    fuzzer.g.call(DEBUG.format(domain=domain), {**fuzzer.seed_wm, "entity": list(spec.entities)[1]})
    fuzzer.check(endpoint, rejected)
    assert fuzzer.outcomes[endpoint].changed_by_rejected == ['malformed: {"op": "info", "zz":  (changed: faces.wm)']


def real_request_targets(scenario) -> tuple[str, str]:
    """An entity and a property of the scenario's first domain, for the real requests after the fuzz."""
    spec = next(iter(scenario.domains.values()))
    return next(iter(spec.entities)), spec.preference[0]


def check_wire(wire: WireFuzz, domains: list[str]) -> None:
    assert sorted(wire.tallies) == sorted(e.name for e in endpoints(domains))  # every endpoint of the contract
    assert not wire.failures(), "\n" + wire.report()
    assert all(t.refused + t.taken == t.sent for t in wire.tallies.values()), "\n" + wire.report()


@pytest.mark.slow
def test_every_endpoint_refuses_what_no_schema_can_save_and_every_node_answers_after(table1_path, tmp_path):
    """Issue 38.1 and its generalisation, in one process: every envelope to every endpoint is refused (never
    as an internal error), no callback raises, and every node answers a real request after."""
    scenario = load_scenario(table1_path)
    graph = start_graph(table1_path, tmp_path)  # its own: the fuzzer fixture's probe listens on answer topics
    try:
        wire = WireFuzz(graph, list(scenario.domains))
        wire.run()
        check_wire(wire, list(scenario.domains))
        assert wire.real_requests(*real_request_targets(scenario)) == []
    finally:
        graph.close()


@pytest.mark.slow
def test_no_node_process_exits_on_what_no_schema_can_save(table1_path, tmp_path):
    """The same inputs to a graph of node processes (issue 38.1 killed two of them): every process still runs
    and answers a real request after."""
    scenario = load_scenario(table1_path)
    with LiveGraph(table1_path, processes=True, log_dir=tmp_path / "logs", state_dir=tmp_path / "state") as live:
        live.set_clock(WIRE_TIME)
        wire = WireFuzz(live.session, list(scenario.domains))
        wire.run()
        failed = wire.real_requests(*real_request_targets(scenario))
        dead = [f"{spec.name} exited {code}: {live.graph.tail(spec.name, 3)}" for spec, code in live.graph.dead()]
        assert dead == [] and failed == [], "\n".join(dead + failed)
        check_wire(wire, list(scenario.domains))
