"""The in-process consultant port: :class:`LocalPort`, over a consultant service in this process.

:class:`LocalPort` is a :class:`~fsreg_ros.core.algorithms.port.ConsultantPort` over a
:class:`~fsreg_ros.core.consultant.service.ConsultantService` (ready at once, no store).

The simulator, the research tools and the tests run the algorithms through it (with
:func:`~fsreg_ros.core.algorithms.port.run_sync`); the consultant node serves the same service over
the graph, so both run the same code.
"""

from __future__ import annotations

from typing import Optional, Sequence

from .consultant import Consultant
from ..algorithms.port import Narrowed, Reference, Step, View, Walked, WalkStep, walk_by_narrowing
from .service import ConsultantService


class LocalPort:
    """A :class:`~fsreg_ros.core.algorithms.port.ConsultantPort` over an in-process consultant.

    It is backed by a :class:`~fsreg_ros.core.consultant.service.ConsultantService` (ready at once,
    no store), the same code the consultant node serves with: the simulator and the
    graph share it.
    """

    def __init__(self, consultant: Consultant) -> None:
        self.consultant = consultant
        self.domain = consultant.domain
        self.service = ConsultantService(consultant, ready=True)

    async def preference(self) -> list[str]:
        return list(self.consultant.preference)

    async def open(
        self, target: Optional[str] = None, context: Optional[Sequence[str]] = None, first: Optional[Step] = None,
        refer: Optional[Reference] = None,
    ) -> View:
        return self.service.open(target, context, first, refer)

    async def narrow(self, view: View, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> Narrowed:
        return self.service.narrow(view.handle, prop, cause, time, turn)

    async def walk(self, view: View, steps: Sequence[WalkStep], cause: Optional[str], time: float,
                   turn: Optional[int], size: Optional[int] = None) -> Walked:
        # Through self.narrow, so a port that refines narrow (research/games.py) walks by its own.
        return await walk_by_narrowing(self, view, steps, cause, time, turn, size)

    async def rule_out(self, view: View) -> tuple[list[str], list[int]]:
        return self.service.rule_out(view.handle)

    async def close(
        self, view: View, encode: Sequence[str] = (), time: float = 0.0, turn: Optional[int] = None
    ) -> list[str]:
        return self.service.close(view.handle, encode, time, turn)

    async def wm(self, entity: str) -> list[str]:
        """Q[entity], LRU first (in-process only: the graph serves it on the debug service)."""
        return self.consultant.queue(entity)

    async def encode(
        self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> None:
        """Encode(entity, properties) (Algorithm 1; in-process only)."""
        self.service.encode(entity, properties, cause, time, turn)
