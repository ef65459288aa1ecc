"""Fuzz every topic and service of the running graph (in-process, sim time, fixed seed).

See ``fuzzgraph`` for the inputs and the checks.  The example count per endpoint is
bounded for CI (``FUZZ_EXAMPLES``); ``scripts/fuzz.py`` runs the same fuzzer longer.
"""

from __future__ import annotations

import pytest

from fuzzgraph import ENDPOINTS, NOT_JSON, Fuzzer, fuzz_endpoint, start_graph, templates

from fsreg_ros.core.scenario import load_scenario

pytestmark = pytest.mark.graph
FUZZ_EXAMPLES = 20


@pytest.fixture(scope="module")
def fuzzer(table1_path, tmp_path_factory):
    scenario = load_scenario(table1_path)
    fuzzer = Fuzzer(lambda: start_graph(table1_path, tmp_path_factory.mktemp("fuzz")), scenario)
    yield fuzzer
    fuzzer.close()


def test_the_fuzzed_endpoints_are_every_endpoint(table1_path):
    assert sorted(templates(load_scenario(table1_path))) == sorted(ENDPOINTS)


@pytest.mark.parametrize("endpoint", ENDPOINTS)
def test_every_input_is_answered_and_rejections_change_nothing(fuzzer, endpoint):
    fuzz_endpoint(fuzzer, endpoint, FUZZ_EXAMPLES, first_id=10_000 + 1_000 * ENDPOINTS.index(endpoint))
    outcome = fuzzer.outcomes[endpoint]
    assert outcome.tried >= FUZZ_EXAMPLES and outcome.rejected >= len(NOT_JSON)
    assert not outcome.failures(), "\n" + fuzzer.report([endpoint])
