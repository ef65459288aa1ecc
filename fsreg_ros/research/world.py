"""The world of the generated games: domains, attributes and their values, the robot's orders.

Shared by :mod:`.games` (which deals boards and plays games in it) and :mod:`.listener`
(the agent that perceives it); a module of its own so that neither imports the other
for it.
"""

from __future__ import annotations

DOMAIN = "faces"
OBJECTS = "objects"
#: Each domain's attributes and their values (property names as in the shipped lexicon where it has them).
DOMAIN_ATTRIBUTES: dict[str, dict[str, tuple[str, ...]]] = {
    DOMAIN: {
        "hair-colour": ("light-hair", "dark-hair"),
        "hair-length": ("short-hair", "long-hair"),
        "gender": ("male", "female"),
        "clothing": ("lab-coat", "hoodie", "t-shirt"),
        "glasses": ("glasses", "no-glasses"),
    },
    OBJECTS: {
        "kind": ("mug", "ball", "box"),
        "colour": ("red", "green", "blue", "yellow"),
        "size": ("large", "small"),
        "place": ("on-table", "on-shelf", "in-drawer", "on-floor"),
    },
}
ATTRIBUTES = DOMAIN_ATTRIBUTES[DOMAIN]
#: What can change mid-game, as perception would report it: glasses taken off or put on,
#: clothes changed, an object moved.
MUTABLE = {DOMAIN: ("glasses", "clothing"), OBJECTS: ("place",)}
#: The worlds a game can be played in: their domains, in order.
WORLDS = {"faces": (DOMAIN,), "faces+objects": (DOMAIN, OBJECTS)}
#: The robot's preference order per domain (the same in every game).
ROBOT_ORDERS = {d: tuple(v for values in attrs.values() for v in values) for d, attrs in DOMAIN_ATTRIBUTES.items()}
ROBOT_ORDER = ROBOT_ORDERS[DOMAIN]
PROPERTY_ATTRIBUTE = {
    value: a for attrs in DOMAIN_ATTRIBUTES.values() for a, values in attrs.items() for value in values
}
#: Each domain's exclusive groups: an entity has one value of each attribute, so its values exclude each other
#: (a fact change names the old value with certainty 0 itself, so the exclusion retracts nothing more).
EXCLUSIVE = {d: tuple(values for values in attrs.values()) for d, attrs in DOMAIN_ATTRIBUTES.items()}


__all__ = ["DOMAIN", "OBJECTS", "DOMAIN_ATTRIBUTES", "ATTRIBUTES", "MUTABLE", "WORLDS", "ROBOT_ORDERS",
           "ROBOT_ORDER", "PROPERTY_ATTRIBUTE", "EXCLUSIVE"]
