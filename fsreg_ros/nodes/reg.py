"""``reg``: referring expression generation + realisation (SPEC section 4).

Subscribes ``/reg/request`` ``{"id", "target", "context"?, "time"?, "turn"?}`` and
publishes ``/reg/expression`` ``{"id", "target", "description", "sources",
"distinguishing", "distractors_left", "text", "wm_before", "domain",
"algorithm", "time"}``.  The core's generation coroutine asks the target's
consultant over the graph, so REG's affirmations for distractors (rule 3) and
the final description (rule 1) are encoded in that consultant's WM.

Parameters: ``algorithm`` (``auto`` = SD-PIA, or DIST-PIA for a domain whose
policy is ``none``; or one of sd-pia, dist-pia, full-brevity, greedy),
``wm_order`` (lru-first, mru-first, preference), ``lexicon`` (path, '' = default).
Bad requests get ``{"id", "error"}`` on ``/reg/expression`` and a logged warning.
"""

from __future__ import annotations

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from std_msgs.msg import String

from ..carrier import CarrierError, MessageError, from_msg, to_msg
from ..core.generation import ALGORITHMS, WM_ORDERS, GenerationError, generate
from ..core.lexicon import Lexicon, LexiconError
from .asking import AskingNode
from .common import error_reply, run_node

AUTO = "auto"


class RegNode(AskingNode):
    """SD-PIA / DIST-PIA (and baselines) as a thin adapter over the core."""

    def __init__(self, **kwargs) -> None:
        super().__init__("reg", **kwargs)
        self.declare_parameter(
            "algorithm",
            AUTO,
            ParameterDescriptor(description=f"{AUTO} (sd-pia, dist-pia under policy none) or one of {', '.join(ALGORITHMS)}"),
        )
        self.declare_parameter(
            "wm_order", "lru-first", ParameterDescriptor(description=f"order SD-PIA walks WM in: {', '.join(WM_ORDERS)}")
        )
        self.declare_parameter(
            "lexicon", "", ParameterDescriptor(description="lexicon YAML ('' = package default)", read_only=True)
        )
        problem = self._check(self.get_parameter("algorithm").value, self.get_parameter("wm_order").value)
        if problem:
            raise ValueError(problem)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.lexicon = Lexicon.load(self.get_parameter("lexicon").value or None)
        self._expressions = self.create_publisher(String, "/reg/expression", 100)
        self.create_subscription(String, "/reg/request", self._on_request, 100, callback_group=self.request_group)
        self.get_logger().info(f"REG over domains {sorted(self.ports)}")

    @staticmethod
    def _check(algorithm: object, wm_order: object) -> str:
        if algorithm != AUTO and algorithm not in ALGORITHMS:
            return f"algorithm must be {AUTO} or one of {', '.join(ALGORITHMS)}, got {algorithm!r}"
        if wm_order not in WM_ORDERS:
            return f"wm_order must be one of {', '.join(WM_ORDERS)}, got {wm_order!r}"
        return ""

    def _on_set_parameters(self, params) -> SetParametersResult:
        values = {"algorithm": self.get_parameter("algorithm").value, "wm_order": self.get_parameter("wm_order").value}
        for param in params:
            if param.name == "lexicon":
                return SetParametersResult(successful=False, reason="'lexicon' is read-only; restart the node")
            if param.name in values:
                values[param.name] = param.value
        problem = self._check(values["algorithm"], values["wm_order"])
        return SetParametersResult(successful=not problem, reason=problem)

    async def _on_request(self, msg: String) -> None:
        try:
            data = from_msg(msg, {"id": (str, int), "target": str})
        except MessageError as err:
            self.get_logger().warning(f"/reg/request: {err}")
            self._expressions.publish(to_msg(error_reply(msg, str(err))))
            return
        await self.answer_once(data, self._expressions)

    async def answer(self, data: dict) -> dict:
        """The ``/reg/expression`` for one request."""
        time = self.request_time(data)
        out = {"id": data["id"], "target": data["target"], "time": time}
        try:
            context = data.get("context")
            if context is not None and (not isinstance(context, list) or not all(isinstance(e, str) for e in context)):
                raise MessageError("'context' must be a list of entity names")
            await self.ensure_ready()
            domain, policy = await self._domain_of(data["target"])
            algorithm = self.get_parameter("algorithm").value
            if algorithm == AUTO:
                algorithm = "dist-pia" if policy == "none" else "sd-pia"
            expression = await generate(
                data["target"],
                self.ports[domain],
                algorithm,
                context=context,
                wm_order=self.get_parameter("wm_order").value,
                time=time,
                turn=data.get("turn"),
            )
        except (MessageError, GenerationError, CarrierError) as err:
            self.get_logger().warning(f"request {data['id']!r}: {err}")
            out["error"] = str(err)
            return out
        expression.text = self.lexicon.realise(expression.description, domain)
        out.update(expression.to_json())
        return out

    async def _domain_of(self, target: str) -> tuple[str, str]:
        """The domain whose consultant knows ``target``, and that domain's policy name."""
        for domain, port in self.ports.items():
            info = await port.info()
            if target in info["entities"]:
                return domain, info.get("policy", "none")
        raise GenerationError(f"no consultant knows entity '{target}' (domains: {', '.join(sorted(self.ports))})")


def main(args=None) -> int:
    return run_node(RegNode, args, startup_errors=(LexiconError, ValueError))


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
