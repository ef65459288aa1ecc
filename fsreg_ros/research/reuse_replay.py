"""Replaying reference games through the core's working memory: each candidate's WM cell under a setting.

Every game is played through the core's own working memory: a
:class:`~fsreg_ros.core.memory.WMBuffer` managed by a
:class:`~fsreg_ros.core.forgetting.wm_manager.WMManager` under a
:class:`~fsreg_ros.core.forgetting.policies.ForgettingPolicy` (the same code the simulator and the
node graph run; nothing here re-implements a rule).  Each content word type is a property of
the message's referent, an entity; messages are encoded in word order (a repeated word is a
refresh); the message time, in seconds from the game's first message, is the clock (the
manager catches up to it before every message, as the simulator does before every turn).

*Group WM* (the robot's design): one buffer per game holds what anyone said.  *Player WM*:
one buffer per player holds only what that player said (cause ``speaker``) or heard (``rr``)
while present; an event reads its describer's buffer.

Each trial begins a reference episode of its referent (``WMBuffer.begin_episode``, at the
trial's first message, before it is encoded), in every WM present.  The replay writes each
candidate's *cell*: 0 if the word is not in the referent's WM queue, else 1 + its strength bin
(:func:`strength_cells`: the entry's episode age and how many episodes it was used in, from
``WMBuffer.strength``), which the graded link fits a rate to; the in/out link reads only cell > 0.

A game under a grid point that the core promises forgets nothing in it
(:func:`fsreg_ros.core.forgetting.keeps.keeps_everything`, given the game's :class:`Span`:
its last time, the most words held per referent and in all, the most trials and words said
per referent)
leaves the WM of an unmanaged buffer, so its cells are the no-forgetting replay's, played once
(:func:`cells_of`); a grid point of two rules one of which keeps everything in a game forgets
what the other rule alone does (:func:`~fsreg_ros.core.forgetting.keeps.within`), so the game
takes that rule's cells when its grid point was played already (in this process); the other
games are played.
"""

from __future__ import annotations

import multiprocessing
from typing import Optional, Sequence

import numpy as np

from ..core.forgetting.keeps import Span, within
from ..core.forgetting.policies import ForgettingPolicy
from ..core.forgetting.wm_manager import WMManager
from ..core.memory import WMBuffer
from .reuse_events import Events
from .reuse_models import policy_of

DOMAIN = "games"
#: Strength bins of an entry in WM by its episode age (the referent's current episode minus the
#: last one the word was used in; at an event the trial's own episode has begun, so a word said in
#: the referent's previous trial is 1): the upper edges; the last bin holds every larger age.
AGE_EDGES = (1, 2, 3, 5)
#: ... and by the episodes it was used in since it entered WM: 1, or more.
EPISODE_BINS = 2
#: Cells: 0 = not in WM, then one per (age bin, episodes bin).
CELL_NAMES = ("out",) + tuple(f"age {age}, {used}" for age in ("<=1", "2", "3", "4-5", ">5")
                              for used in ("1 episode", "2+ episodes"))
CELLS = len(CELL_NAMES)
#: An entry's cell by its episode age (ages over 63 as 63), for one episode used in (add 1 for more).
_AGE_CELL = tuple(1 + EPISODE_BINS * int(b) for b in np.searchsorted(np.asarray(AGE_EDGES), np.arange(64), side="left"))


def strength_cells(buffer: WMBuffer, referent: str, words: Sequence[str]) -> Optional[list[int]]:
    """Each word's cell in Q[referent] from the strength of its entries (None when the queue is empty).

    The strength's episode fields (``WMBuffer.strength``'s ``age`` and ``episodes``) are read
    from the buffer's episode log over its entries, one read of the queue: ``WMBuffer.strength``
    itself would also rebuild each entry's activation trace under rule ``activation``, which
    the cells do not use (it doubled the replays' time).
    """
    entries = buffer.entry_stamps(referent)
    if not entries:
        return None
    cell = {e.property: _AGE_CELL[age if age < 63 else 63] + (used > 1)
            for e, (age, used) in zip(entries, buffer.episodes.strength(referent, entries))}
    get = cell.get
    return [get(w, 0) for w in words]


class _Memory:
    """A buffer with its manager (None: an unmanaged buffer, which keeps everything)."""

    def __init__(self, policy: Optional[ForgettingPolicy], name: str = DOMAIN) -> None:
        self.buffer = WMBuffer(name)
        self.manager = None
        if policy is not None:
            self.manager = WMManager()
            self.manager.manage(self.buffer, policy, 0.0)
        # The manager is asked to catch up only when that can forget something (decay, activation
        # on seconds, the shared pool: WMManager.clock_driven); the other rules act at encodings
        # and episode boundaries.
        self.clocked = self.manager is not None and self.manager.clock_driven

    def advance(self, time: float) -> None:
        if self.clocked:
            self.manager.advance(time)  # type: ignore[union-attr]


def replay(stream: Sequence[tuple], policy: Optional[ForgettingPolicy], out: np.ndarray) -> None:
    """Play one game's stream through one (group) WM buffer; write each candidate's cell into ``out``."""
    memory = _Memory(policy)
    buffer = memory.buffer
    advance = memory.manager.advance if memory.clocked else None  # type: ignore[union-attr]
    for turn, (kind, time, referent, words, extra, _, _) in enumerate(stream):
        if advance is not None:
            advance(time)
        if kind == "ask":
            cells = strength_cells(buffer, referent, words)
            if cells is not None:
                out[extra:extra + len(words)] = cells
        elif kind == "say":
            buffer.encode(referent, words, extra, time, turn)
        else:
            buffer.begin_episode(referent, time, turn)


def replay_players(stream: Sequence[tuple], policy: Optional[ForgettingPolicy], out: np.ndarray) -> None:
    """Play one game's stream through one WM per player (what they said or heard while present)."""
    memories: dict[str, _Memory] = {}
    for turn, (kind, time, referent, words, extra, player, present) in enumerate(stream):
        for who in present:
            if who not in memories:
                memories[who] = _Memory(policy, f"{DOMAIN}{len(memories)}")
            memories[who].advance(time)
        if kind == "ask":
            cells = strength_cells(memories[player].buffer, referent, words)
            if cells is not None:
                out[extra:extra + len(words)] = cells
        elif kind == "say":
            for who in present:
                memories[who].buffer.encode(referent, words, "speaker" if who == player else "rr", time, turn)
        else:
            for who in present:
                memories[who].buffer.begin_episode(referent, time, turn)


def spans(events: Events) -> list[Span]:
    """Each game's :class:`Span`: what its stream does to a WM that forgets nothing (any player's holds less)."""
    out = []
    for stream in events.streams:
        held: dict[str, set] = {}
        episodes: dict[str, int] = {}
        said: dict[str, int] = {}
        last = 0.0
        for kind, time, referent, words, _, _, _ in stream:
            last = max(last, time)
            if kind == "say":
                held.setdefault(referent, set()).update(words)
                said[referent] = said.get(referent, 0) + len(words)
            elif kind == "episode":
                episodes[referent] = episodes.get(referent, 0) + 1
        sizes = [len(words) for words in held.values()]
        out.append(Span(last, sum(sizes), max(sizes, default=0), max(episodes.values(), default=0),
                        max(said.values(), default=0)))
    return out


_SHARED: dict = {}


def _replay_setting(index: int) -> np.ndarray:
    events, settings, play, games = _SHARED["events"], _SHARED["settings"], _SHARED["play"], _SHARED["games"]
    setting = settings[index]
    policy = None if setting is None else policy_of(setting)
    out = np.zeros(events.candidates, dtype=np.uint8)
    kept, bounds, done = _SHARED["kept"], _SHARED["bounds"], _SHARED["done"]
    rests = within(policy, _SHARED["spans"]) if policy is not None else [policy] * len(events.streams)
    for g, stream in enumerate(events.streams):
        if games is None or games[g]:
            rest, span = rests[g], slice(bounds[g], bounds[g + 1])
            if policy is not None and rest is None:
                out[span] = kept[span]  # as if unmanaged (module docstring)
            elif rest is not policy and _key(rest) in done:
                out[span] = done[_key(rest)][span]  # the policy of its other rules, played already
            else:
                play(stream, policy, out)
    if policy is not None:
        done[_key(policy)] = out
    return out


def _key(policy: ForgettingPolicy) -> tuple:
    return tuple(sorted(policy.settings().items()))


def cells_of(events: Events, settings: Sequence[Optional[dict]], jobs: int = 1, players: bool = False,
             games: Optional[np.ndarray] = None) -> np.ndarray:
    """Every candidate's cell under each setting (rows; None = no forgetting), replaying every game.

    ``players``: per-player WM instead of the group's; ``games``: replay only these (the other
    games' candidates stay 0); ``jobs`` processes (results do not depend on it).  A game the
    setting forgets nothing in takes the no-forgetting replay's cells (module docstring).
    """
    play = replay_players if players else replay
    bounds = np.searchsorted(events.game, np.arange(len(events.streams) + 1))
    _SHARED.update(events=events, settings=[None], play=play, games=games, spans=spans(events), bounds=bounds,
                   kept=None, done={})
    try:
        if settings:
            _SHARED["kept"] = _replay_setting(0)
        _SHARED["settings"] = list(settings)
        if jobs <= 1 or len(settings) < 2:
            rows = [_replay_setting(i) for i in range(len(settings))]
        else:
            with multiprocessing.get_context("fork").Pool(jobs) as pool:
                rows = pool.map(_replay_setting, range(len(settings)), chunksize=max(1, len(settings) // (8 * jobs)))
    finally:
        _SHARED.clear()
    if not rows:
        return np.zeros((0, events.candidates), dtype=np.uint8)
    return np.stack(rows)


def memberships(events: Events, settings: Sequence[Optional[dict]], jobs: int = 1) -> np.ndarray:
    """WM membership (group WM) of every candidate under each setting (rows)."""
    return cells_of(events, settings, jobs) > 0


__all__ = ["DOMAIN", "AGE_EDGES", "EPISODE_BINS", "CELLS", "CELL_NAMES", "strength_cells", "replay", "replay_players",
           "spans", "cells_of", "memberships"]
