"""Fuzz every topic and service of the running graph (in-process, sim time, fixed seed).

See ``fuzzgraph`` for the inputs and the checks.  The quick suite sends every hostile
input right after a malformed one on every endpoint; the catalogue (every hostile
mutation, field by field) and the generated inputs (``FUZZ_EXAMPLES`` per endpoint) are
marked slow, and ``scripts/fuzz.py`` runs the same fuzzer longer.
"""

from __future__ import annotations

import pytest

from fuzzgraph import ENDPOINTS, NOT_JSON, REPLY_TOPIC, Fuzzer, Outcome, fuzz_after_malformed, fuzz_catalogue, \
    fuzz_generated, start_graph, templates

from fsreg_ros import contract
from fsreg_ros.core.scenario import load_scenario

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
