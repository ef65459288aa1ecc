"""``reg``: referring expression generation + realisation (docs/semantics.md section 4).

Subscribes ``reg/request`` and publishes ``reg/expression`` (schemas
:class:`~fsreg_ros.contract.RegRequest`, :class:`~fsreg_ros.contract.RegExpression`).
The core's generation coroutine asks the target's
consultant over the graph, so REG's affirmations for distractors (rule 3) and
the final description (rule 1) are encoded in that consultant's WM.

Parameters: ``algorithm`` (``auto`` = SD-PIA, or DIST-PIA for a domain whose
policy is ``none``; or one of sd-pia, dist-pia, full-brevity, greedy),
``wm_order`` (lru-first, mru-first, preference, strength), ``lexicon`` (path, '' = default), and
the limits and timeouts of :class:`~fsreg_ros.ros.asking.AskingNode`.  Bad requests
get ``{"id", "error"}`` on ``reg/expression`` and a logged warning.
"""

from __future__ import annotations

from typing import Optional

from rcl_interfaces.msg import SetParametersResult

from .. import contract
from ..ros.carrier import CarrierError, publish, publisher, reply_kind, subscribe
from ..contract.codec import printable
from ..core.algorithms.generation import ALGORITHMS, AUTO, WM_ORDERS, GenerationError, generate
from ..core.lexicon import Lexicon
from ..ros.asking import AskingNode
from ..ros.node_base import descriptor, run_node


class RegNode(AskingNode):
    """SD-PIA / DIST-PIA (and baselines) as a thin adapter over the core."""

    def __init__(self, node_name: str = "reg", *, namespace: Optional[str] = None, **kwargs) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        self.declare_parameter(
            "algorithm", AUTO,
            descriptor(f"{AUTO} (sd-pia, dist-pia under policy none) or one of {', '.join(ALGORITHMS)}"),
        )
        self.declare_parameter("wm_order", "lru-first", descriptor(f"order SD-PIA walks WM in: {', '.join(WM_ORDERS)}"))
        self.declare_parameter("lexicon", "", descriptor("lexicon YAML ('' = package default)", read_only=True))
        problem = self._check(self.get_parameter("algorithm").value, self.get_parameter("wm_order").value)
        if problem:
            raise ValueError(problem)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.lexicon = Lexicon.load(self.get_parameter("lexicon").value or None)
        self._expressions = publisher(self, contract.REG_EXPRESSION)
        subscribe(self, contract.REG_REQUEST, self.answer_once_on(self._expressions), reject=self._reject,
                  callback_group=self.request_group, limits=self.limits)
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
            if param.name in values:
                values[param.name] = param.value
        problem = self._check(values["algorithm"], values["wm_order"])
        return SetParametersResult(successful=not problem, reason=problem)

    def _reject(self, request_id, error: str, kind: str = "bad-request") -> None:
        reply = {"error": error, "kind": kind}
        if request_id is not None:
            reply["id"] = request_id
        publish(self._expressions, reply)

    async def answer(self, data: dict) -> dict:
        """Return the ``reg/expression`` for one request."""
        time = self.request_time(data)
        out = {"id": data["id"], "target": data["target"], "time": time}
        try:
            await self.ensure_ready()
            domain = await self._domain_of(data["target"])
            port = self.ports[domain]
            expression = await generate(  # "auto" is decided by the domain's policy when REG opens its view
                data["target"],
                port,
                self.get_parameter("algorithm").value,
                context=data.get("context"),
                wm_order=self.get_parameter("wm_order").value,
                time=time,
                turn=data.get("turn"),
                reference=contract.reference_id(data, port.client_id),  # a resent request: no second episode
            )
        except (ValueError, CarrierError) as err:  # GenerationError, KnowledgeError, MessageError
            self.get_logger().warning(printable(f"{contract.REG_REQUEST.name} (id {data['id']!r}): {err}"))
            out["error"] = str(err)
            out["kind"] = reply_kind(err)
            return out
        expression.text = self.lexicon.realise(expression.description, domain)
        out.update(expression.to_json())
        return out

    async def _domain_of(self, target: str) -> str:
        """Return the domain whose consultant knows ``target``.

        From the ports' cached entity lists (an entity never leaves its domain); only a
        target no cache knows makes every consultant say which entities it added since.
        """
        for refresh in (False, True):
            for domain, port in self.ports.items():
                if await port.knows(target, refresh):
                    return domain
        raise GenerationError(f"no consultant knows entity '{target}' (domains: {', '.join(sorted(self.ports))})",
                              kind="unknown-entity")


def main(args=None) -> int:
    return run_node(RegNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
