"""Random Guess-Who games like the paper's case study, played by the core simulator.

A game (:func:`make_game`, deterministic per seed) is a board of distinct entities
per domain -- faces over five attributes (hair colour, hair length, gender,
clothing, glasses), and in the ``faces+objects`` world also objects (kind, colour,
size, place) -- a human speaker modelled as the Incremental Algorithm (DIST-PIA,
read-only) with its own attribute preference order per domain drawn per game, and
alternating turns: the human describes a random entity (the robot resolves it),
then the robot describes a random entity.  Seconds between turns are drawn per game.

A game may be *dynamic*: facts change mid-game as perception would report them (a
person takes off their glasses or changes clothes, an object is moved).  Each change
is an LTM update through :meth:`~fsreg_ros.core.consultant.consultant.Consultant.assert_facts`,
the path the consultant node's ``ltm/assert`` topic takes; the human describes the
world as it is at each turn.

:func:`play` runs the game as a :class:`~fsreg_ros.core.scenario.Scenario` through
:class:`~fsreg_ros.core.simulation.simulator.Simulation`, so the robot runs the real RR and
REG (SD-PIA, or DIST-PIA under policy ``none``) under any forgetting policy, with
the robot's WM told of LTM changes or not (``retract``) and REG verifying WM against
LTM (the package's SD-PIA) or taking the target's WM as what it believes
(``wm_belief``, :class:`BeliefPort`).  Optionally the human speaks from a WM of its
own (:class:`HumanSpeaker`).
"""

from __future__ import annotations

import hashlib
import json
import random
from dataclasses import dataclass, field, replace
from itertools import product
from typing import Any, Mapping, Optional, Sequence

from ..core.algorithms.alignment import AlignmentSummary, summarise
from ..core.consultant.consultant import Consultant
from ..core.simulation.describe import describe
from ..core.algorithms.generation import algorithm_for
from ..core.lexicon import Lexicon
from ..core.consultant.local_port import LocalPort
from ..core.algorithms.port import Narrowed, Reference, Step, View, run_sync
from ..core.algorithms.resolution import NO_MATCH, resolve
from ..core.scenario import DomainSpec, Scenario, Turn
from ..core.simulation.simulator import Options, Simulation, human_record
from ..core.forgetting.wm_manager import WMManager
from .listener import Listener, ListenerOptions, speak
from .world import (  # noqa: F401 (ATTRIBUTES, OBJECTS, ROBOT_ORDER: the world's names stay importable from here)
    ATTRIBUTES, DOMAIN, DOMAIN_ATTRIBUTES, EXCLUSIVE, MUTABLE, OBJECTS, PROPERTY_ATTRIBUTE, ROBOT_ORDER, ROBOT_ORDERS,
    WORLDS,
)

BOARD_SIZE = 16
#: Board sizes a world allows (at least two entities; at most every distinct entity of the smallest domain).
MAX_BOARD_SIZE = 48


@dataclass(frozen=True)
class Change:
    """One fact change as perception reports it: at ``time`` ``entity`` has ``new`` instead of ``old``."""

    time: float
    domain: str
    entity: str
    old: str
    new: str

    def facts(self) -> dict[str, float]:
        """Return the LTM update (``ltm/assert`` properties): the old value retracted, the new one asserted."""
        return {self.old: 0.0, self.new: 1.0}


@dataclass(frozen=True)
class Game:
    """One generated game: the boards, the human's orders, the turns, the fact changes."""

    seed: int
    world: str
    boards: dict  # domain -> {entity: [properties]} at the start
    human_orders: dict  # domain -> the human's preference order
    gap: float
    turns: tuple  # of (speaker, time, target, domain, description or None)
    changes: tuple = ()  # of Change, in time order
    shortest: tuple = ()  # per robot turn: the shortest distinguishing description's length then

    @property
    def board(self) -> dict:
        """Return the board of faces; every world has one."""
        return self.boards[DOMAIN]

    @property
    def human_order(self) -> tuple:
        """Return the human's order over faces."""
        return self.human_orders[DOMAIN]

    def kb_hash(self) -> str:
        """Return the SHA-256 of the knowledge base (boards, robot orders, fact changes) as canonical JSON."""
        text = json.dumps(
            {"boards": self.boards, "robot_orders": {d: ROBOT_ORDERS[d] for d in self.boards},
             "changes": [[c.time, c.domain, c.entity, c.old, c.new] for c in self.changes]},
            sort_keys=True,
        )
        return hashlib.sha256(text.encode()).hexdigest()


def _consultant(domain: str, board: Mapping[str, Sequence[str]], order: Sequence[str]) -> Consultant:
    return Consultant(domain, {e: {p: 1.0 for p in props} for e, props in board.items()}, order,
                      exclusive=EXCLUSIVE[domain])


def _draw_change(rng: random.Random, time: float, world: Mapping[str, dict]) -> Optional[Change]:
    """Draw one fact change that keeps every entity of its domain distinct (None if none can)."""
    domain = rng.choice(sorted(world))
    board = world[domain]
    for _ in range(20):
        entity = rng.choice(sorted(board))
        attribute = rng.choice(MUTABLE[domain])
        values = DOMAIN_ATTRIBUTES[domain][attribute]
        (old,) = [p for p in board[entity] if p in values]
        new = rng.choice([v for v in values if v != old])
        after = [new if p == old else p for p in board[entity]]
        if all(sorted(after) != sorted(props) for e, props in board.items() if e != entity):
            board[entity] = after
            return Change(time, domain, entity, old, new)
    return None


def make_game(
    seed: int,
    turns: int,
    gap_range: tuple = (2.0, 12.0),
    board_size: int = BOARD_SIZE,
    world: str = "faces",
    changes: float = 0.0,
) -> Game:
    """Generate the game of ``seed`` with ``turns`` dialogue turns (human first, alternating).

    ``board_size`` entities per domain; ``changes`` fact changes per 100 turns, at
    random times during the game (0: a static game, as in the paper).
    """
    if world not in WORLDS:
        raise ValueError(f"unknown world '{world}' (known: {', '.join(WORLDS)})")
    if not 2 <= board_size <= MAX_BOARD_SIZE:
        raise ValueError(f"board size must be in [2, {MAX_BOARD_SIZE}], got {board_size}")
    rng = random.Random(seed)
    domains = WORLDS[world]
    boards, human_orders = {}, {}
    for domain in domains:
        attrs = DOMAIN_ATTRIBUTES[domain]
        entities = rng.sample(list(product(*attrs.values())), board_size)
        prefix = "face" if domain == DOMAIN else "object"
        boards[domain] = {f"{prefix}{i + 1}": list(e) for i, e in enumerate(entities)}
        order = list(attrs)
        rng.shuffle(order)
        human_orders[domain] = tuple(v for a in order for v in attrs[a])
    gap = round(rng.uniform(*gap_range), 1)
    times, time = [], 0.0
    for _ in range(turns):
        time = round(time + gap * rng.uniform(0.5, 1.5), 3)
        times.append(time)
    targets = [(d, e) for d in domains for e in boards[d]]
    picks = [rng.choice(targets) for _ in range(turns)]
    count = round(changes * turns / 100)
    change_times = sorted(round(rng.uniform(times[0], times[-1]), 3) for _ in range(count))
    # The world as it is at each moment: the human's view and the full-brevity length.
    world_now = {d: {e: list(p) for e, p in boards[d].items()} for d in domains}
    humans = {d: _consultant(d, boards[d], human_orders[d]) for d in domains}
    robots = {d: _consultant(d, boards[d], ROBOT_ORDERS[d]) for d in domains}
    drawn: list[Change] = []
    pending = list(change_times)
    played, shortest = [], []
    for index, (time, (domain, target)) in enumerate(zip(times, picks)):
        while pending and pending[0] <= time:
            change = _draw_change(rng, pending.pop(0), world_now)
            if change is not None:
                drawn.append(change)
                for kb in (humans[change.domain], robots[change.domain]):
                    kb.assert_facts(change.entity, change.facts(), change.time)
        if index % 2 == 0:
            said = describe(target, humans[domain], "dist-pia", attributes=PROPERTY_ATTRIBUTE).description
            played.append(("human", time, target, domain, tuple(said)))
        else:
            played.append(("robot", time, target, domain, None))
            shortest.append(len(describe(target, robots[domain], "full-brevity").description))
    return Game(seed, world, boards, human_orders, gap, tuple(played), tuple(drawn), tuple(shortest))


def scenario_of(game: Game) -> Scenario:
    """Return the game as a scenario (the world's domains, the robot's preference orders)."""
    domains = {}
    for domain, board in game.boards.items():
        entities = {e: {p: 1.0 for p in props} for e, props in board.items()}
        # The attributes let attribute-similarity interference (rule ``similarity``) act.
        attributes = {p: PROPERTY_ATTRIBUTE[p] for p in ROBOT_ORDERS[domain]}
        domains[domain] = DomainSpec(domain, ROBOT_ORDERS[domain], entities, attributes=attributes,
                                     exclusive=EXCLUSIVE[domain])
    dialogue = tuple(
        Turn(i, time, speaker, target=target, description=said, domain=domain if speaker == "human" else None)
        for i, (speaker, time, target, domain, said) in enumerate(game.turns)
    )
    return Scenario(f"guess-who-{game.seed}", f"<game {game.seed}>", domains, None, dialogue)


class BeliefPort(LocalPort):
    """A :class:`LocalPort` through which REG takes the target's WM as what the robot believes of it.

    The package's SD-PIA (docs/semantics.md section 4) skips a WM property that no
    longer holds for the target in LTM, so a stale WM entry is never said.  Through
    this port the robot trusts its WM instead -- the reading under which WM saves LTM
    queries, and the one the follow-up study (Sousa Silva & Williams, 2026) weighs
    against outdated information: a property in Q[target] counts as holding for the
    target, and it narrows the distractors (encoding it for those it holds for, rule 3)
    whatever LTM now says of the target.  Reference resolution (no target) is unchanged.
    """

    async def open(
        self, target: Optional[str] = None, context: Optional[Sequence[str]] = None, first: Optional[Step] = None,
        refer: Optional[Reference] = None,
    ) -> View:
        view = await super().open(target, context, first, refer)
        if target is not None and view.holding is not None:
            view.holding = view.holding | frozenset(view.queue)
        return view

    async def narrow(self, view: View, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> Narrowed:
        candidates = view.handle
        if candidates.target is None or prop not in view.queue:
            return await super().narrow(view, prop, cause, time, turn)
        target = candidates.target
        if self.consultant.certainty(self.consultant.entities[target], prop) >= self.consultant.threshold:
            return await super().narrow(view, prop, cause, time, turn)
        # Believed from WM, no longer true in LTM: narrow the distractors as if no target were checked.
        candidates.target = None
        try:
            self.consultant.narrow(candidates, prop, cause, time, turn)
        finally:
            candidates.target = target
        return Narrowed(True, candidates.size)


@dataclass
class Played:
    """A played game: the docs/semantics.md section 6 result, its alignment and what the robot said wrongly.

    ``wm_sizes`` and ``outdated`` are parallel to ``alignment.turns`` (the robot's
    turns): the properties in the target domain's WM just before the turn, and the
    properties said of the target that no longer held for it.  ``trace`` is the WM
    event trace when asked for (else None).
    """

    result: dict
    alignment: AlignmentSummary
    wm_sizes: list = field(default_factory=list)
    outdated: list = field(default_factory=list)
    trace: Optional[list] = None
    heard: Optional[list] = None  # per robot turn, the listener's :class:`~.listener.Heard` (with a listener)


class HumanSpeaker:
    """The human with a working memory of its own (paper Algorithm 4 on the human's side).

    It describes with SD-PIA over its own WM (DIST-PIA under ``none``) in its own
    preference orders, and resolves the robot's descriptions (rules 1 and 2), so
    what the robot says can shape what the human says next.  It sees fact changes too.
    """

    def __init__(self, game: Game, memory: Mapping[str, Any]) -> None:
        scenario = scenario_of(game)
        self.manager = WMManager()
        self.consultants, self.algorithms = {}, {}
        for domain, board in game.boards.items():
            policy = scenario.policy_for(domain, dict(memory))
            self.consultants[domain] = _consultant(domain, board, game.human_orders[domain])
            self.manager.manage(self.consultants[domain].wm, policy, now=0.0)
            self.algorithms[domain] = algorithm_for(policy.retains, None)

    def say(self, target: str, domain: str, time: float, turn: int) -> list[str]:
        """Return the human's description of ``target`` at ``time`` (encoding it in the human's WM)."""
        return speak(self, target, domain, time, turn)

    def hear(self, description: Sequence[str], domain: str, time: float, turn: int) -> None:
        """Resolve the robot's description in the human's WM."""
        if description:
            self.manager.advance(time)
            ports = {domain: LocalPort(self.consultants[domain])}
            run_sync(resolve(description, ports, domain=domain, time=time, turn=turn))

    def see(self, change: Change) -> None:
        """Take in a fact change (the human sees it as perception reports it to the robot)."""
        self.manager.advance(change.time)
        self.consultants[change.domain].assert_facts(change.entity, change.facts(), change.time)


def play(
    game: Game,
    memory: Mapping[str, Any],
    lexicon: Optional[Lexicon] = None,
    human_memory: Optional[Mapping[str, Any]] = None,
    retract: bool = True,
    wm_belief: bool = False,
    trace: bool = False,
    listener: Optional[ListenerOptions] = None,
    wm_order: str = "lru-first",
) -> Played:
    """Play ``game`` with the robot's memory settings (``{"policy": ..., ...}``) and REG's ``wm_order``.

    With ``human_memory`` the human speaks from a WM of its own (:class:`HumanSpeaker`),
    turn by turn, instead of the game's precomputed no-WM descriptions.  ``retract``
    False keeps the robot's WM uninformed of fact changes; ``wm_belief`` makes REG
    take the target's WM as true (:class:`BeliefPort`).  Fact changes reach the
    robot's LTM through ``Consultant.assert_facts`` before the first turn at or after
    their time (decay ticks due by then first).

    With ``listener`` (:mod:`.listener`) a listener of its own knowledge resolves each
    robot description, the robot repairing a failed reference (``Played.heard``); with
    its ``partner`` ``robot``, that listener is a second fsreg agent that also plays
    the human's turns, from its own WM (``partner_memory``, else ``memory``).
    """
    scenario = scenario_of(game)
    simulation = Simulation(scenario, Options(memory=dict(memory), wm_order=wm_order), lexicon, trace=trace)
    for consultant in simulation.consultants.values():
        consultant.retract_on_update = retract
    if wm_belief:
        simulation.ports = {d: BeliefPort(c) for d, c in simulation.consultants.items()}
    human = HumanSpeaker(game, human_memory) if human_memory is not None else None
    hearer = None
    if listener is not None:
        partner = listener.partner == "robot"
        own = listener.partner_memory if listener.partner_memory is not None else memory
        hearer = Listener(game, listener, scenario, own if partner else None)
        if partner:
            human = hearer  # the second fsreg agent plays the human's role: it speaks, hears and sees
    changes = list(game.changes)
    records, wm_sizes, outdated, heard = [], [], [], []
    for turn in scenario.dialogue:
        while changes and changes[0].time <= turn.time:
            change = changes.pop(0)
            simulation.manager.advance(change.time)  # ticks due by then happen first
            simulation.consultants[change.domain].assert_facts(change.entity, change.facts(), change.time)
            if human is not None:
                human.see(change)
            if hearer is not None and hearer is not human:
                hearer.see(change)
        if turn.speaker == "human" and human is not None:
            turn = replace(turn, description=tuple(human.say(turn.target, turn.domain, turn.time, turn.index)))
        if turn.speaker == "robot":
            domain = scenario.domain_of(turn.target)  # type: ignore[arg-type]
            simulation.manager.advance(turn.time)
            wm_sizes.append(len(simulation.consultants[domain].wm))
        if turn.speaker == "human" and not turn.description:  # a partner that knows nothing to say of it
            simulation.manager.advance(turn.time)
            record = human_record(turn, {"description": [], "status": NO_MATCH, "resolved": None, "candidates": [],
                                         "domain": turn.domain}, None)
        else:
            record = simulation.play(turn)
        if turn.speaker == "robot":
            consultant = simulation.consultants[record["domain"]]
            holding = set(consultant.properties_of(turn.target))  # type: ignore[arg-type]
            outdated.append([p for p in record["description"] or () if p not in holding])
            if hearer is not None:
                heard.append(hearer.hear(record["description"] or (), turn.target, record["domain"], consultant,
                                         turn.time, turn.index))
            if human is not None and human is not hearer:
                human.hear(record["description"] or (), record["domain"], turn.time, turn.index)
        records.append(record)
    result = {"scenario": scenario.name, "memory": simulation.manager.effective(), "turns": records}
    return Played(result, summarise(result), wm_sizes, outdated, simulation.trace() if trace else None,
                  heard if hearer is not None else None)
