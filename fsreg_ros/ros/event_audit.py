"""The player's record of one run's ``wm/events``: complete, in order, and this graph's own (issue 20).

A consultant numbers its events ``seq`` 1, 2, 3, ... per ``incarnation`` and stamps
them with its graph's identity (contract ``WMEventMessage``); a listener that notes
where each consultant stood before the run and where it stands after it can tell
whether it heard exactly the events in between.  The player feeds it every message it hears.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from .. import contract
from .client_base import describe_graph

#: Fields a consultant adds to an event for transport; the trace keeps the event itself (docs/semantics.md §2).
TRANSPORT_FIELDS = ("seq", "incarnation", contract.GRAPH_FIELD)


@dataclass
class EventAudit:
    """Every ``wm/events`` message of one run, checked for completeness and origin.

    :meth:`start` notes, per domain, the consultant's incarnation and the last ``seq``
    it had published before the run; :meth:`hear` takes every message (a foreign or
    malformed one is the audit's ``fault``); :meth:`check` says, given the last
    ``seq`` the consultant reports after the run, whether exactly the events in
    between were heard.
    """

    graph: str
    domains: tuple[str, ...]
    base: dict[str, int] = field(default_factory=dict)
    incarnation: dict[str, int] = field(default_factory=dict)
    seqs: dict[str, list[int]] = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)
    fault: Optional[str] = None

    def start(self, domain: str, incarnation: Optional[int], base: int) -> None:
        """Note the consultant of ``domain`` before the first turn: its incarnation (if known) and last ``seq``."""
        if incarnation is not None:
            self.incarnation[domain] = incarnation
        self.base[domain] = base
        early = [s for s in self.seqs.get(domain, []) if s > base]
        self.seqs[domain] = early
        self.events = [e for e in self.events if e["domain"] != domain or e["_seq"] > base]

    def _fail(self, problem: str) -> None:
        if self.fault is None:
            self.fault = problem

    def hear(self, data: dict) -> None:
        """Take one ``wm/events`` message."""
        graph = data.get(contract.GRAPH_FIELD) or ""
        if graph != self.graph:
            self._fail(f"{contract.WM_EVENTS.name}: an event from another graph ({describe_graph(graph)}, this run is "
                       f"{describe_graph(self.graph)}): another graph publishes in this namespace")
            return
        domain, seq, incarnation = data.get("domain"), data.get("seq"), data.get("incarnation")
        if domain not in self.domains:
            self._fail(f"{contract.WM_EVENTS.name}: an event of domain {domain!r}, which this run does not have")
            return
        if not isinstance(seq, int) or isinstance(seq, bool) or not isinstance(incarnation, int):
            self._fail(f"{contract.WM_EVENTS.name}: an event of '{domain}' without 'seq' and 'incarnation': "
                       "its completeness cannot be checked")
            return
        if self.incarnation.setdefault(domain, incarnation) != incarnation:
            self._fail(f"consultant '{domain}' restarted during the run (incarnation {self.incarnation[domain]} -> "
                       f"{incarnation}): its earlier events may be missing")
            return
        if domain in self.base and seq <= self.base[domain]:
            return  # published before the run began
        event = {k: v for k, v in data.items() if k not in TRANSPORT_FIELDS}
        event["_seq"] = seq
        self.seqs.setdefault(domain, []).append(seq)
        self.events.append(event)

    def heard(self, domain: str) -> int:
        return len(self.seqs.get(domain, ()))

    def check(self, domain: str, last: int) -> Optional[str]:
        """Return what is wrong with ``domain``'s events given its last ``seq`` after the run (None: complete)."""
        base = self.base[domain]
        expected = list(range(base + 1, last + 1))
        got = self.seqs.get(domain, [])
        if got == expected:
            return None
        missing = sorted(set(expected) - set(got))
        extra = len(got) - len(set(got)) + len(set(got) - set(expected))
        what = []
        if missing:
            shown = ", ".join(str(s) for s in missing[:10]) + (", ..." if len(missing) > 10 else "")
            what.append(f"{len(missing)} of its {len(expected)} events missing (seq {shown})")
        if extra:
            what.append(f"{extra} unexpected or repeated")
        if not what:
            what.append("its events arrived out of order")
        return f"consultant '{domain}': " + "; ".join(what)

    def trace_events(self) -> list[dict]:
        """Return the events heard in the run, without their transport fields, in arrival order."""
        return [{k: v for k, v in e.items() if k != "_seq"} for e in self.events]
