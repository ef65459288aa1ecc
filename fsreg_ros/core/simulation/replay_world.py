"""Whether a recording was made in the world of the scenario it is replayed with (one line, or None).

A replay against another world's knowledge base (``fsreg-sim --replay DIR --scenario
OTHER``) differs turn by turn for a reason the turns do not show: the graph ran with other
domains or entities.  :func:`world_mismatch` says so in one line, naming what does not
match: the recording's domains (``wm_manager/ready``, ``wm/events``) or entities (REG
targets, ``wm/events``, not asserted during the session) the scenario does not have, or a
given scenario file that is not the copy the recording carries.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Optional

from ..scenario import Scenario

#: Most names listed in the line.
SHOWN = 5


def world_mismatch(scenario: Scenario, scenario_path: Path, carried: Optional[Path], steps: Iterable[Any],
                   events: Iterable[dict], ready: Iterable[dict]) -> Optional[str]:
    """Return why ``scenario`` is not the recording's world (None: nothing says so).

    ``carried``: the scenario copy the recording holds, when another file was given;
    ``steps``: the recorded requests (``kind``, ``request``); ``events``: ``wm/events``;
    ``ready``: ``wm_manager/ready`` messages.
    """
    steps, events = list(steps), list(events)
    domains = {d for message in ready for d in (message.get("domains") or {})}
    domains |= {e["domain"] for e in events if isinstance(e.get("domain"), str)}
    where = f"the scenario {scenario_path} does not match the recording"
    missing = sorted(domains - set(scenario.domains))
    if missing:
        return (f"{where}: the recording's domains {_names(missing)} are not among its domains "
                f"({', '.join(scenario.domains)}); every turn below may differ for that alone")
    known = {e for spec in scenario.domains.values() for e in spec.entities}
    asserted = {s.request.get("entity") for s in steps if s.kind == "assert"}
    named = {s.request.get("target") for s in steps if s.kind == "robot"} | {e.get("entity") for e in events}
    unknown = sorted(n for n in named - known - asserted if isinstance(n, str))
    if unknown:
        return (f"{where}: it names entities the scenario does not have ({_names(unknown)}); every turn below "
                "may differ for that alone")
    if carried is not None and carried.is_file() and Path(scenario_path).resolve() != carried.resolve():
        try:
            same = Path(scenario_path).read_bytes() == carried.read_bytes()
        except OSError:
            same = True  # unreadable: the scenario loader has said so already
        if not same:
            return (f"the scenario {scenario_path} is not the one the graph ran with (the recording carries "
                    f"{carried.name}, which differs)")
    return None


def _names(names: list[str]) -> str:
    more = f" and {len(names) - SHOWN} more" if len(names) > SHOWN else ""
    return ", ".join(names[:SHOWN]) + more
