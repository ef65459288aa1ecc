"""Random worlds: seeded scenario files with many entities, for benchmarks and tests.

A world has one domain (``things``) whose properties are values of mutually
exclusive attributes, written ``attribute=value`` (``a07=v3``).  Every entity holds
exactly one value of every attribute, with certainty 1, so a description never needs
two values of one attribute.  The preference order is a random permutation of every
property.  The dialogue interleaves human turns (a description of a random target:
a distinguishing one, built by adding the target's properties in random order while
they rule out someone, or a random subset of its properties, which is often
ambiguous) with robot turns (a random target, or the target the human just named),
at increasing times in tenths of a second (equal times and times on decay ticks
happen).  The same :class:`WorldShape` gives the same world on every run.

The result is a docs/semantics.md section 5 scenario document (a dict); :func:`dump_world`
writes it as YAML that :func:`fsreg_ros.core.scenario.load_scenario` reads.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Optional

import yaml

from ..core.forgetting.policies import ForgettingPolicy, PolicyError

DOMAIN = "things"


@dataclass(frozen=True)
class WorldShape:
    """What :func:`random_world` builds; the defaults are issue 11's benchmark world."""

    entities: int = 10_000
    attributes: int = 40
    values: int = 5  # values per attribute: attributes * values properties in all
    human_turns: int = 100
    robot_turns: int = 100
    policy: str = "decay+displacement"
    decay_period: float = 10.0
    capacity: int = 3
    global_capacity: Optional[int] = None
    distinguishing_share: float = 0.5  # human turns that are distinguishing descriptions
    follow_share: float = 0.3  # robot turns that describe the entity the human just named
    subset_max: int = 4  # largest random-subset human description
    seed: int = 0

    def check(self) -> "WorldShape":
        """Return self if every size and share is usable, else raise ValueError naming the field."""
        for name in ("entities", "attributes", "values", "subset_max"):  # the memory settings: the policy's checks
            if getattr(self, name) < 1:
                raise ValueError(f"world shape: {name} must be >= 1, got {getattr(self, name)}")
        for name in ("human_turns", "robot_turns"):
            if getattr(self, name) < 0:
                raise ValueError(f"world shape: {name} must be >= 0, got {getattr(self, name)}")
        for name in ("distinguishing_share", "follow_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"world shape: {name} must be in [0, 1], got {getattr(self, name)}")
        self.memory()  # the core's own rules for policy names and parameters
        return self

    def memory(self) -> dict:
        """Return the world's ``memory:`` block (the settings given, as a configure carries them); ValueError if bad."""
        try:
            policy = ForgettingPolicy.parse(
                self.policy,
                decay_period=float(self.decay_period),
                capacity=self.capacity,
                global_capacity=self.global_capacity,
            )
        except PolicyError as err:
            raise ValueError(f"world shape: {err}") from None
        return policy.settings()


def property_names(shape: WorldShape) -> list[list[str]]:
    """Return the properties of each attribute (``a07=v3``), attribute by attribute."""
    width = len(str(shape.attributes - 1))
    return [[f"a{a:0{width}d}=v{v}" for v in range(shape.values)] for a in range(shape.attributes)]


def random_world(shape: WorldShape = WorldShape()) -> dict:
    """Build the scenario document of a random world (see the module docstring)."""
    shape.check()
    rng = random.Random(shape.seed)
    groups = property_names(shape)
    width = len(str(shape.entities - 1))
    names = [f"e{i:0{width}d}" for i in range(shape.entities)]
    facts = {name: [rng.choice(group) for group in groups] for name in names}
    preference = [prop for group in groups for prop in group]
    rng.shuffle(preference)
    holders: dict[str, set[str]] = {prop: set() for prop in preference}
    for name, props in facts.items():
        for prop in props:
            holders[prop].add(name)

    speakers = ["human"] * shape.human_turns + ["robot"] * shape.robot_turns
    rng.shuffle(speakers)
    dialogue: list[dict] = []
    time, named = 0.0, None
    for speaker in speakers:
        time = round(time + rng.choice((0.0, 0.5, 1.0, 2.0, 3.5, 5.0, 10.0)) + rng.randrange(10) / 10, 1)
        if speaker == "human":
            named = rng.choice(names)
            if rng.random() < shape.distinguishing_share:
                description = distinguishing_description(named, facts[named], holders, set(names), rng)
            else:
                size = rng.randint(1, min(shape.subset_max, shape.attributes))
                description = rng.sample(facts[named], size)
            dialogue.append({"time": time, "speaker": "human", "target": named, "description": description})
        else:
            target = named if named is not None and rng.random() < shape.follow_share else rng.choice(names)
            dialogue.append({"time": time, "speaker": "robot", "target": target})

    memory = shape.memory()
    return {
        "name": f"random-world-{shape.entities}-seed{shape.seed}",
        "domains": {DOMAIN: {"preference": preference, "entities": facts}},
        "memory": memory,
        "dialogue": dialogue,
    }


def distinguishing_description(
    target: str, props: list[str], holders: dict[str, set[str]], everyone: set[str], rng: random.Random
) -> list[str]:
    """Describe ``target`` by its properties in random order, each kept if it rules someone out.

    It stops when only the target is left, or when its properties run out (a twin entity).
    """
    order = list(props)
    rng.shuffle(order)
    candidates = everyone
    description = []
    for prop in order:
        if len(candidates) == 1:
            break
        kept = candidates & holders[prop]
        if len(kept) < len(candidates):
            description.append(prop)
            candidates = kept
    return description or order[:1]


def dump_world(document: dict) -> str:
    """Return the world as YAML text: block style, each entity's and turn's lists in flow style."""
    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    return yaml.dump(document, Dumper=dumper, sort_keys=False, default_flow_style=None, width=1_000_000)
