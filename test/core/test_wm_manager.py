"""The core WM Manager (core/forgetting/wm_manager.py): what it sends through its port, attach/detach."""

from __future__ import annotations

import pytest

from fsreg_ros.core.memory.ticks import TickError, TickRun
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.memory import WMBuffer
from fsreg_ros.core.forgetting.wm_manager import SYNC_AHEAD, WMManager, configure_buffer


class RecordingPort:
    """A MemoryPort that records what the manager sends."""

    def __init__(self) -> None:
        self.sent: list[tuple] = []

    def configure(self, domain, policy, time):
        self.sent.append(("configure", domain, policy.name, time))

    def decay(self, domain, ticks):
        self.sent.append(("decay", domain, ticks))


DECAY = ForgettingPolicy.parse("decay", decay_period=10.0)


def test_nothing_is_sent_before_attach_and_earlier_ticks_are_not_owed():
    port = RecordingPort()
    manager = WMManager(port)
    manager.manage_domain("faces", DECAY, 0.0)
    assert manager.advance(25.0) == {"faces": 2}
    assert port.sent == []
    manager.attach("faces", 1, 26.0)
    assert port.sent == [("configure", "faces", "decay", 26.0)]
    manager.advance(31.0)
    assert port.sent[-1] == ("decay", "faces", TickRun(0.0, 10.0, 3, 1))


def test_reattach_sends_ticks_owed_while_down_then_configure():
    port = RecordingPort()
    manager = WMManager(port)
    manager.manage_domain("faces", DECAY, 0.0)
    manager.attach("faces", 1, 0.0)
    manager.detach("faces")
    manager.advance(20.0)
    manager.advance(45.0)
    port.sent.clear()
    manager.attach("faces", 2, 50.0)
    # One run for the ticks at 10..50 (merged, never a list), then the policy.
    assert port.sent == [
        ("decay", "faces", TickRun(0.0, 10.0, 1, 5)),
        ("configure", "faces", "decay", 50.0),
    ]
    assert manager.domains["faces"].incarnation == 2 and manager.domains["faces"].owed == []


def test_grid_origin_is_the_managers_start():
    port = RecordingPort()
    manager = WMManager(port, origin=1.7e9)
    manager.manage_domain("faces", DECAY, 1.7e9)
    manager.attach("faces", None, 1.7e9)
    assert manager.advance(1.7e9 + 0.04) == {"faces": 0}  # not forgotten 0.04 s after start
    assert manager.next_tick("faces") == 1.7e9 + 10.0


def test_sync_time_window():
    manager = WMManager()
    assert manager.check_sync_time(100.0, 0.0) == 100.0
    assert manager.check_sync_time(SYNC_AHEAD, 0.0) == SYNC_AHEAD
    for bad in (SYNC_AHEAD + 1.0, 1e6 + SYNC_AHEAD, 1e308, float("inf"), float("nan"), "5"):
        with pytest.raises(TickError):
            manager.check_sync_time(bad, 0.0)


def test_clock_far_ahead_empties_wm_and_decay_continues():
    buffer = WMBuffer("faces")
    manager = WMManager()
    manager.manage(buffer, DECAY)
    buffer.encode("f1", ["a", "b"], "rr", 1.0)
    assert manager.advance(1e9) == {"faces": 10**8}
    assert buffer.snapshot() == {}
    buffer.encode("f1", ["c", "d"], "rr", 1e9 + 1.0)
    manager.advance(1e9 + 10.0)
    assert buffer.snapshot() == {"f1": ["d"]}
    assert manager.advance(5.0) == {"faces": 0}  # backwards: nothing undone or re-applied
    assert buffer.snapshot() == {"f1": ["d"]}


def test_apply_ticks_is_canonical_entity_order_and_bounded():
    events: list = []
    buffer = WMBuffer("faces", events.append)
    configure_buffer(buffer, DECAY, 0.0)
    buffer.encode("f2", ["a", "b"], "rr", 1.0)
    buffer.encode("f1", ["c"], "rr", 1.0)
    events.clear()
    buffer.decay_now(TickRun(0.0, 10.0, 1, 10**12), ["f1", "f2"])
    assert [(e.entity, e.property, e.time) for e in events] == [("f1", "c", 10.0), ("f2", "a", 10.0), ("f2", "b", 20.0)]
    assert buffer.snapshot() == {}
    buffer.encode("f1", ["x"], "rr", 1e13)
    assert buffer.queue("f1") == ("x",)  # later ticks are not owed by a new encoding


def test_lazy_decay_memory_does_not_grow_with_ticks():
    buffer = WMBuffer("faces")
    manager = WMManager()
    manager.manage(buffer, ForgettingPolicy.parse("decay", decay_period=0.01))
    for i in range(1, 2001):
        buffer.encode(f"e{i % 7}", ["a"], "rr", i * 0.05)
        manager.advance(i * 0.05)
    assert buffer.ticks.count == 10_000
    assert len(buffer.ticks._runs) == 1


@pytest.mark.parametrize("settings, driven", [
    ({"policy": "decay", "decay_period": 10.0}, True),
    ({"policy": "activation", "activation_threshold": -1.0}, True),
    ({"policy": "shared-capacity", "shared_capacity": 4}, True),
    ({"policy": "activation", "activation_threshold": -1.0, "activation_clock": "episodes"}, False),
    ({"policy": "activation", "activation_threshold": -1.0, "activation_clock": "words"}, False),
    ({"policy": "episodes"}, False),
    ({"policy": "displacement", "capacity": 2}, False),
])
def test_clock_driven_tells_whether_catching_up_can_forget(settings, driven):
    manager = WMManager()
    manager.manage(WMBuffer("d"), ForgettingPolicy.from_settings(settings), 0.0)
    assert manager.clock_driven is driven
    manager.manage(WMBuffer("e"), ForgettingPolicy.from_settings({"policy": "decay", "decay_period": 5.0}), 0.0)
    assert manager.clock_driven is True


def test_an_episode_boundary_keeps_the_count_of_an_entry_not_used_since_and_restarts_one_that_came_back():
    wm = WMBuffer("d")
    wm.begin_episode("r")
    wm.encode("r", ["a", "b"], "speaker", 0.0)
    wm.begin_episode("r")
    wm.encode("r", ["a"], "speaker", 1.0)
    wm.begin_episode("r")
    wm.begin_episode("r")  # a used in episodes 1 and 2, b in 1; neither since
    assert [(s.age, s.episodes) for s in wm.strength("r")] == [(3, 1), (2, 2)]
    wm.remove("r", "a", "retract", 2.0)
    wm.encode("r", ["a"], "speaker", 2.0)  # back: a new entry, used in episode 4 only
    wm.begin_episode("r")
    assert wm.queue("r") == ("b", "a")
    assert [(s.age, s.episodes) for s in wm.strength("r")] == [(4, 1), (1, 1)]
    assert wm.export_episodes()["r"]["counts"] == {"b": 1, "a": 1}
