"""The fsreg message contract: every topic and service, its QoS and its JSON schema.

This package is the one owner of the wire contract (docs/semantics.md §7).  Nodes, the
remote consultant port, the graph runner and the tests take names, QoS profiles and
schemas from here; ``docs/design.md`` lists them (a test checks the table against
:func:`message_table`), and ``scripts/export_schemas.py`` writes their JSON Schemas.
It imports no ROS package, so a tool that only needs names or schemas stays ROS-free.

One module per job:

* schemas (pydantic models): :mod:`.base` (``Message``, ``ErrorReply``, ``Stamp``, the
  shared field types ``Number``, ``Count``, ``Name``, ``Names``), :mod:`.dialogue` (the dialogue
  pipeline), :mod:`.wm` (``wm/state``, ``wm/events``), :mod:`.ltm` (``ltm/assert``),
  :mod:`.consultant` (a consultant's announcement, query ops and manage ops),
  :mod:`.manager` (the WM Manager's services), :mod:`.policy` (a forgetting policy,
  generated from the memory settings table);
* :mod:`.codec`: the wire codec, one JSON object per ``std_msgs/String`` (bounded
  decoding, encoding that refuses what is not JSON, error replies that never raise);
* :mod:`.consultant_codec`: the consultant protocol's codec (pure functions): each op's
  request and reply encoded and decoded, for the consultant's side and its callers';
* :mod:`.attribution`: request fingerprints, so every answer names its request;
* :mod:`.qos`: QoS profiles as plain data (``fsreg_ros.ros.carrier.qos_profile`` makes the
  rclpy profile);
* :mod:`.endpoints`: the registry of topics and services (relative names, who talks), and
  :func:`graph_topics`, every topic of one graph with its type and QoS (what a recorder subscribes to);
* :mod:`.naming`: namespaces and the per-graph ``/clock`` remapping;
* :mod:`.limits`: bounds on what a node accepts;
* :mod:`.checking`: a decoded message against its schema, with one-line errors;
* :mod:`.export`: JSON Schemas and the docs' message table.

Names are **relative** (``rr/result``, ``consultant/faces``): a node started with
``--ros-args -r __ns:=/robot1`` (or ``fsreg-graph --namespace robot1``) uses
``/robot1/rr/result``, so two graphs in different namespaces share a ROS domain without
hearing each other.  ``/clock`` is the one absolute name (the ROS convention): a
namespaced *sim-time* graph is given its own clock by remapping it (:func:`clock_remap`).
"""

from .attribution import attribution, cache_key, fingerprint, reference_id
from .base import ErrorReply, Id, Message, Name, NameNumbers, Names, Number, RequestRef, Stamp
from .checking import check
from .consultant import (
    CONSULTANT_OPS,
    DEBUG_OPS,
    MANAGE_OPS,
    AffirmRequest,
    CloseReply,
    CloseRequest,
    ConfigureReply,
    ConfigureRequest,
    ConsultantAnnounce,
    ConsultantReply,
    ConsultantRequest,
    DebugReply,
    DebugRequest,
    AdvanceReply,
    AdvanceRequest,
    DecayReply,
    DecayRequest,
    EncodeReply,
    EncodeRequest,
    EvictReply,
    EvictRequest,
    HoldsReply,
    HoldsRequest,
    InfoReply,
    InfoRequest,
    ManageReply,
    ManageRequest,
    NarrowReply,
    NarrowRequest,
    Narrowing,
    OpenReply,
    OpenRequest,
    QueueReply,
    ResetReply,
    ResetRequest,
    RestoredState,
    RuleOutReply,
    RuleOutRequest,
    SizeReply,
    SizeRequest,
    SnapshotReply,
    SnapshotRequest,
    StepRequest,
    StoredState,
    Versioned,
    WalkReply,
    WalkRequest,
    WalkStepRequest,
    WMRequest,
    version_incarnation,
)
from .dialogue import HumanUtterance, RegExpression, RegError, RegRequest, Request, RRResult, Semantics
from .endpoints import (
    ALIVE,
    ANNOUNCE,
    CLOCK,
    CONSULTANT,
    DEBUG,
    HUMAN,
    LTM_ASSERT,
    LTM_ASSERT_RESULT,
    MANAGE,
    REG_EXPRESSION,
    REG_REQUEST,
    RR_RESULT,
    SEMANTICS,
    SERVICES,
    STATUS,
    SYNC,
    TOPICS,
    READY,
    WM_EVENTS,
    WM_STATE,
    CLOCK_TYPE,
    STRING_TYPE,
    GraphTopic,
    Service,
    Topic,
    alive_topic,
    consultant_service,
    debug_service,
    graph_topics,
    manage_service,
)
from .export import fields_of, json_schemas, message_table
from .limits import LIMIT_RANGES, Limits
from .ltm import LtmAssert, LtmAssertResult, LtmFact, LtmFactResult
from .manager import DomainReadiness, ManagerReady, StatusReply, StatusRequest, SyncReply, SyncRequest
from .naming import GRAPH_FIELD, GRAPH_PARAMETER, clock_remap, normalise_namespace
from .policy import PolicySettings
from .qos import (ALIVE_QOS, ASSERT_QOS, ASSERT_RESULT_QOS, DEFAULT_QOS, EVENTS_QOS, PIPELINE_QOS, READY_QOS,
                  SERVICE_QOS, STATE_PUB_QOS, STATE_QOS, QosSpec)
from .wm import Origin, WMEventMessage, WMState

__all__ = [
    "ALIVE", "ALIVE_QOS", "ANNOUNCE", "ASSERT_QOS", "ASSERT_RESULT_QOS", "CLOCK", "CONSULTANT", "CONSULTANT_OPS",
    "DEBUG", "DEBUG_OPS", "DEFAULT_QOS",
    "EVENTS_QOS", "HUMAN", "LIMIT_RANGES", "LTM_ASSERT", "LTM_ASSERT_RESULT", "MANAGE", "MANAGE_OPS",
    "PIPELINE_QOS", "READY_QOS", "REG_EXPRESSION", "REG_REQUEST", "RR_RESULT", "SEMANTICS", "SERVICES", "SERVICE_QOS",
    "STATE_PUB_QOS", "STATE_QOS", "STATUS", "SYNC", "TOPICS", "WM_EVENTS", "WM_STATE", "AffirmRequest",
    "CloseReply", "CloseRequest", "ConfigureReply", "ConfigureRequest", "ConsultantAnnounce", "ConsultantReply",
    "ConsultantRequest", "DebugReply", "DebugRequest", "DecayReply", "DecayRequest", "AdvanceReply", "AdvanceRequest",
    "EncodeReply", "EncodeRequest",
    "ErrorReply", "EvictReply", "EvictRequest", "HoldsReply", "HoldsRequest", "HumanUtterance", "Id", "InfoReply",
    "InfoRequest", "Limits", "LtmAssert", "LtmAssertResult", "LtmFact", "LtmFactResult", "ManageReply",
    "ManageRequest", "Message", "Name",
    "NameNumbers", "Names", "NarrowReply", "NarrowRequest", "Narrowing", "Number", "OpenReply", "OpenRequest",
    "Origin", "PolicySettings", "QosSpec", "QueueReply", "RRResult", "RegError", "RegExpression", "RegRequest",
    "Request", "RequestRef", "ResetReply", "ResetRequest", "RestoredState", "RuleOutReply", "RuleOutRequest",
    "Semantics", "Service", "SizeReply", "SizeRequest",
    "SnapshotReply", "SnapshotRequest", "Stamp", "StatusReply", "StatusRequest", "StepRequest", "StoredState",
    "SyncReply", "SyncRequest", "Topic", "Versioned", "WMEventMessage", "WMRequest", "WMState",
    "alive_topic", "attribution", "cache_key", "check", "clock_remap", "consultant_service",
    "debug_service", "fields_of", "fingerprint", "json_schemas", "manage_service", "message_table",
    "normalise_namespace", "reference_id", "version_incarnation", "WalkReply", "WalkRequest", "WalkStepRequest",
    "GRAPH_FIELD", "GRAPH_PARAMETER", "READY", "DomainReadiness", "ManagerReady",  # graph identity and readiness
    "CLOCK_TYPE", "STRING_TYPE", "GraphTopic", "graph_topics",  # every topic of a graph, as a recorder sees it
]
