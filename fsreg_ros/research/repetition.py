"""Description length by repetition of a referent: the sweep's measure of people's shrinking descriptions.

People's descriptions of a tangram shrink from 7.7 to 2.5 content words over six
repetitions (docs/research.md, section 8).  The robot's counterpart, per game: the mean
number of properties (content words) of the robot's k-th description of the same
referent, k = 1 .. :data:`REPETITIONS`, over the referents the robot described at
least k times (None when it described none that often).  A description is REG's, as
first said (a listener's repairs are ``said_length``).
"""

from __future__ import annotations

from typing import Mapping, Optional, Sequence

#: The repetitions measured (people's corpus has six).
REPETITIONS = 6
#: runs.csv's and summary.csv's columns: ``length_rep1`` ... ``length_rep6``.
METRICS = tuple(f"length_rep{k}" for k in range(1, REPETITIONS + 1))


def lengths_by_repetition(turns: Sequence[Mapping]) -> dict[str, Optional[float]]:
    """Return :data:`METRICS` for one game's turns (the robot's, in order; others are skipped)."""
    seen: dict[str, int] = {}
    lengths: list[list[int]] = [[] for _ in range(REPETITIONS)]
    for turn in turns:
        if turn.get("speaker") != "robot":
            continue
        k = seen.get(turn["target"], 0)
        seen[turn["target"]] = k + 1
        if k < REPETITIONS:
            lengths[k].append(len(turn.get("description") or ()))
    return {name: (sum(values) / len(values) if values else None) for name, values in zip(METRICS, lengths)}
