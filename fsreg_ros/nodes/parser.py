"""``parser``: a stub of DIARC's TLDL parser, English text -> properties.

Subscribes ``dialogue/human`` (:class:`~fsreg_ros.contract.HumanUtterance`: text or a
property list) and publishes the semantics on ``dialogue/semantics`` for reference
resolution (:class:`~fsreg_ros.contract.Semantics`, with the utterance's fingerprint as
``request``).  Text is mapped to
properties with the lexicon (:mod:`fsreg_ros.core.lexicon`), restricted to the
properties of the knowledge base given as ``kb`` (every lexicon property if
empty).  Text with no known property is forwarded with an empty description, so
reference resolution answers ``no-match``.  A malformed message gets a warning and
an error result on ``rr/result``, the human channel's reply topic.  Size limits: the
``max_*`` parameters (:class:`~fsreg_ros.contract.Limits`); an utterance whose reading
would be over ``max_message_bytes`` on ``dialogue/semantics`` (it carries the text and its
unknown words: up to twice the utterance) is refused as ``too-large`` here, in one line,
not by reference resolution with a size naming no topic.
"""

from __future__ import annotations

from typing import Optional

from rclpy.node import Node

from ..ros.clock_parameter import fix_use_sim_time
from .. import contract
from ..contract.codec import TooLarge
from ..ros.carrier import message_bytes, publish, publisher, subscribe
from ..contract import fingerprint
from ..core.lexicon import Lexicon
from ..core.scenario import load_scenario
from ..ros.asking import declare_limits
from ..ros.node_base import descriptor, run_node, watch_clock
from .reference_resolution import rr_error


class ParserNode(Node):
    """Text -> property list, as the TLDL parser would hand semantics to RR."""

    def __init__(self, node_name: str = "parser", *, namespace: Optional[str] = None, **kwargs) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        fix_use_sim_time(self)  # one clock for the whole graph
        self.declare_parameter(
            "kb", "",
            descriptor("scenario/KB YAML whose properties may be parsed ('' = all in lexicon)", read_only=True),
        )
        self.declare_parameter(
            "lexicon", "", descriptor("lexicon YAML ('' = the package's config/lexicon.yaml)", read_only=True)
        )
        self.limits = declare_limits(self)
        self.lexicon = Lexicon.load(self.get_parameter("lexicon").value or None)
        kb = self.get_parameter("kb").value
        known = load_scenario(kb, self.lexicon).properties() if kb else self.lexicon.properties()
        self.properties: set[str] = set(known)
        self._semantics = publisher(self, contract.SEMANTICS)
        self._errors = publisher(self, contract.RR_RESULT)
        subscribe(self, contract.HUMAN, self._on_human, reject=self._reject, limits=self.limits)
        self._clock_watch = watch_clock(self)
        self.get_logger().info(f"parser ready for {len(self.properties)} properties")

    def _reject(self, request_id, error: str, kind: str = "bad-request") -> None:
        publish(self._errors, rr_error(request_id, error, kind))

    def _on_human(self, data: dict) -> None:
        semantics = self.parse(data)
        size, limit = message_bytes(self._semantics, semantics), self.limits.max_message_bytes
        if size > limit:
            raise TooLarge(f"{contract.HUMAN.name}: its reading on {contract.SEMANTICS.name} (the text and its "
                           f"{len(semantics.get('unknown_words') or ())} unknown words) would be {size} bytes, over "
                           f"the limit of {limit} (max_message_bytes); say less at once")
        publish(self._semantics, semantics)

    def parse(self, data: dict) -> dict:
        """Return the semantics message for one (validated) human utterance.

        It carries the utterance's ``id``, ``time``, ``turn`` and ``client``, and its
        fingerprint as ``request``, which reference resolution's answer echoes.
        """
        out = {key: data[key] for key in ("id", "time", "turn", "client") if key in data}
        out["request"] = fingerprint(data)
        if data.get("domain") is not None:
            out["domain"] = data["domain"]
        if data.get("description") is not None:
            out["description"] = data["description"]
            return out
        parsed = self.lexicon.parse(data["text"], self.properties)
        out.update(description=parsed.properties, text=data["text"], unknown_words=parsed.unknown_words)
        return out


def main(args=None) -> int:
    return run_node(ParserNode, args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
