"""``parser``: a stub of DIARC's TLDL parser, English text -> properties.

Subscribes ``/dialogue/human`` (``{"id", "time", "text"}`` or ``{"id", "time",
"description": [...]}``, optional ``"domain"``) and publishes the semantics on
``/dialogue/semantics`` for reference resolution: ``{"id", "time",
"description", "domain"?, "text"?, "unknown_words"?}``.  Text is mapped to
properties with the lexicon (:mod:`fsreg_ros.core.lexicon`), restricted to the
properties of the knowledge base given as ``kb`` (every lexicon property if
empty).  Text with no known property is forwarded with an empty description, so
reference resolution answers ``no-match``.  A malformed message gets a warning and
an error result on ``/rr/result``, the human channel's reply topic.
"""

from __future__ import annotations


from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from std_msgs.msg import String

from ..carrier import MessageError, from_msg, to_msg
from ..core.lexicon import Lexicon, LexiconError
from ..core.scenario import ScenarioError, load_scenario
from .common import error_reply, run_node


class ParserNode(Node):
    """Text -> property list, as the TLDL parser would hand semantics to RR."""

    def __init__(self, **kwargs) -> None:
        super().__init__("parser", **kwargs)
        self.declare_parameter(
            "kb",
            "",
            ParameterDescriptor(description="scenario/KB YAML whose properties may be parsed ('' = all in lexicon)", read_only=True),
        )
        self.declare_parameter(
            "lexicon",
            "",
            ParameterDescriptor(description="lexicon YAML ('' = the package's config/lexicon.yaml)", read_only=True),
        )
        self.lexicon = Lexicon.load(self.get_parameter("lexicon").value or None)
        kb = self.get_parameter("kb").value
        self.properties: set[str] = set(load_scenario(kb, self.lexicon).properties() if kb else self.lexicon.properties())
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._semantics = self.create_publisher(String, "/dialogue/semantics", 100)
        self._errors = self.create_publisher(String, "/rr/result", 100)
        self.create_subscription(String, "/dialogue/human", self._on_human, 100)
        self.get_logger().info(f"parser ready for {len(self.properties)} properties")

    def _on_set_parameters(self, params) -> SetParametersResult:
        for param in params:
            if param.name in ("kb", "lexicon"):
                return SetParametersResult(successful=False, reason=f"'{param.name}' is read-only; restart the parser")
        return SetParametersResult(successful=True)

    def _on_human(self, msg: String) -> None:
        try:
            data = from_msg(msg, {"id": (str, int)})
            semantics = self.parse(data)
        except MessageError as err:
            self.get_logger().warning(f"/dialogue/human: {err}")
            self._errors.publish(to_msg(error_reply(msg, str(err))))
            return
        self._semantics.publish(to_msg(semantics))

    def parse(self, data: dict) -> dict:
        """The semantics message for one human utterance (raises MessageError)."""
        has_text, has_description = "text" in data, "description" in data
        if has_text == has_description:
            raise MessageError("give exactly one of 'text' and 'description'")
        out = {key: data[key] for key in ("id", "time", "turn") if key in data}
        if data.get("domain") is not None:
            if not isinstance(data["domain"], str):
                raise MessageError("'domain' must be a string")
            out["domain"] = data["domain"]
        if has_description:
            description = data["description"]
            if not isinstance(description, list) or not all(isinstance(p, str) for p in description):
                raise MessageError("'description' must be a list of property names")
            out["description"] = description
            return out
        if not isinstance(data["text"], str):
            raise MessageError("'text' must be a string")
        parsed = self.lexicon.parse(data["text"], self.properties)
        out.update(description=parsed.properties, text=data["text"], unknown_words=parsed.unknown_words)
        return out


def main(args=None) -> int:
    return run_node(ParserNode, args, startup_errors=(LexiconError, ScenarioError, OSError))


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
