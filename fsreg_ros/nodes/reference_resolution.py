"""``reference_resolution``: which entity did the human mean?  (SPEC section 3)

Subscribes ``/dialogue/semantics`` (from the parser) and publishes ``/rr/result``
``{"id", "time", "status", "resolved", "candidates", "description", "domain"}``
(plus ``text`` and ``unknown_words`` when the utterance was text).  It runs the
core's :func:`~fsreg_ros.core.resolution.resolve` against the consultants over
the graph, so RR's affirmations are encoded in the consultants' WM (rule 2) and a
resolved description is encoded for its referent (rule 1).  Errors (unknown
property, domain not determined, a consultant not answering) are published as
``{"id", "status": "error", "error"}`` with a logged warning.
"""

from __future__ import annotations

from std_msgs.msg import String

from ..carrier import CarrierError, MessageError, from_msg, to_msg
from ..core.resolution import NO_MATCH, ResolutionError, resolve
from .asking import AskingNode
from .common import error_reply, run_node


class ReferenceResolutionNode(AskingNode):
    """RR as a thin adapter over the core algorithm."""

    def __init__(self, **kwargs) -> None:
        super().__init__("reference_resolution", **kwargs)
        self._results = self.create_publisher(String, "/rr/result", 100)
        self.create_subscription(
            String, "/dialogue/semantics", self._on_semantics, 100, callback_group=self.request_group
        )
        self.get_logger().info(f"reference resolution over domains {sorted(self.ports)}")

    async def _on_semantics(self, msg: String) -> None:
        try:
            data = from_msg(msg, {"id": (str, int), "description": list})
        except MessageError as err:
            self.get_logger().warning(f"/dialogue/semantics: {err}")
            self._results.publish(to_msg({**error_reply(msg, str(err)), "status": "error"}))
            return
        await self.answer_once(data, self._results)

    async def answer(self, data: dict) -> dict:
        """The ``/rr/result`` for one utterance's semantics."""
        time = self.request_time(data)
        out = {"id": data["id"], "time": time}
        for key in ("text", "unknown_words"):
            if key in data:
                out[key] = data[key]
        description = data["description"]
        try:
            if not all(isinstance(p, str) for p in description):
                raise MessageError("'description' must be a list of property names")
            domain = data.get("domain")
            if domain is not None and not isinstance(domain, str):
                raise MessageError("'domain' must be a string")
            if not description:  # the parser found no known property in the text
                out.update(status=NO_MATCH, resolved=None, candidates=[], description=[], domain=domain)
                return out
            await self.ensure_ready()
            result = await resolve(description, self.ports, domain=domain, time=time, turn=data.get("turn"))
        except (MessageError, ResolutionError, CarrierError) as err:
            self.get_logger().warning(f"utterance {data['id']!r}: {err}")
            out.update(status="error", error=str(err), resolved=None, candidates=[], description=list(description))
            return out
        out.update(result.to_json())
        return out


def main(args=None) -> int:
    return run_node(ReferenceResolutionNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
