"""The replays' shortcut: a game a grid point forgets nothing in takes the no-forgetting cells, and nothing changes.

:func:`fsreg_ros.core.forgetting.keeps.keeps_everything` is each rule's promise; the
replay (:func:`fsreg_ros.research.reuse_replay.cells_of`) uses it to skip games.  On seeded
random games (four referents, six repetitions, words drawn from a small vocabulary, a
matcher who joins late) and grids that straddle every bound, the cells with the shortcut equal
those of playing every game under every grid point, in the group's WM and in each player's,
and the shortcut is taken for some grid points and games and not for others.
"""

import random

import numpy as np
import pytest

from fsreg_ros.core.forgetting.keeps import Span, keeps_everything, within
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.research.reference_games import Row, games_from_rows
from fsreg_ros.research.reuse_events import build_events
from fsreg_ros.research.reuse_models import policy_of, wm_models
from fsreg_ros.research.reuse_replay import cells_of, replay, replay_players, spans

VOCABULARY = "red blue tall man ghost bird bowl arms ears kneeling bunny sitting long raised".split()


def random_games(seed: int = 7, games: int = 5):
    rng = random.Random(seed)
    rows = []
    for g in range(games):
        time, trial = 0.0, 0
        for rep in range(6):
            for referent in rng.sample("ABCD", 4):
                trial += 1
                time += rng.uniform(2, 40)
                words = " ".join(rng.sample(VOCABULARY, rng.randint(1, 5)))
                rows.append(Row(f"g{g}", trial, referent, "dir", "describer", time, words, rep + 1))
                if trial > 3 and rng.random() < 0.4:
                    time += rng.uniform(1, 5)
                    rows.append(Row(f"g{g}", trial, referent, f"m{g % 2}", "matcher", time,
                                    rng.choice(VOCABULARY) + "?", rep + 1))
    return games_from_rows(rows)


GRIDS = {"decay_period": (5.0, 300.0, 2000.0), "capacity": (2, 9, 14, 30), "global_capacity": (8, 40, 56, 100),
         "shared_capacity": (8, 56, 100), "activation_decay": (0.1, 0.5, 0.9),
         "activation_threshold": (-10.0, -6.0, -1.0), "episode_window": (1, 5, 6, 8)}


def played(events, settings, play, games=None) -> np.ndarray:
    rows = []
    for setting in settings:
        out = np.zeros(events.candidates, dtype=np.uint8)
        policy = None if setting is None else policy_of(setting)
        for g, stream in enumerate(events.streams):
            if games is None or games[g]:
                play(stream, policy, out)
        rows.append(out)
    return np.stack(rows)


@pytest.fixture(scope="module")
def events():
    return build_events(random_games())


def test_the_shortcut_changes_no_cell_in_the_group_or_the_players_wm(events):
    settings = [None] + [s for model in wm_models(GRIDS) for s in model.settings]
    assert np.array_equal(cells_of(events, settings), played(events, settings, replay))
    late = np.ones(len(events.games), bool)
    assert np.array_equal(cells_of(events, settings[1:], players=True, games=late),
                          played(events, settings[1:], replay_players, late))


def test_the_shortcut_is_taken_for_some_grid_points_and_games_and_not_for_others(events):
    game_spans = spans(events)
    for model in wm_models(GRIDS):
        kept = [keeps_everything(policy_of(s), span) for s in model.settings for span in game_spans]
        assert any(kept) and not all(kept), model.name


def test_a_games_span_is_what_an_unmanaged_wm_holds(events):
    stream = events.streams[0]
    said, words_said = {}, {}
    for kind, _, referent, words, _, _, _ in stream:
        if kind == "say":
            said.setdefault(referent, set()).update(words)
            words_said[referent] = words_said.get(referent, 0) + len(words)
    span = spans(events)[0]
    assert span.seconds == max(step[1] for step in stream)
    assert (span.entries, span.per_entity, span.episodes, span.words) == \
        (sum(map(len, said.values())), max(map(len, said.values())), 6, max(words_said.values()))


@pytest.mark.parametrize("policy, kept, not_kept", [
    (dict(decay_period=10.0), Span(9.99, 1, 1, 1), Span(10.0, 1, 1, 1)),
    (dict(capacity=3), Span(1e9, 99, 3, 99), Span(0.0, 4, 4, 1)),
    (dict(global_capacity=5), Span(1e9, 5, 5, 99), Span(0.0, 6, 1, 1)),
    (dict(shared_capacity=5), Span(1e9, 5, 5, 99), Span(0.0, 6, 1, 1)),
    (dict(episode_window=2), Span(1e9, 99, 99, 2), Span(0.0, 1, 1, 3)),
    # one encoding stays exp(-tau / d) = exp(2) = 7.389 s
    (dict(activation_decay=0.5, activation_threshold=-1.0), Span(7.38, 99, 99, 99), Span(7.39, 1, 1, 1)),
    # on an entity's own clock, ages count from 1: at most episodes + 1 (words + 1) old within the span
    (dict(activation_decay=0.5, activation_threshold=-1.0, activation_clock="episodes"),
     Span(1e9, 99, 99, 6, 99), Span(0.0, 1, 1, 7, 0)),
    (dict(activation_decay=0.5, activation_threshold=-1.0, activation_clock="words"),
     Span(1e9, 99, 99, 99, 6), Span(0.0, 1, 1, 0, 7)),
])
def test_each_rules_promise_at_its_bound(policy, kept, not_kept):
    rule = {"decay_period": "decay", "capacity": "displacement", "global_capacity": "global-capacity",
            "shared_capacity": "shared-capacity", "episode_window": "episodes",
            "activation_decay": "activation"}[next(iter(policy))]
    p = ForgettingPolicy((rule,), **policy)
    assert keeps_everything(p, kept) and not keeps_everything(p, not_kept)


def test_no_promise_from_none_similarity_or_a_rule_that_forgets_in_the_span():
    span = Span(1.0, 1, 1, 1)
    assert not keeps_everything(ForgettingPolicy(()), span)  # none keeps nothing
    assert not keeps_everything(ForgettingPolicy(("similarity",)), span)
    both = ForgettingPolicy(("decay", "displacement"), decay_period=100.0, capacity=1)
    assert keeps_everything(both, span) and not keeps_everything(both, Span(1.0, 2, 2, 1))


def test_a_combination_whose_rule_keeps_everything_forgets_what_its_other_rule_does(events):
    game_spans = spans(events)
    both = ForgettingPolicy(("decay", "displacement"), decay_period=5.0, capacity=30)
    assert {rest.settings() == {"policy": "decay", "decay_period": 5.0} for rest in within(both, game_spans)} == {True}
    neither = ForgettingPolicy(("decay", "displacement"), decay_period=1e6, capacity=30)
    assert within(neither, game_spans) == [None] * len(game_spans)
    assert within(ForgettingPolicy(("decay", "displacement"), decay_period=5.0, capacity=1), game_spans) == \
        [ForgettingPolicy(("decay", "displacement"), decay_period=5.0, capacity=1)] * len(game_spans)
