"""``reference_resolution``: find the entity the human meant (docs/semantics.md section 3).

Subscribes ``dialogue/semantics`` (from the parser) and publishes ``rr/result``
(schemas :class:`~fsreg_ros.contract.Semantics`, :class:`~fsreg_ros.contract.RRResult`;
``text`` and ``unknown_words`` are passed on when the utterance was text; the answer's
``request`` is the fingerprint of the utterance the parser read).  It runs the
core's :func:`~fsreg_ros.core.algorithms.resolution.resolve` against the consultants over
the graph, so RR's affirmations are encoded in the consultants' WM (rule 2) and a
resolved description is encoded for its referent (rule 1).  Errors (unknown
property, domain not determined, a consultant not answering) are published as
``{"id", "status": "error", "error"}`` with a logged warning.
"""

from __future__ import annotations

from typing import Optional

from .. import contract
from ..ros.carrier import CarrierError, publish, publisher, reply_kind, subscribe
from ..contract.codec import printable
from ..core.algorithms.resolution import NO_MATCH, resolve
from ..ros.asking import AskingNode
from ..ros.node_base import run_node


class ReferenceResolutionNode(AskingNode):
    """RR as a thin adapter over the core algorithm."""

    def __init__(self, node_name: str = "reference_resolution", *, namespace: Optional[str] = None, **kwargs) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        self._results = publisher(self, contract.RR_RESULT)
        subscribe(self, contract.SEMANTICS, self.answer_once_on(self._results), reject=self._reject,
                  callback_group=self.request_group, limits=self.limits)
        self.get_logger().info(f"reference resolution over domains {sorted(self.ports)}")

    def _reject(self, request_id, error: str, kind: str = "bad-request") -> None:
        publish(self._results, rr_error(request_id, error, kind))

    def fingerprint(self, data: dict) -> str:
        """Return the fingerprint of the utterance the parser read (``request``), else of the semantics message."""
        given = data.get("request")
        return given if isinstance(given, str) else super().fingerprint(data)

    def error_fields(self, data: dict) -> dict:
        return {"status": "error"}

    async def answer(self, data: dict) -> dict:
        """Return the ``rr/result`` for one utterance's semantics."""
        time = self.request_time(data)
        out = {"id": data["id"], "time": time}
        for key in ("text", "unknown_words"):
            if key in data:
                out[key] = data[key]
        description = data["description"]
        domain = data.get("domain")
        try:
            if not description:  # the parser found no known property in the text
                out.update(status=NO_MATCH, resolved=None, candidates=[], description=[], domain=domain)
                return out
            await self.ensure_ready()
            result = await resolve(description, self.ports, domain=domain, time=time, turn=data.get("turn"))
        except (ValueError, CarrierError) as err:  # ResolutionError, KnowledgeError, MessageError
            self.get_logger().warning(printable(f"{contract.SEMANTICS.name} (id {data['id']!r}): {err}"))
            out.update(status="error", error=str(err), kind=reply_kind(err), resolved=None, candidates=[],
                       description=list(description))
            return out
        out.update(result.to_json())
        return out


def rr_error(request_id, error: str, kind: str = "bad-request") -> dict:
    """Return the ``rr/result`` for an utterance that could not be read (no resolution ran)."""
    reply = {"status": "error", "error": error, "kind": kind, "resolved": None, "candidates": []}
    if request_id is not None:
        reply["id"] = request_id
    return reply


def main(args=None) -> int:
    return run_node(ReferenceResolutionNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
