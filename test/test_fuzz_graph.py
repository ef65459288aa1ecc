"""Fuzz every topic and service of the running graph (in-process, sim time, fixed seed).

See ``fuzzgraph`` for the inputs and the checks.  The example count per endpoint is
bounded for CI (``FUZZ_EXAMPLES``); ``scripts/fuzz.py`` runs the same fuzzer longer.
"""

from __future__ import annotations

import itertools

import pytest
from hypothesis import HealthCheck, given, settings

from fuzzgraph import CONSULTANT, HUMAN, LTM_ASSERT, MANAGE, REG_REQUEST, SEMANTICS, STATUS, SYNC, Fuzzer, inputs
from fuzzgraph import NOT_JSON, catalogue
from fuzzgraph import start_graph, templates

from fsreg_ros.core.scenario import load_scenario

pytestmark = pytest.mark.graph
FUZZ_EXAMPLES = 20
DOMAIN = "faces"  # Table 1's one domain
ENDPOINTS = [CONSULTANT.format(domain=DOMAIN), MANAGE.format(domain=DOMAIN), SYNC, STATUS,
             HUMAN, SEMANTICS, REG_REQUEST, LTM_ASSERT]


def fuzz_endpoint(fuzzer: Fuzzer, endpoint: str, examples: int, first_id: int = 10_000) -> None:
    """Send every catalogued hostile input, then ``examples`` generated ones (fixed seed), to ``endpoint``."""
    ids = itertools.count(first_id)
    for template in templates(fuzzer.scenario)[endpoint]:
        for given_input in catalogue(template, ids):
            fuzzer.check(endpoint, given_input)
    strategy = inputs(templates(fuzzer.scenario)[endpoint], ids)

    @settings(max_examples=examples, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def fuzz(given_input):
        fuzzer.check(endpoint, given_input)

    fuzz()


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
