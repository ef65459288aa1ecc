"""Random Guess-Who games like the paper's case study, played by the core simulator.

A game (:func:`make_game`, deterministic per seed) is a board of 16 distinct faces
over five attributes (hair colour, hair length, gender, clothing, glasses), a
human speaker modelled as the Incremental Algorithm (DIST-PIA, read-only) with its
own attribute preference order drawn per game, and alternating turns: the human
describes a random face (the robot resolves it), then the robot describes a random
face.  Seconds between turns are drawn per game.  :func:`play` runs the game as a
:class:`~fsreg_ros.core.scenario.Scenario` through
:class:`~fsreg_ros.core.simulation.Simulation`, so the robot runs the real RR and
REG (SD-PIA, or DIST-PIA under policy ``none``) under any forgetting policy.
Optionally the human speaks from a WM of its own (:class:`HumanSpeaker`).
"""

from __future__ import annotations

import hashlib
import json
import random
from dataclasses import dataclass, replace
from itertools import product
from typing import Any, Mapping, Optional, Sequence

from ..core.alignment import AlignmentSummary, summarise
from ..core.consultant import Consultant, LocalPort, run_sync
from ..core.describe import describe
from ..core.generation import algorithm_for
from ..core.wm_manager import WMManager
from ..core.lexicon import Lexicon
from ..core.resolution import resolve
from ..core.scenario import DomainSpec, Scenario, Turn
from ..core.simulation import Options, Simulation

DOMAIN = "faces"
#: The board's attributes and their values (property names as in the shipped lexicon).
ATTRIBUTES = {
    "hair-colour": ("light-hair", "dark-hair"),
    "hair-length": ("short-hair", "long-hair"),
    "gender": ("male", "female"),
    "clothing": ("lab-coat", "hoodie", "t-shirt"),
    "glasses": ("glasses", "no-glasses"),
}
BOARD_SIZE = 16
#: The robot's preference order (the same in every game).
ROBOT_ORDER = tuple(value for values in ATTRIBUTES.values() for value in values)
PROPERTY_ATTRIBUTE = {value: attribute for attribute, values in ATTRIBUTES.items() for value in values}


@dataclass(frozen=True)
class Game:
    """One generated game: the board, the human's order, the turns (speaker, time, target)."""

    seed: int
    board: dict
    human_order: tuple
    gap: float
    turns: tuple  # of (speaker, time, target, description or None)

    def kb_hash(self) -> str:
        """Return the SHA-256 of the board (the knowledge base) as canonical JSON."""
        text = json.dumps({"board": self.board, "robot_order": ROBOT_ORDER}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()


def make_game(seed: int, turns: int, gap_range: tuple = (2.0, 12.0)) -> Game:
    """Generate the game of ``seed`` with ``turns`` dialogue turns (human first, alternating)."""
    rng = random.Random(seed)
    faces = rng.sample(list(product(*ATTRIBUTES.values())), BOARD_SIZE)
    board = {f"face{i + 1}": list(face) for i, face in enumerate(faces)}
    human_attributes = list(ATTRIBUTES)
    rng.shuffle(human_attributes)
    human_order = tuple(v for a in human_attributes for v in ATTRIBUTES[a])
    gap = round(rng.uniform(*gap_range), 1)
    human = Consultant("human", {f: {p: 1.0 for p in props} for f, props in board.items()}, human_order)
    names = list(board)
    time = 0.0
    played = []
    for index in range(turns):
        time = round(time + gap * rng.uniform(0.5, 1.5), 3)
        target = rng.choice(names)
        if index % 2 == 0:
            said = describe(target, human, "dist-pia", attributes=PROPERTY_ATTRIBUTE).description
            played.append(("human", time, target, tuple(said)))
        else:
            played.append(("robot", time, target, None))
    return Game(seed, board, human_order, gap, tuple(played))


def scenario_of(game: Game) -> Scenario:
    """Return the game as a scenario (one domain ``faces``, the robot's preference order)."""
    entities = {face: {p: 1.0 for p in props} for face, props in game.board.items()}
    # The board's attributes let attribute-similarity interference (rule ``similarity``) act.
    domain = DomainSpec(DOMAIN, ROBOT_ORDER, entities, attributes=dict(PROPERTY_ATTRIBUTE))
    dialogue = tuple(
        Turn(i, time, speaker, target=target, description=said, domain=DOMAIN if speaker == "human" else None)
        for i, (speaker, time, target, said) in enumerate(game.turns)
    )
    return Scenario(f"guess-who-{game.seed}", f"<game {game.seed}>", {DOMAIN: domain}, None, dialogue)


@dataclass
class Played:
    """A played game: the docs/semantics.md section 6 result, the event trace and its alignment summary."""

    result: dict
    trace: list
    alignment: AlignmentSummary


class HumanSpeaker:
    """The human with a working memory of its own (paper Algorithm 4 on the human's side).

    It describes with SD-PIA over its own WM (DIST-PIA under ``none``) in its own
    preference order, and resolves the robot's descriptions (rules 1 and 2), so
    what the robot says can shape what the human says next.
    """

    def __init__(self, game: Game, memory: Mapping[str, Any]) -> None:
        scenario = scenario_of(game)
        self.policy = scenario.policy_for(DOMAIN, dict(memory))
        entities = {face: {p: 1.0 for p in props} for face, props in game.board.items()}
        self.consultant = Consultant(DOMAIN, entities, game.human_order)
        self.manager = WMManager()
        self.manager.manage(self.consultant.wm, self.policy, now=0.0)

    def say(self, target: str, time: float, turn: int) -> list[str]:
        """Return the human's description of ``target`` at ``time`` (encoding it in the human's WM)."""
        self.manager.advance(time)
        algorithm = algorithm_for(self.policy.retains, None)
        return describe(target, self.consultant, algorithm, attributes=PROPERTY_ATTRIBUTE, writes=True, time=time,
                        turn=turn).description

    def hear(self, description: Sequence[str], time: float, turn: int) -> None:
        """Resolve the robot's description in the human's WM."""
        if description:
            self.manager.advance(time)
            run_sync(resolve(description, {DOMAIN: LocalPort(self.consultant)}, domain=DOMAIN, time=time, turn=turn))


def play(
    game: Game,
    memory: Mapping[str, Any],
    lexicon: Optional[Lexicon] = None,
    human_memory: Optional[Mapping[str, Any]] = None,
) -> Played:
    """Play ``game`` with the robot's memory settings (``{"policy": ..., ...}``).

    With ``human_memory`` the human speaks from a WM of its own (:class:`HumanSpeaker`),
    turn by turn, instead of the game's precomputed no-WM descriptions.
    """
    scenario = scenario_of(game)
    simulation = Simulation(scenario, Options(memory=dict(memory)), lexicon, trace=True)
    if human_memory is None:
        result = simulation.run()
    else:
        human = HumanSpeaker(game, human_memory)
        turns = []
        for turn in scenario.dialogue:
            if turn.speaker == "human":
                turn = replace(turn, description=tuple(human.say(turn.target, turn.time, turn.index)))
            record = simulation.play(turn)
            if turn.speaker == "robot":
                human.hear(record["description"] or (), turn.time, turn.index)
            turns.append(record)
        result = {"scenario": scenario.name, "memory": simulation.manager.effective(), "turns": turns}
    trace = simulation.trace()
    return Played(result, trace, summarise(result, trace))


def shortest_lengths(game: Game) -> dict:
    """Return each face's shortest distinguishing description length (Full Brevity, no WM)."""
    kb = Consultant(DOMAIN, {f: {p: 1.0 for p in props} for f, props in game.board.items()}, ROBOT_ORDER)
    return {face: len(describe(face, kb, "full-brevity").description) for face in game.board}
