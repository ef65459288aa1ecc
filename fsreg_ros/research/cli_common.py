"""What every command of the research workbench shares: its usage error, the one-line refusal, number lists.

Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Optional, Sequence

from ..core.algorithms.generation import GenerationError
from ..core.forgetting.policies import PolicyError
from .tuna import TunaError


class UsageError(ValueError):
    """A command-line value is unusable; the message names the option."""


def run_command(
    main: Callable[[argparse.Namespace], int], parser: argparse.ArgumentParser, argv: Optional[Sequence[str]]
) -> int:
    args = parser.parse_args(argv)
    try:
        return main(args)
    except (UsageError, TunaError, GenerationError, PolicyError, OSError, ValueError) as err:
        print(f"{parser.prog}: error: {err}", file=sys.stderr)
        return 2


def number_list(option: str, text: str, kind: type, low: float, high: float) -> tuple:
    """Parse a comma-separated list of numbers in [low, high] for ``option``."""
    values = []
    for part in text.split(","):
        part = part.strip()
        try:
            value = kind(part)
        except ValueError:
            raise UsageError(f"{option}: '{part}' is not a{'n integer' if kind is int else ' number'}") from None
        if not low <= value <= high or value != value:
            raise UsageError(f"{option}: {part} is out of range [{low}, {high}]")
        values.append(value)
    if not values:
        raise UsageError(f"{option}: give at least one value")
    return tuple(dict.fromkeys(values))


# the name the commands have always called it by
_run = run_command
