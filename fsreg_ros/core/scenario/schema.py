"""The structure of a scenario file as pydantic models, and its JSON Schema.

``extra="forbid"`` and strict types (``capacity: true`` is not a number while
``decay_period: 10`` is).  The models check shapes only; meaning (unknown
properties, times, ...) is :mod:`.checks`'s job.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Sequence, Union

from pydantic import ConfigDict, Discriminator, Field, Tag

from ..consultant import DEFAULT_THRESHOLD
from ..forgetting import RULES
from ..validation import Strict

Name = Annotated[str, Field(min_length=1)]
Certainty = Annotated[float, Field(json_schema_extra={"minimum": 0, "maximum": 1})]


def _facts_form(value: Any) -> Optional[str]:
    """Return which form an entity's facts take: a property list or a certainty mapping."""
    if isinstance(value, list):
        return "list"
    if isinstance(value, dict):
        return "map"
    return None


Facts = Annotated[
    Union[
        Annotated[list[Name], Tag("list")],
        Annotated[dict[Name, Certainty], Tag("map")],
    ],
    Discriminator(
        _facts_form,
        custom_error_type="facts_type",
        custom_error_message="must be a list of properties or a mapping of property to certainty",
    ),
    Field(
        description="The properties that hold (certainty 1), or a mapping property -> certainty in [0, 1]. "
        "Every property must be in the domain's preference order."
    ),
]

_POLICY_PATTERN = "^(none|({rules})(\\+({rules}))*)$".format(rules="|".join(RULES))


class MemoryBlock(Strict):
    """A ``memory:`` block: forgetting settings."""

    policy: Optional[str] = Field(
        None,
        description="none, or decay / displacement / global-capacity joined by +",
        json_schema_extra={"pattern": _POLICY_PATTERN},
    )
    decay_period: Optional[float] = Field(
        None, description="decay: seconds between ticks (delta), > 0", json_schema_extra={"exclusiveMinimum": 0}
    )
    capacity: Optional[int] = Field(
        None, description="displacement: per-entity queue limit (alpha), >= 1", json_schema_extra={"minimum": 1}
    )
    global_capacity: Optional[int] = Field(
        None, description="global-capacity: per-domain total limit, >= 1", json_schema_extra={"minimum": 1}
    )
    seed: Optional[int] = Field(
        None, description="displacement-random: random seed (default 0), >= 0", json_schema_extra={"minimum": 0}
    )
    shared_capacity: Optional[int] = Field(
        None, description="shared-capacity: limit of the pool shared by domains, >= 1", json_schema_extra={"minimum": 1}
    )


class DomainBlock(Strict):
    """One domain: its LTM, preference order, threshold, attributes and own memory settings."""

    threshold: float = Field(
        DEFAULT_THRESHOLD,
        description="a property holds iff its certainty >= threshold",
        json_schema_extra={"minimum": 0, "maximum": 1},
    )
    preference: list[Name] = Field(description="the domain's properties, most preferred first")
    attributes: dict[Name, list[Name]] = Field(
        default_factory=dict,
        description="attribute -> its properties (optional); a property 'attr=value' belongs to 'attr' implicitly",
    )
    entities: dict[Name, Facts] = Field(
        default_factory=dict, description="entity -> facts, in entity order; names unique across the file"
    )
    memory: Optional[MemoryBlock] = Field(
        None, description="this domain's own settings, merged over the top-level ones"
    )


class TurnEntry(Strict):
    """One dialogue turn.  Human: ``description`` or ``text``; robot: ``target``."""

    time: float = Field(description="seconds from t = 0; never negative, never decreasing")
    speaker: Literal["human", "robot"]
    target: Optional[Name] = Field(None, description="robot: the entity to describe; human: ground truth for scoring")
    description: Optional[list[Name]] = Field(None, description="human: properties in utterance order")
    text: Optional[str] = Field(None, description="human: the description in English, parsed with the lexicon")
    domain: Optional[Name] = Field(None, description="human: the domain to resolve in, when not implied")
    context: Optional[list[Name]] = Field(None, description="robot: explicit context set (distractors)")


class ScenarioFile(Strict):
    """An fsreg scenario or KB file."""

    model_config = ConfigDict(title="fsreg scenario")

    name: Optional[Name] = Field(None, description="defaults to the file name without extension")
    domains: dict[Name, DomainBlock] = Field(description="the knowledge domains, one consultant each")
    memory: Optional[MemoryBlock] = Field(None, description="default settings for every domain")
    dialogue: Optional[list[TurnEntry]] = Field(None, description="time-stamped turns; absent in a KB file")


#: Keys allowed in each kind of mapping, for "unknown key" messages.
KNOWN_KEYS = {
    "scenario": tuple(ScenarioFile.model_fields),
    "domain": tuple(DomainBlock.model_fields),
    "memory": tuple(MemoryBlock.model_fields),
    "turn": tuple(TurnEntry.model_fields),
}


def mapping_kind(loc: Sequence[Any]) -> str:
    """Return which model validates the mapping at ``loc``."""
    if not loc:
        return "scenario"
    if loc[-1] == "memory":
        return "memory"
    if loc[0] == "dialogue":
        return "turn"
    return "domain"


def scenario_json_schema() -> dict:
    """Return the JSON Schema (draft 2020-12) of the scenario file format."""
    schema = ScenarioFile.model_json_schema()
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **schema}


__all__ = ["MemoryBlock", "DomainBlock", "TurnEntry", "ScenarioFile", "KNOWN_KEYS", "scenario_json_schema"]
