"""The structure of a scenario file as pydantic models, and its JSON Schema.

``extra="forbid"`` and strict types (``capacity: true`` is not a number while
``decay_period: 10`` is).  ``MemoryBlock`` is generated from the memory settings
table (:mod:`fsreg_ros.core.forgetting.settings`).  The models check shapes only; meaning (unknown
properties, times, ...) is :mod:`.checks`'s job.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Sequence, Union

from pydantic import ConfigDict, Discriminator, Field, Tag, create_model

from ..forgetting import settings
from ..consultant.consultant import DEFAULT_THRESHOLD
from ..forgetting.policies import POLICY_PATTERN
from ..io.validation import Strict

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

MemoryBlock = create_model(
    "MemoryBlock",
    __base__=Strict,
    __doc__="A ``memory:`` block: forgetting settings, one field per row of the settings table "
    "(:mod:`fsreg_ros.core.forgetting.settings`); each value is checked by the table's rules.",
    **{
        row.name: (Optional[row.kind], Field(None, description=row.description,
                                             json_schema_extra=row.json_schema_extra(POLICY_PATTERN)))
        for row in settings.TABLE
    },
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
    exclusive: list[list[Name]] = Field(
        default_factory=list,
        description="groups of properties that exclude each other (optional): asserting one to hold retracts the "
        "others for that entity; the values of an attribute named 'attr=value' are a group without being listed",
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
