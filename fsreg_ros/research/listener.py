"""A listener that can fail: who resolves the robot's descriptions in ``fsreg-sweep``, and the repair.

This module owns the listener agent of a generated game (:mod:`.games`): its own
knowledge of the boards, how it resolves each robot description (with the core's
reference resolution, :func:`fsreg_ros.core.algorithms.resolution.resolve`, over a consultant
of its own), what it answers when a reference fails, and how the robot repairs it.
It also owns the robot-robot mode, where a second fsreg agent (:class:`Listener`
with a WM and a forgetting policy of its own) plays the human's role: it describes
the human's referents with SD-PIA over its own WM and resolves the robot's.

**Knowledge** (:func:`perceive`, drawn once per game from the game's seed, so every
setting of a sweep faces the same listener): per entity and attribute, the fact is
*missing* with probability ``missing`` (the listener holds no value of the
attribute for the entity: it neither says one nor affirms one), else *misperceived*
with probability ``noise`` (the listener holds another value of the attribute, drawn
uniformly).  Every fact costs the same three draws whatever the rates, so two
listeners of one game differ only where their rates do.  A later fact change is
perceived as it is (the new value).  ``order`` is the listener's preference order
(``human``: the game's human order, ``robot``: the robot's, ``reversed``: the
robot's attributes in reverse); it decides what the listener *says* (robot-robot
mode) -- resolution checks every property whatever the order.

**Resolution and repair** (:meth:`Listener.hear`, docs/research.md section 4): the
listener resolves the description with the core's RR.  It succeeds if the
resolution is the robot's target.  Otherwise it answers, and the robot repairs
from its LTM (what holds for the target now), as a new attempt of the same turn:

* *ambiguous* -- the listener names the candidates left; *wrong referent* -- it
  names the one it took.  The robot adds the first property in its preference order
  (the Incremental Algorithm's) that holds for the target, is not in the
  description, and rules out at least one of the named candidates other than the
  target (in the robot's LTM).
* *none fits* -- the listener names the property it cannot match: the first of the
  description (utterance order) without which some candidate fits (else the one at
  which its candidates ran out), and the candidates the rest leaves.  The robot drops
  that property and adds, as above, the first property that rules out one of those
  candidates other than the target (none if only the target was left).  A property
  the listener said fits no one is not said again in the same turn.

A repair the robot cannot make (no such property, nothing dropped) ends the turn
unresolved, as does reaching ``max_repairs`` repairs.  Each added property is
encoded for the target in the robot's WM (rule 1, cause ``speaker``), as the robot
said it.  :class:`Heard` records the attempts.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence

from ..core.consultant.consultant import Consultant
from ..core.consultant.local_port import LocalPort
from ..core.algorithms.port import run_sync
from ..core.simulation.describe import describe
from ..core.algorithms.generation import algorithm_for
from ..core.algorithms.resolution import AMBIGUOUS, NO_MATCH, RESOLVED, resolve
from ..core.scenario import Scenario
from ..core.forgetting.wm_manager import WMManager
from .world import DOMAIN_ATTRIBUTES, PROPERTY_ATTRIBUTE, ROBOT_ORDERS

#: The listener's preference orders (what it says in robot-robot mode).
ORDERS = ("human", "robot", "reversed")
#: The players of the human's role: the game's Incremental-Algorithm human, or a second fsreg agent.
PARTNERS = ("human", "robot")
MAX_REPAIRS = 3
#: Outcomes of one attempt (the listener's answer when it is not the target).
WRONG = "wrong-referent"


@dataclass(frozen=True)
class ListenerOptions:
    """Who listens to the robot and how well (written to manifest.json)."""

    missing: float = 0.0  # probability that a fact is unknown to the listener
    noise: float = 0.0  # probability that a known fact is misperceived (another value of its attribute)
    order: Optional[str] = None  # the listener's preference order (None: human's for the human, robot's for a robot)
    max_repairs: int = MAX_REPAIRS
    partner: str = "human"  # who plays the human's role: the game's IA human, or a second fsreg agent ("robot")
    partner_memory: Optional[dict] = None  # a robot partner's WM settings (None: the same as the robot's each run)

    def order_name(self) -> str:
        """Return the listener's order: the one given, else the role player's own."""
        return self.order or ("robot" if self.partner == "robot" else "human")


@dataclass
class Heard:
    """One robot turn as the listener heard it: each attempt's description and outcome, and the result.

    ``outcomes`` parallels ``attempts`` (``resolved``, ``wrong-referent``, ``ambiguous``
    or ``no-match``); ``repairs`` the robot's move before each attempt after the first
    (``{"added": prop or None, "dropped": prop or None}``).
    """

    target: str
    attempts: list = field(default_factory=list)
    outcomes: list = field(default_factory=list)
    repairs: list = field(default_factory=list)

    @property
    def success(self) -> bool:
        """Whether the listener identified the target in the end."""
        return bool(self.outcomes) and self.outcomes[-1] == RESOLVED

    @property
    def turns(self) -> Optional[int]:
        """Attempts until the target was identified (1: at once), or None if it never was."""
        return len(self.attempts) if self.success else None

    @property
    def final_length(self) -> int:
        """Properties in the last description the listener heard."""
        return len(self.attempts[-1]) if self.attempts else 0

    @property
    def said(self) -> int:
        """Properties the robot said over all attempts (each repair adds at most one)."""
        return len(self.attempts[0]) + sum(r["added"] is not None for r in self.repairs) if self.attempts else 0


def listener_order(name: str, domain: str, human_order: Sequence[str]) -> tuple:
    """Return the listener's preference order over ``domain``'s properties for ``name`` (:data:`ORDERS`)."""
    if name == "human":
        return tuple(human_order)
    if name == "robot":
        return ROBOT_ORDERS[domain]
    if name == "reversed":
        return tuple(v for a in reversed(DOMAIN_ATTRIBUTES[domain]) for v in DOMAIN_ATTRIBUTES[domain][a])
    raise ValueError(f"unknown listener order '{name}' (known: {', '.join(ORDERS)})")


def perceive(boards: Mapping[str, Mapping[str, Sequence[str]]], seed: int, missing: float,
             noise: float) -> tuple[dict, dict]:
    """Return the listener's boards (domain -> entity -> properties) and what differs (domain -> entity -> kinds).

    Drawn from ``random.Random(f"listener:{seed}")``: per domain (board order), entity
    and attribute, three draws (missing?, misperceived?, which other value).
    """
    rng = random.Random(f"listener:{seed}")
    seen: dict = {}
    errors: dict = {}
    for domain, board in boards.items():
        seen[domain] = {}
        for entity, props in board.items():
            mine = []
            for attribute, values in DOMAIN_ATTRIBUTES[domain].items():
                (value,) = [p for p in props if p in values]
                lost, flipped = rng.random() < missing, rng.random() < noise
                other = rng.choice([v for v in values if v != value])
                if lost:
                    errors.setdefault(domain, {}).setdefault(entity, []).append(("missing", value, None))
                elif flipped:
                    errors.setdefault(domain, {}).setdefault(entity, []).append(("noise", value, other))
                    mine.append(other)
                else:
                    mine.append(value)
            seen[domain][entity] = mine
    return seen, errors


def speak(agent: Any, target: str, domain: str, time: float, turn: int) -> list[str]:
    """Return an agent's description of ``target`` at ``time``, encoding it in the agent's own WM.

    ``agent`` has a ``manager`` (its WMManager), ``consultants`` and ``algorithms`` per domain:
    the listener and the human speaker of :mod:`.games` describe the same way (SD-PIA over
    their WM, DIST-PIA under ``none``).
    """
    agent.manager.advance(time)
    return describe(target, agent.consultants[domain], agent.algorithms[domain], attributes=PROPERTY_ATTRIBUTE,
                    writes=True, time=time, turn=turn).description


class Listener:
    """The agent the robot speaks to: its own knowledge per domain, optionally a WM and a voice of its own.

    ``memory`` (a robot partner's WM settings) makes it a speaker too (:meth:`say`,
    SD-PIA over its WM, DIST-PIA under ``none``); without it, it only listens, in a
    WM nobody reads.  ``scenario`` is the game's (:func:`.games.scenario_of`, which the
    caller passes so that this module need not import the games): the world's exclusive
    groups, and with ``memory`` the policy per domain.
    """

    def __init__(self, game: Any, options: ListenerOptions, scenario: Scenario,
                 memory: Optional[Mapping[str, Any]] = None) -> None:
        self.options = options
        boards, self.errors = perceive(game.boards, game.seed, options.missing, options.noise)
        self.consultants: dict[str, Consultant] = {}
        self.algorithms: dict[str, str] = {}
        self.manager = WMManager()
        for domain, board in boards.items():
            order = listener_order(options.order_name(), domain, game.human_orders[domain])
            self.consultants[domain] = Consultant(domain, {e: {p: 1.0 for p in ps} for e, ps in board.items()}, order,
                                                  exclusive=scenario.domains[domain].exclusive)
            if memory is not None:
                policy = scenario.policy_for(domain, dict(memory))  # type: ignore[arg-type]
                self.manager.manage(self.consultants[domain].wm, policy, now=0.0)
                self.algorithms[domain] = algorithm_for(policy.retains, None)

    def say(self, target: str, domain: str, time: float, turn: int) -> list[str]:
        """Return the listener's description of ``target`` (encoding it in its WM); needs a memory."""
        return speak(self, target, domain, time, turn)

    def see(self, change: Any) -> None:
        """Take in a fact change as it is: the entity's attribute now has the new value."""
        self.manager.advance(change.time)
        values = DOMAIN_ATTRIBUTES[change.domain][PROPERTY_ATTRIBUTE[change.new]]
        facts = {v: 0.0 for v in values}
        facts[change.new] = 1.0
        self.consultants[change.domain].assert_facts(change.entity, facts, change.time)

    def resolve(self, description: Sequence[str], domain: str, time: float, turn: int) -> tuple[str, list[str]]:
        """Resolve with the core's RR in the listener's knowledge; return (status, candidates left)."""
        self.manager.advance(time)
        ports = {domain: LocalPort(self.consultants[domain])}
        resolution = run_sync(resolve(description, ports, domain=domain, time=time, turn=turn))
        return resolution.status, list(resolution.candidates)

    def matching(self, description: Sequence[str], domain: str) -> list[str]:
        """Return the entities every property of ``description`` holds for, in the listener's knowledge (read-only)."""
        consultant = self.consultants[domain]
        left = list(consultant.entities)
        for prop in description:
            left = consultant.holds(prop, left)
        return left

    def blame(self, description: Sequence[str], domain: str) -> tuple[str, list[str]]:
        """Return the property the listener says fits no one, and the candidates the rest of the description leaves.

        The first property (utterance order) without which some candidate fits; if
        none, the one at which the candidates ran out.  Read-only (the listener
        explaining "none fits"; nothing is encoded).
        """
        for prop in description:
            left = self.matching([p for p in description if p != prop], domain)
            if left:
                return prop, left
        for i, prop in enumerate(description):
            if not self.matching(description[:i + 1], domain):
                return prop, self.matching(description[:i], domain)
        return description[-1], []

    def hear(self, description: Sequence[str], target: str, domain: str, robot: Consultant, time: float,
             turn: int) -> Heard:
        """Resolve a robot description, repairing failures from the robot's LTM (``robot``) as the module says."""
        heard = Heard(target)
        said = list(description)
        if not said:  # nothing to resolve: the reference fails at once
            heard.attempts.append([])
            heard.outcomes.append(NO_MATCH)
            return heard
        disputed: list[str] = []  # what the listener said fits no one: never said again in this turn
        while True:
            status, candidates = self.resolve(said, domain, time, turn)
            if status == RESOLVED and candidates != [target]:
                status = WRONG
            heard.attempts.append(list(said))
            heard.outcomes.append(status)
            if status == RESOLVED or len(heard.repairs) >= self.options.max_repairs:
                return heard
            dropped = None
            if status == NO_MATCH:
                dropped, candidates = self.blame(said, domain)
                said = [p for p in said if p != dropped]
                disputed.append(dropped)  # type: ignore[arg-type]
            added = next_property(robot, target, said, candidates, exclude=disputed)
            if added is None and (dropped is None or not said):
                return heard  # no repair the robot can make
            if added is not None:
                said.append(added)
                robot.encode(target, [added], "speaker", time, turn)  # rule 1: the robot said it
            heard.repairs.append({"added": added, "dropped": dropped})


def next_property(robot: Consultant, target: str, said: Sequence[str], candidates: Sequence[str],
                  exclude: Sequence[str] = ()) -> Optional[str]:
    """Return the robot's next property for a repair (Incremental Algorithm order), or None.

    The first property in the robot's preference order that holds for ``target`` in
    its LTM, is neither said nor excluded, and does not hold (in its LTM) for at
    least one of ``candidates`` other than the target.
    """
    others = [c for c in candidates if c != target and robot.knows_entity(c)]
    if not others:
        return None
    for prop in robot.properties_of(target):
        if prop in said or prop in exclude:
            continue
        if len(robot.holds(prop, others)) < len(others):
            return prop
    return None


__all__ = ["AMBIGUOUS", "Heard", "Listener", "ListenerOptions", "MAX_REPAIRS", "NO_MATCH", "ORDERS", "PARTNERS",
           "RESOLVED", "WRONG", "listener_order", "next_property", "perceive"]
