"""What the live view shows, as plain data: the dialogue, each entity's WM per domain, REG's sources.

:class:`ViewModel` owns the view's picture of one graph.  It is fed the graph's own
messages (``wm/state``, ``wm/events``, ``dialogue/human``, ``rr/result``,
``reg/expression``, ``wm_manager/ready`` and the WM Manager's status) by
:mod:`fsreg_ros.tools.view`, and :meth:`ViewModel.snapshot` gives the JSON the page
renders.  It imports no ROS package, so its rules are tested without a graph.

What a queue entry shows (docs/deployment.md "The live view"):

* ``origin``: the cause (and dialogue turn) of the encoding that made the property enter
  the queue, from the consultant's ``wm/events`` (``?`` when that encoding happened
  before the view started);
* ``strength``: how strongly the consultant holds the entry (episode age, episodes used
  in, activation under rule ``activation``), as its ``open`` reply says
  (:meth:`~fsreg_ros.ros.client.GraphClient.held`, what ``fsreg-ctl wm`` prints).  The view
  asks for an entity's strength (:meth:`ViewModel.strength_wanted`) once its queue or an
  event of it changed, so a graph nobody views pays nothing; it is shown only while the
  queue it came with is the queue ``wm/state`` shows (None meanwhile);
* ``forget_at``: under decay, when the property leaves WM if nothing is encoded meanwhile:
  decay pops the front of every non-empty queue each tick (Alg. 2), so the k-th entry
  (0 = least recently used) leaves at the next tick plus k decay periods; ``None``
  without decay (displacement forgets only when something new is encoded).
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any, Mapping, Optional

from ..core.forgetting.policies import RULE_PARAMETERS, ForgettingPolicy, PolicyError

#: How many dialogue lines the view keeps (the oldest scroll off, and with them what the view knows of their ids).
DIALOGUE_LINES = 200
#: How many queue entries' origins the view keeps (the oldest encoded first go when a stream never forgets).
MAX_ORIGINS = 100_000
#: How many domains' ``wm/state`` the view keeps (the one heard of longest ago goes first).
MAX_DOMAINS = 256
#: How many entities' strengths the view keeps (the one read longest ago goes first).
MAX_HELD = 100_000


def decay_period(memory: Mapping[str, Any]) -> Optional[float]:
    """Return the decay period of a policy object (seconds), or None when the policy does not decay."""
    try:
        policy = ForgettingPolicy.from_settings({k: v for k, v in memory.items() if v is not None})
    except (PolicyError, TypeError, ValueError):
        return None
    if not policy.decays:
        return None
    (period,) = RULE_PARAMETERS["decay"]
    return float(policy.value(period))


class ViewModel:
    """The live view's state of one graph; every method is thread-safe.

    Its memory is bounded whatever the graph says: :data:`DIALOGUE_LINES` lines (an
    utterance id is forgotten with its line), :data:`MAX_ORIGINS` origins,
    :data:`MAX_DOMAINS` domains.
    """

    def __init__(self) -> None:
        self._lock = threading.Condition()
        self.version = 0
        self._states: dict[str, dict] = {}  # domain -> latest wm/state
        self._origins: dict[tuple[str, str, str], dict] = {}  # (domain, entity, property) -> origin
        self._held: dict[tuple[str, str], dict] = {}  # (domain, entity) -> {"queue", "strength"} as last read
        self._unread: dict[tuple[str, str], None] = {}  # entities whose strength is to be read (in order)
        self._dialogue: deque = deque(maxlen=DIALOGUE_LINES)
        self._said: dict[str, int] = {}  # request id -> index of its line in the dialogue
        self._ready: Optional[dict] = None
        self._status: Optional[dict] = None
        self._ready_since_status = False  # a ready message (settings, incarnations) newer than the status
        self._time: Optional[float] = None

    # ------------------------------------------------------------ input
    def _changed(self) -> None:
        self.version += 1
        self._lock.notify_all()

    def on_state(self, state: Mapping[str, Any]) -> None:
        """Take a domain's ``wm/state`` (newer than the last one shown)."""
        with self._lock:
            domain = state["domain"]
            self._states.pop(domain, None)
            _bounded(self._states, MAX_DOMAINS)
            self._states[domain] = dict(state)
            for entity, queue in (state.get("queues") or {}).items():
                held = self._held.get((domain, entity))
                if held is None or held["queue"] != list(queue):
                    self._want((domain, entity))
            self._clock(state.get("time"))
            self._changed()

    def on_event(self, event: Mapping[str, Any]) -> None:
        """Take a ``wm/events`` message: an encode records the entry's origin, a forget drops it."""
        with self._lock:
            key = (event["domain"], event["entity"], event["property"])
            if event.get("op") == "encode":
                self._origins.pop(key, None)
                _bounded(self._origins, MAX_ORIGINS)
                self._origins[key] = {"cause": event.get("cause"), "turn": event.get("turn")}
            elif event.get("op") == "forget":
                self._origins.pop(key, None)
            self._want(key[:2])  # an encoding may change the entity's strengths, not its queue
            self._clock(event.get("time"))
            self._changed()

    def on_human(self, message: Mapping[str, Any]) -> None:
        """Take the human's utterance (``dialogue/human``): a dialogue line, resolved later by ``rr/result``."""
        with self._lock:
            words = message.get("text") or ", ".join(message.get("description") or [])
            self._add_line(message.get("id"), {"speaker": "human", "text": words, "time": message.get("time"),
                                               "turn": message.get("turn")})

    def on_rr(self, message: Mapping[str, Any]) -> None:
        """Take reference resolution's answer to an utterance: whom it resolved (or why not)."""
        with self._lock:
            line = self._line_of(message.get("id"), {"speaker": "human", "text": message.get("text") or "",
                                                     "time": message.get("time")})
            line["resolved"] = message.get("resolved")
            line["status"] = message.get("status")
            if message.get("error"):
                line["error"] = message.get("error")
            line["candidates"] = len(message.get("candidates") or [])
            self._changed()

    def on_expression(self, message: Mapping[str, Any]) -> None:
        """Take REG's expression: the robot's line, each property marked WM (origin, strength) or LTM."""
        with self._lock:
            if message.get("error"):
                line = {"speaker": "robot", "text": "", "error": message.get("error"), "target": message.get("target"),
                        "time": message.get("time")}
            else:
                description = list(message.get("description") or [])
                sources = list(message.get("sources") or [])
                origins = list(message.get("origins") or [])
                strengths = list(message.get("strengths") or [])
                line = {"speaker": "robot", "text": message.get("text") or "", "target": message.get("target"),
                        "time": message.get("time"), "domain": message.get("domain"),
                        "properties": [{"property": p,
                                        "source": sources[i] if i < len(sources) else None,
                                        "origin": origins[i] if i < len(origins) else None,
                                        "strength": strengths[i] if i < len(strengths) else None}
                                       for i, p in enumerate(description)]}
            self._add_line(message.get("id"), line)
            self._clock(message.get("time"))

    def on_ready(self, ready: Mapping[str, Any]) -> None:
        """``wm_manager/ready``: readiness and each domain's running memory settings."""
        with self._lock:
            self._ready = dict(ready)
            self._ready_since_status = True
            self._clock(ready.get("time"))
            self._changed()

    def on_status(self, status: Mapping[str, Any]) -> None:
        """Take the WM Manager's status (the next decay tick of each domain, its settings)."""
        with self._lock:
            self._status = dict(status)
            self._ready_since_status = False
            self._clock(status.get("time"))
            self._changed()

    def strength_wanted(self, limit: int) -> list[tuple[str, str]]:
        """Return (and take) up to ``limit`` ``(domain, entity)`` whose strength is to be read (:meth:`on_held`).

        Those whose queue in the latest ``wm/state`` differs from the one their strength came
        with, or that had an event since; only entities the latest state holds.
        """
        with self._lock:
            wanted = []
            while self._unread and len(wanted) < limit:
                domain, entity = key = next(iter(self._unread))
                del self._unread[key]
                if entity in (self._states.get(domain) or {}).get("queues", {}):
                    wanted.append(key)
            return wanted

    def on_held(self, domain: str, entity: str, held: Mapping[str, Any]) -> None:
        """Take how the consultant holds ``entity``'s entries now: ``queue`` and ``strength`` (parallel)."""
        with self._lock:
            self._held.pop((domain, entity), None)
            _bounded(self._held, MAX_HELD)
            self._held[(domain, entity)] = {"queue": list(held["queue"]), "strength": list(held["strength"])}
            self._changed()

    def status_wanted(self) -> bool:
        """Whether the WM Manager's status may have changed since the last one taken.

        It only adds each domain's next decay tick to what the topics say, so it is
        wanted at the start, after a ``wm_manager/ready`` (settings or an incarnation
        changed) and once the clock has reached a next tick (the tick after it is due).
        """
        with self._lock:
            if self._status is None or self._ready_since_status:
                return True
            ticks = [t for t in (self._status.get("next_tick") or {}).values() if isinstance(t, (int, float))]
            return self._time is not None and any(self._time >= t for t in ticks)

    def _want(self, key: tuple[str, str]) -> None:
        """Note that ``key``'s strength is to be read (at most :data:`MAX_HELD` waiting: the oldest go)."""
        self._unread.pop(key, None)
        _bounded(self._unread, MAX_HELD)
        self._unread[key] = None

    def _clock(self, t: Any) -> None:
        if isinstance(t, (int, float)) and (self._time is None or t > self._time):
            self._time = float(t)

    def _add_line(self, key: Any, line: dict) -> None:
        if key is not None and str(key) in self._said:
            self._find(str(key)).update(line)
        else:
            if key is not None:
                line["id"] = str(key)
            self._append(line)
        self._changed()

    def _append(self, line: dict) -> None:
        """Add a dialogue line; the line that scrolls off takes its id with it."""
        if len(self._dialogue) == self._dialogue.maxlen:
            self._said.pop(self._dialogue[0].get("id"), None)
        self._dialogue.append(line)
        if line.get("id") is not None:
            self._said[line["id"]] = 1

    def _find(self, key: str) -> dict:
        for line in reversed(self._dialogue):
            if line.get("id") == key:
                return line
        line = {"id": key}
        self._append(line)
        return line

    def _line_of(self, key: Any, default: dict) -> dict:
        if key is not None and str(key) in self._said:
            return self._find(str(key))
        self._add_line(key, default)
        return self._dialogue[-1]

    # ------------------------------------------------------------ output
    def wait_change(self, seen: int, timeout: float) -> int:
        """Block until the version passes ``seen`` (or ``timeout`` seconds); return the version."""
        with self._lock:
            self._lock.wait_for(lambda: self.version != seen, timeout)
            return self.version

    def snapshot(self) -> dict:
        """Return the page's data: dialogue lines, each domain's queues (origins, strengths, forget times), settings."""
        with self._lock:
            domains = {}
            for domain, state in sorted(self._states.items()):
                memory = self._memory(domain)
                period = decay_period(memory)
                next_tick = self._next_tick(domain)
                entities = {}
                for entity, queue in sorted(state.get("queues", {}).items()):
                    entries = []
                    held = self._held.get((domain, entity))
                    strength = held["strength"] if held and held["queue"] == list(queue) else [None] * len(queue)
                    for k, prop in enumerate(queue):
                        forget_at = (next_tick + k * period) if (next_tick is not None and period) else None
                        origin = self._origins.get((domain, entity, prop))
                        entries.append({"property": prop, "origin": origin, "strength": strength[k],
                                        "forget_at": forget_at})
                    entities[entity] = entries
                domains[domain] = {"time": state.get("time"), "incarnation": state.get("incarnation"),
                                   "wm_version": state.get("wm_version"), "memory": memory,
                                   "next_tick": next_tick, "entities": entities}
            ready = self._ready or {}
            return {"version": self.version, "time": self._time, "ready": ready.get("ready"),
                    "graph": ready.get("graph"), "domains": domains, "dialogue": list(self._dialogue)}

    def sizes(self) -> dict[str, int]:
        """Return how many lines, utterance ids, origins, domains, strengths, strengths to read it holds (bounded)."""
        with self._lock:
            return {"dialogue": len(self._dialogue), "ids": len(self._said), "origins": len(self._origins),
                    "domains": len(self._states), "held": len(self._held), "unread": len(self._unread)}

    def _memory(self, domain: str) -> dict:
        if self._status and domain in (self._status.get("memory") or {}):
            return dict(self._status["memory"][domain])
        running = ((self._ready or {}).get("domains") or {}).get(domain) or {}
        return dict(running.get("running") or {})

    def _next_tick(self, domain: str) -> Optional[float]:
        if not self._status:
            return None
        tick = (self._status.get("next_tick") or {}).get(domain)
        return float(tick) if isinstance(tick, (int, float)) else None


def _bounded(table: dict, limit: int) -> None:
    """Drop the oldest entries of ``table`` (insertion order) until one more fits within ``limit``."""
    while len(table) >= limit:
        del table[next(iter(table))]
