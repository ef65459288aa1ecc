"""What a buffer may hold: the :class:`Limits` the WM Manager installs, as data.

The WM Manager (:mod:`fsreg_ros.core.forgetting.wm_manager`, with the policies of
:mod:`fsreg_ros.core.forgetting.policies`) decides *what* is forgotten and sets these; the
buffer enforces them after every single encoding event
(:mod:`fsreg_ros.core.memory.displacement`).  This module imports neither.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional

#: How displacement chooses the property it forgets from an over-full queue.
VICTIMS = ("lru", "lfu", "random")


@dataclass(frozen=True)
class Limits:
    """What a buffer may hold, enforced after every encoding event (set by the WM Manager).

    * ``retains``: False forgets everything and encodes nothing (policy ``none``);
    * ``capacity``: at most this many properties per queue (Algorithm 3); the victim
      is the queue's front (``lru``), its least frequently encoded property other
      than the one just encoded (``lfu``, ties to the LRU one), or a random such
      property (``random``, drawn from ``random.Random(seed)``, created anew each
      time the limits are set);
    * ``similarity``: encoding a property of an attribute forgets the entity's other
      properties of that attribute (interference by similarity);
    * ``global_capacity``: at most this many properties in the domain; the victim is
      the front encoded least recently in the whole domain;
    * ``activation``: ``(d, tau)``: an entry is forgotten when its ACT-R base-level
      activation falls below tau (:mod:`fsreg_ros.core.memory.activation`), read on
      ``activation_clock``: the buffer's ``seconds``, or each entity's own ``words``
      (:mod:`fsreg_ros.core.memory.entity_clock`);
    * ``episode_activation``: ``(d, tau)``: the same rule on each entity's own episodes
      clock, decided when the entity's episode begins (:class:`~.entity_clock.EpisodeActivation`;
      ``activation`` is then None: nothing is noted per encoding);
    * ``episode_window``: k: when an entity's episode begins, its entries not used in its
      last k episodes are forgotten (:mod:`fsreg_ros.core.memory.episodes`; not after
      encodings).

    Order after one encoding event: similarity, then capacity, then the global limit.
    """

    retains: bool = True
    capacity: Optional[int] = None
    victim: str = "lru"
    similarity: bool = False
    global_capacity: Optional[int] = None
    seed: int = 0
    activation: Optional[tuple[float, float]] = None
    activation_clock: str = "seconds"
    episode_activation: Optional[tuple[float, float]] = None
    episode_window: Optional[int] = None

    def check(self) -> None:
        """Raise ValueError for an unknown victim choice."""
        if self.victim not in VICTIMS:
            raise ValueError(f"unknown displacement victim {self.victim!r} (known: {', '.join(VICTIMS)})")

    @property
    def lru_only(self) -> bool:
        """True when nothing beyond an LRU capacity and rule ``activation`` is in force (the fast encoding paths)."""
        return self.victim == "lru" and not self.similarity and self.global_capacity is None


UNLIMITED = Limits()


def attribute_of(prop: str, attributes: Optional[Mapping[str, str]] = None, *, own: bool = False) -> Optional[str]:
    """Return the attribute ``prop`` belongs to (the one definition: similarity interference and REG use it).

    It is declared in ``attributes``, or the part before ``=`` in an ``attribute=value``
    name.  A plain name (``glasses``) has none: None, or, with ``own``, it is its own
    attribute (REG's one-value-per-attribute rule counts it as one; similarity interference
    leaves it alone).
    """
    found = attributes.get(prop) if attributes else None
    if found is None:
        if "=" in prop:
            return prop.split("=", 1)[0]
        if own:
            return prop
    return found
