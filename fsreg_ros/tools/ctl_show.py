"""``fsreg-ctl``'s answers as text: one line (or a few) per answer, and ``watch``'s screen on a terminal."""

from __future__ import annotations

import json
from typing import Optional

from .ctl_table import PROG
from .up import restored_text


def show_say(answer: dict) -> str:
    status = answer.get("status")
    heard = ", ".join(answer.get("description") or []) or "nothing known"
    unknown = answer.get("unknown_words") or []
    tail = f"; heard: {heard}" + (f"; unknown words: {', '.join(unknown)}" if unknown else "")
    if status == "resolved":
        return f"{answer.get('resolved')} (resolved{tail})"
    if status == "ambiguous":
        return f"ambiguous: {', '.join(answer.get('candidates') or [])}{tail}"
    return f"{status}{tail}"


def held_text(origin: Optional[dict], strength: Optional[dict]) -> str:
    """Return how a WM entry is held: ``[speaker turn 3; age 0, 1 episode, activation 0.52]`` ('' if nothing known).

    ``origin``: the encoding that made it enter WM (cause, turn); ``strength``: its episode
    age (0: used in the entity's current episode), the episodes it was used in and, under
    rule activation, its activation (``inf`` at an encoding's very time).
    """
    parts = []
    if origin:
        parts.append(str(origin.get("cause")) + (f" turn {origin['turn']}" if origin.get("turn") is not None else ""))
    if strength:
        episodes = strength.get("episodes")
        text = f"age {strength.get('age')}, {episodes} episode{'' if episodes == 1 else 's'}"
        activation = strength.get("activation")
        if activation is not None:
            text += f", activation {activation if isinstance(activation, str) else format(activation, '.2f')}"
        parts.append(text)
    return f" [{'; '.join(parts)}]" if parts else ""


def show_describe(answer: dict) -> str:
    words = answer.get("description") or []
    origins = list(answer.get("origins") or []) + [None] * len(words)
    strengths = list(answer.get("strengths") or []) + [None] * len(words)
    sources = ", ".join(f"{p}: {s}" + (held_text(o, g) if s == "wm" else "")
                        for p, s, o, g in zip(words, answer.get("sources") or [], origins, strengths))
    left = answer.get("distractors_left") or []
    note = "" if answer.get("distinguishing", True) else f"; not distinguishing from {', '.join(left)}"
    return f"\"{answer.get('text')}\" ({sources or 'nothing to say'}{note})"


def show_assert(answer: dict) -> str:
    updated = ", ".join(f"{p} {c:g}" for p, c in (answer.get("updated") or {}).items())
    retracted = answer.get("retracted") or []
    what = "added" if answer.get("new_entity") else "updated"
    return (f"{answer.get('entity')} ({answer.get('domain')}): {what} {updated}"
            + (f"; retracted from WM: {', '.join(retracted)}" if retracted else ""))


def show_status(status: dict) -> str:
    lines = [f"graph {status.get('graph') or '(unnamed)'}: {'ready' if status.get('ready') else 'NOT ready'}, "
             f"time {status.get('time'):g} s"]
    for domain in status.get("domains") or []:
        running = (status.get("running") or {}).get(domain)
        tick = (status.get("next_tick") or {}).get(domain)
        lines.append(
            f"  {domain}: memory {json.dumps((status.get('memory') or {}).get(domain), sort_keys=True)}, "
            f"running {json.dumps(running, sort_keys=True)}, incarnation "
            f"{(status.get('incarnation') or {}).get(domain)}, "
            f"{'configured' if (status.get('configured') or {}).get(domain) else 'not configured'}"
            + (f", next decay tick at {tick:g} s" if isinstance(tick, (int, float)) else "")
            + f"; {restored_text((status.get('restored') or {}).get(domain))}")
    return "\n".join(lines)


def show_state(state: dict) -> str:
    queues = state.get("queues") or {}
    body = "  ".join(f"{entity}: [{', '.join(props)}]" for entity, props in queues.items()) or "(empty)"
    return f"t={state.get('time', 0):.2f} {state.get('domain')}  {body}"


def show_event(event: dict) -> str:
    return (f"t={event.get('time', 0):.2f} {event.get('op')} {event.get('domain')} {event.get('entity')} "
            f"{event.get('property')} ({event.get('cause')})")


class Screen:
    """``watch`` on a terminal: every domain's queues redrawn in place after each update."""

    def __init__(self, out) -> None:
        self.out = out
        self.states: dict[str, dict] = {}

    def update(self, state: dict) -> None:
        self.states[str(state.get("domain"))] = state
        lines = ["\x1b[H\x1b[J" + f"{PROG} watch: working memory (least recently used first); Ctrl-C ends"]
        for domain, st in sorted(self.states.items()):
            lines.append(f"{domain} at t={st.get('time', 0):.2f} s")
            queues = st.get("queues") or {}
            width = max((len(e) for e in queues), default=0)
            lines += [f"  {e.ljust(width)}  {', '.join(q)}" for e, q in queues.items()] or ["  (empty)"]
        self.out.write("\n".join(lines) + "\n")
        self.out.flush()
