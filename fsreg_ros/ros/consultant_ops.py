"""The consultant's side of its protocol: one validated request decoded, run on the core service, its reply encoded.

:func:`apply` is what the consultant node does with each request its carrier validated
against the contract's schemas: the op's request is decoded by the codec
(:data:`fsreg_ros.contract.consultant_codec.SERVED`), run as the op's typed call
(:mod:`fsreg_ros.core.consultant.ops`: sessions, request times, clock notes) inside one
:meth:`~fsreg_ros.core.consultant.service.ConsultantService.run` (its changes written once, its
events numbered), and its result encoded, with the ``queues_changed`` and ``version`` its
reply carries (:func:`~fsreg_ros.contract.consultant_codec.completed`).  ROS-free: the tests and
``scripts/bench_store.py`` call it in-process.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

from ..contract import consultant_codec as codec
from ..core.consultant import ops
from ..core.consultant.service import ConsultantService, Outcome, RequestError

#: The typed call each op the service serves runs (``reset`` is the node's: it replaces the service).
CALLS: dict[str, Callable[..., Any]] = {
    "info": ops.info, "open": ops.open_session, "narrow": ops.narrow, "walk": ops.walk,
    "rule_out": ops.rule_out, "close": ops.close_session,
    "holds": ops.holds, "affirm": ops.affirm, "wm": ops.queue, "encode": ops.encode, "snapshot": ops.snapshot,
    "configure": ops.configure, "decay": ops.decay, "advance": ops.advance, "evict": ops.evict, "size": ops.size,
}


def apply(service: ConsultantService, op: str, request: Mapping[str, Any], listening: bool = False) -> Outcome:
    """Run one op of the consultant protocol on ``service``; return its :class:`~.service.Outcome`.

    ``request`` is validated by the op's schema (the carrier checked it); ``listening``
    whether anyone hears the events.  Raises KnowledgeError, PolicyError, RequestError,
    NotReady or SessionError, having changed nothing, for a request it refuses.
    """
    call = CALLS.get(op)
    if call is None:
        raise RequestError(f"unknown op {op!r}")
    decode, encode = codec.SERVED[op]
    if op not in codec.UNGUARDED_OPS:
        service.require_ready()
    counted = op in codec.COUNTED_OPS
    outcome = service.run(lambda: encode(call(service, *decode(request))), listening, counted)
    codec.completed(op, outcome.reply, len(outcome.changes.queues), service.version)
    return outcome
