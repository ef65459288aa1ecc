"""Every topic and service of the graph: relative name, schema, QoS, who talks (the registry).

Names are **relative** (``rr/result``, ``consultant/faces``): a node started with
``--ros-args -r __ns:=/robot1`` uses ``/robot1/rr/result``.  ``/clock`` is the one
absolute name (see :mod:`fsreg_ros.contract.naming`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Optional, Union

from .base import ErrorReply
from .consultant import (
    ConsultantAnnounce,
    ConsultantReply,
    ConsultantRequest,
    DebugReply,
    DebugRequest,
    ManageReply,
    ManageRequest,
)
from .dialogue import HumanUtterance, RegExpression, RegError, RegRequest, RRResult, Semantics
from .ltm import LtmAssert, LtmAssertResult
from .manager import ManagerReady, StatusReply, StatusRequest, SyncReply, SyncRequest
from .naming import CLOCK, normalise_namespace  # CLOCK: re-exported with the endpoints; naming owns it
from .qos import (ALIVE_QOS, ASSERT_QOS, ASSERT_RESULT_QOS, EVENTS_QOS, PIPELINE_QOS, READY_QOS, STATE_PUB_QOS,
                  STATE_QOS, QosSpec)
from .wm import WMEventMessage, WMState


@dataclass(frozen=True)
class Topic:
    """One topic: relative name, JSON schema of ``String.data``, QoS, who talks."""

    name: str
    schema: Any
    qos: QosSpec
    publishers: str
    subscribers: str
    reader_qos: Optional[QosSpec] = None
    #: The topic its messages are answered on (a refusal included); None: no answer by contract.
    answered_on: Optional[str] = None

    @property
    def subscriber_qos(self) -> QosSpec:
        return self.reader_qos if self.reader_qos is not None else self.qos


@dataclass(frozen=True)
class Service:
    """One JSON service: relative name (``<domain>`` filled in per consultant), schemas."""

    name: str
    request: Any
    reply: Any
    server: str
    clients: str


HUMAN = Topic("dialogue/human", HumanUtterance, PIPELINE_QOS, "the robot's speech input", "parser",
              answered_on="rr/result")
SEMANTICS = Topic("dialogue/semantics", Semantics, PIPELINE_QOS, "parser", "reference_resolution",
                  answered_on="rr/result")
RR_RESULT = Topic("rr/result", Union[RRResult, ErrorReply], PIPELINE_QOS, "reference_resolution, parser (errors)",
                  "dialogue manager")
REG_REQUEST = Topic("reg/request", RegRequest, PIPELINE_QOS, "dialogue manager", "reg", answered_on="reg/expression")
REG_EXPRESSION = Topic("reg/expression", Union[RegExpression, RegError], PIPELINE_QOS, "reg", "dialogue manager")
WM_STATE = Topic("wm/state", WMState, STATE_PUB_QOS, "consultants", "anyone", reader_qos=STATE_QOS)
WM_EVENTS = Topic("wm/events", WMEventMessage, EVENTS_QOS, "consultants", "dialogue_player (trace)")
ANNOUNCE = Topic("consultant/announce", ConsultantAnnounce, STATE_PUB_QOS, "consultants",
                 "wm_manager, reference_resolution, reg",
                 reader_qos=STATE_QOS)
ALIVE = Topic("consultant/<domain>/alive", ConsultantAnnounce, ALIVE_QOS, "consultant",
              "wm_manager (readiness), reference_resolution, reg")
READY = Topic("wm_manager/ready", ManagerReady, READY_QOS, "wm_manager", "reference_resolution, reg (restarts), "
              "clients (fsreg-up, fsreg-ctl, fsreg_ros.testing, dialogue_player)", reader_qos=STATE_QOS)
LTM_ASSERT = Topic("ltm/assert", LtmAssert, ASSERT_QOS, "perception, dialogue manager", "consultants",
                   answered_on="ltm/assert/result")
LTM_ASSERT_RESULT = Topic("ltm/assert/result", Union[LtmAssertResult, ErrorReply], ASSERT_RESULT_QOS, "consultants",
                          "asserter")

CONSULTANT = Service("consultant/<domain>", ConsultantRequest, ConsultantReply, "consultant",
                     "reference_resolution, reg")
MANAGE = Service("consultant/<domain>/manage", ManageRequest, ManageReply, "consultant",
                 "wm_manager (and fsreg-ctl state reset: op reset)")
DEBUG = Service("consultant/<domain>/debug", DebugRequest, DebugReply, "consultant (parameter debug)", "tests, tools")
SYNC = Service("wm_manager/sync", SyncRequest, SyncReply, "wm_manager", "dialogue_player")
STATUS = Service("wm_manager/status", StatusRequest, StatusReply, "wm_manager", "anyone")

TOPICS: tuple[Topic, ...] = (HUMAN, SEMANTICS, RR_RESULT, REG_REQUEST, REG_EXPRESSION, WM_STATE, WM_EVENTS,
                             ANNOUNCE, ALIVE, READY, LTM_ASSERT, LTM_ASSERT_RESULT)
SERVICES: tuple[Service, ...] = (CONSULTANT, MANAGE, DEBUG, SYNC, STATUS)


def consultant_service(domain: str) -> str:
    """Return the (relative) query service of a domain's consultant."""
    return CONSULTANT.name.replace("<domain>", domain)


def manage_service(domain: str) -> str:
    """Return the (relative) WM Manager service of a domain's consultant."""
    return MANAGE.name.replace("<domain>", domain)


def debug_service(domain: str) -> str:
    """Return the (relative) debug service of a domain's consultant (served only with ``debug`` true)."""
    return DEBUG.name.replace("<domain>", domain)


def alive_topic(domain: str) -> Topic:
    """Return the latched, liveliness-leased announcement topic of one domain's consultant."""
    return replace(ALIVE, name=ALIVE.name.replace("<domain>", domain))


#: Message type of every fsreg topic (one JSON object in ``data``) and of the clock, as ROS names them.
STRING_TYPE = "std_msgs/msg/String"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
#: ``/clock`` as fsreg's clients and the dialogue player publish it: reliable, volatile, depth 10.
CLOCK_QOS = QosSpec(10)
#: Topics a recording leaves out: ``consultant/<domain>/alive`` repeats the announcement 4 times a
#: second as a liveliness heartbeat (``consultant/announce`` carries the same, once per change).
NOT_RECORDED = (ALIVE,)


@dataclass(frozen=True)
class GraphTopic:
    """One topic of a graph as a subscriber sees it: full name, ROS type, the QoS its writers offer and a reader's.

    ``topic`` is the contract's entry (None for ``/clock``, which is not a JSON topic).
    """

    name: str
    msgtype: str
    qos: QosSpec
    reader_qos: QosSpec
    topic: Optional[Topic] = None


def graph_topics(namespace: str = "", clock: Optional[str] = None) -> tuple[GraphTopic, ...]:
    """Return every fsreg topic of the graph in ``namespace`` with its type and QoS, ``/clock`` last.

    Every topic of :data:`TOPICS` but the heartbeat (:data:`NOT_RECORDED`), resolved in the
    namespace, and the graph's clock: ``clock`` if given, else ``<namespace>/clock`` under a
    namespace (:func:`fsreg_ros.contract.clock_remap`) and ``/clock`` without one.  What a
    recorder or a viewer subscribes to.
    """
    ns = normalise_namespace(namespace)
    out = [GraphTopic(f"{ns}/{t.name}", STRING_TYPE, t.qos, t.subscriber_qos, t)
           for t in TOPICS if t not in NOT_RECORDED]
    clock_name = clock or f"{ns}{CLOCK}"
    out.append(GraphTopic(clock_name if clock_name.startswith("/") else "/" + clock_name, CLOCK_TYPE, CLOCK_QOS,
                          CLOCK_QOS))
    return tuple(out)
