"""What a user types on the tools' command lines, checked in one place: one line, exit 2, before any ROS.

:class:`OneLineParser` (argparse with one-line errors naming the tool and subcommand),
:func:`number` (an argparse ``type`` for a finite number in a range) and
:func:`undecodable` (an argument that is not UTF-8 text: the shell passes bytes, and a
ROS string or a JSON message can only carry text).  ``fsreg-ctl`` and ``fsreg-up`` use them.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from typing import Any, Callable, Optional, Sequence

from ..contract.codec import printable
from ..core.forgetting import settings

#: The tools' exit code for bad usage.
EXIT_USAGE = 2
#: What argparse takes for a negative number rather than an option.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``fsreg-ctl: error: ...``), exit 2.

    ``-inf``, ``-nan`` and ``-1e300`` are read as (negative) numbers, not options, so a
    number argument refuses them with its own range instead of "required".
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str) -> None:  # type: ignore[override]
        tool, _, sub = self.prog.partition(" ")
        where = f"{sub}: " if sub else ""
        self.exit(EXIT_USAGE, f"{tool}: error: {where}{' '.join(message.split())} (see {self.prog} --help)\n")


def number(low: float, high: float, *, integer: bool = False, above: bool = False,
           unit: str = "") -> Callable[[str], Any]:
    """Return an argparse ``type`` taking a finite number in [low, high] (``above``: (low, high]); one-line errors."""
    bounds = f"{'(' if above else '['}{settings.number(low)}, {settings.number(high)}]"
    kind = "a whole number" if integer else "a finite number"
    rule = f"{kind}{' of ' + unit if unit else ''} in {bounds}"

    def parse(text: str) -> Any:
        try:
            value = int(text) if integer else float(text)
        except (ValueError, OverflowError):
            raise argparse.ArgumentTypeError(f"expected {rule}, got {printable(repr(text), 60)}") from None
        if not math.isfinite(value) or value < low or value > high or (above and value <= low):
            raise argparse.ArgumentTypeError(f"expected {rule}, got {printable(text, 60)}")
        return value

    return parse


def undecodable(argv: Sequence[str]) -> Optional[str]:
    """Return the refusal of the first argument that is not UTF-8 text (None: all are), naming it and its bytes.

    Python keeps such bytes as lone surrogates (``os.fsdecode``); they cannot be sent,
    printed or stored as text.
    """
    for index, arg in enumerate(argv, 1):
        try:
            arg.encode("utf-8")
        except UnicodeEncodeError:
            raw = printable(repr(os.fsencode(arg)), 80)
            return f"argument {index} is not UTF-8 text (its bytes: {raw}); give text in UTF-8"
    return None
