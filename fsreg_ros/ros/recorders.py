"""Which recorders hear a graph, and a sender reaching them before it publishes (issue 38.4).

A writer sends a message to the readers it has matched when it writes; a short-lived
sender (``fsreg-ctl``) often publishes before it has even discovered a recorder's
participant, and it cannot wait for a recorder it does not know exists.  The WM Manager
lives as long as the graph and so has discovered every recorder: it names them in
``wm_manager/ready`` (``recorders``: :func:`recorders_of`, the recorder nodes among the
discovered readers of ``dialogue/human``; a recorder that stops leaves the list when its
node goes, one killed when DDS expires its participant), which every client already
waits for.  Before a client publishes on a recorded topic, :class:`RecorderReach` waits
(at most :data:`RECORDER_WAIT` s per recorder, once per command) until its writer has
matched every reader of that topic it discovered and the named recorders are among
them (:data:`RECORDER_WAIT` s for a recorder not discovered at all, longer,
:data:`RECORDER_MATCH_WAIT`, once its reader is seen: it is alive and only the match is
under way); a recorder not reached in time is not waited for again, and the client reports it
(:meth:`RecorderReach.unheard`: one line), never silently.

A recorder is recognised by its readers' node name (:data:`SUFFIX`, given by
:class:`fsreg_ros.ros.recorder.Recorder`).
"""

from __future__ import annotations

import time
from typing import Optional

from .. import contract

#: The end of a recorder's readers node name (``<node>_recorder``).
SUFFIX = "_recorder"
#: Seconds at most a client waits for a named recorder it has not discovered at all (discovery on this
#: machine takes 0.1-2.5 s, more under load; the wait ends as soon as it matched).  A recorder that was
#: killed is never discovered by a new client (it announces nothing), so this is what such a one costs
#: each command until DDS expires it in the WM Manager (~20 s).
RECORDER_WAIT = 5.0
#: Seconds at most a client waits for a recorder whose reader of the topic it has discovered (alive:
#: only the match is still under way, which a loaded machine can take seconds to complete).
RECORDER_MATCH_WAIT = 15.0


def full_name(namespace: str, name: str) -> str:
    """Return a node's fully-qualified name."""
    return f"{namespace.rstrip('/')}/{name}"


def recorders_of(node) -> list[str]:
    """Return the fully-qualified names of the recorders ``node`` has discovered reading its ``dialogue/human``."""
    topic = node.resolve_topic_name(contract.HUMAN.name)
    return sorted({full_name(i.node_namespace, i.node_name) for i in node.get_subscriptions_info_by_topic(topic)
                   if i.node_name.endswith(SUFFIX)})


def missing(node, writer, recorders: list[str]) -> tuple[list[str], bool]:
    """Return those of ``recorders`` that ``writer`` (of ``node``) may not have matched yet, and whether all are seen.

    Matched: the recorder's reader of the writer's topic is discovered, and the writer has
    matched as many readers as were discovered (a writer reports a count, not which).
    Seen: every one of ``recorders`` has a reader of the topic that ``node`` discovered.
    """
    readers = node.get_subscriptions_info_by_topic(writer.topic_name)
    seen = {full_name(i.node_namespace, i.node_name) for i in readers}
    unseen = [r for r in recorders if r not in seen]
    if writer.get_subscription_count() < len(readers):
        return list(recorders), not unseen
    return unseen, not unseen


class RecorderReach:
    """Reach the graph's recorders before publishing (a part of ``GraphClient``; see the module docstring).

    Uses the client's ``node``, ``readiness()`` (the recorders its WM Manager names),
    ``recorder_wait``, ``_unheard`` (recorder -> topics it was not reached on) and ``_reached``
    ((recorder, topic) pairs matched already).
    """

    def reach_recorders(self, writer) -> None:
        """Wait until ``writer`` matched every recorder the graph names (bounded; a recorder missed is noted)."""
        ready = self.readiness() or {}
        topic = writer.topic_name
        waiting = [r for r in ready.get("recorders") or ()
                   if r not in self._unheard and (r, topic) not in self._reached]
        start = time.monotonic()
        left, seen = missing(self.node, writer, waiting) if waiting else ([], True)
        while left and time.monotonic() - start < (max(self.recorder_wait, RECORDER_MATCH_WAIT) if seen
                                                   else self.recorder_wait):
            time.sleep(0.01)
            left, seen = missing(self.node, writer, left)
        for r in waiting:
            if r in left:
                self._unheard.setdefault(r, []).append(topic)
            else:
                self._reached.add((r, topic))  # a match stays: a stream's later messages ask nothing

    def unheard(self) -> Optional[str]:
        """Return one line naming the recorders not reached before a message was sent (None: all were)."""
        if not self._unheard:
            return None
        names = ", ".join(sorted(self._unheard))
        topics = ", ".join(sorted({t for ts in self._unheard.values() for t in ts}))
        return (f"recorder {names} (named by the graph's WM Manager) did not match this command's writer of "
                f"{topics} within {self.recorder_wait:g} s: the recording may lack what it sent there")
