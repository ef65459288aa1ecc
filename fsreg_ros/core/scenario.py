"""Scenario files: load, validate and represent a scenario or KB file (SPEC section 5).

A scenario file is YAML with ``name``, ``domains``, ``memory`` and ``dialogue``.  A
knowledge-base (KB) file for a consultant is the same format without a dialogue.

Loading runs in three stages, and every problem in any of them becomes exactly one
:class:`ScenarioError` naming the file, the path inside it (``dialogue[3].text``,
``domains.faces.entities.face2.glasses``), the line where known, and what is wrong:

1. **YAML**: :class:`ScenarioLoader`, a ``yaml.SafeLoader`` that rejects duplicate
   mapping keys and keeps the node tree, so that any path can be mapped to a line.
2. **Structure**: the pydantic models below (``extra="forbid"``, strict types, so
   ``capacity: true`` is not a number while ``decay_period: 10`` is).  They are also
   the source of the JSON Schema of the format (:func:`scenario_json_schema`).
3. **Meaning**: :class:`_Checker` -- unknown properties and entities, preference
   orders, times, forgetting settings, turn shapes and domains.  The rules of
   forgetting settings and certainties are the core's own
   (:mod:`fsreg_ros.core.forgetting`, :func:`fsreg_ros.core.consultant.check_certainty`).

Choices where SPEC section 5 is silent (the project docs should repeat them):

* ``null`` for a ``memory:`` setting means "not set here" (the next layer down applies).
* ``entities`` may be left out or empty (entities can join at run time, SPEC section 7);
  ``dialogue`` may be left out, empty or null (a KB file).
* A human turn's ``target`` (ground truth) must be an entity of the turn's domain;
  a robot turn may name ``domain:`` only if it is its target's domain.
* A property may not be listed twice in one entity's facts or one preference order.
* ``Turn.domain`` is the ``domain:`` as written (None when absent): reference
  resolution determines it at run time, and validation checks that it can.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, Mapping, Optional, Sequence, Union

import yaml
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError

from .consultant import DEFAULT_THRESHOLD, Consultant, KnowledgeError, check_certainty
from .forgetting import PARAMETERS, RULES, ForgettingPolicy, PolicyError, check_setting, merge_settings
from .resolution import domains_knowing

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .memory import EventSink
    from .realisation import Lexicon

#: Path used for errors in command-line overrides of the ``memory:`` settings.
COMMAND_LINE = "<command line>"
#: The keys of a ``memory:`` block.
MEMORY_KEYS = ("policy",) + PARAMETERS
#: How many entity names an "unknown entity" message lists before eliding the rest.
MAX_LISTED = 20

PathLoc = tuple[Union[str, int], ...]


class ScenarioError(ValueError):
    """One problem with a scenario file: where it is and what is wrong.

    ``str(err)`` is one line, ``"{source}:{line}: {path}: {message}"``, without
    ``:{line}`` when the line is unknown and without ``{path}: `` when the problem
    concerns the whole file (``path == ""``).
    """

    def __init__(self, source: str, path: str, message: str, line: Optional[int] = None) -> None:
        self.source = source
        self.path = path
        self.message = message
        self.line = line
        super().__init__(self._format())

    def _format(self) -> str:
        where = self.source if self.line is None else f"{self.source}:{self.line}"
        return f"{where}: {self.path}: {self.message}" if self.path else f"{where}: {self.message}"

    def __str__(self) -> str:
        return self._format()

    def __reduce__(self) -> tuple:
        # Picklable (e.g. across processes) despite the custom constructor.
        return (type(self), (self.source, self.path, self.message, self.line))


# ------------------------------------------------------------------ data model
@dataclass(frozen=True)
class DomainSpec:
    """One domain of a scenario: its LTM, preference order and own memory settings."""

    name: str
    preference: tuple[str, ...]
    #: entity -> {property: certainty}, in file order; the list form means certainty 1.0.
    entities: dict[str, dict[str, float]]
    threshold: float = DEFAULT_THRESHOLD
    #: The domain's own ``memory:`` block (keys given with a non-null value), or None.
    memory: Optional[dict] = None


@dataclass(frozen=True)
class Turn:
    """One dialogue turn, as written in the file (SPEC section 5)."""

    index: int  # position in the dialogue list, 0-based
    time: float
    speaker: str  # "human" | "robot"
    target: Optional[str] = None  # robot: required; human: optional ground truth
    description: Optional[tuple[str, ...]] = None  # human turns given as property lists
    text: Optional[str] = None  # human turns given as English
    domain: Optional[str] = None  # as written; None when absent
    context: Optional[tuple[str, ...]] = None  # robot turns only


@dataclass(frozen=True)
class Scenario:
    """A validated scenario or KB file."""

    name: str
    source: str  # file name used in error messages
    domains: dict[str, DomainSpec]  # file order
    memory: Optional[dict]  # top-level ``memory:`` block (non-null keys) or None
    dialogue: tuple[Turn, ...]  # may be empty (a KB file)
    #: Line numbers of some paths (``memory``, ``domains.<d>``, ``domains.<d>.memory``,
    #: ``dialogue[i]``), for messages about them after loading.
    lines: Mapping[str, int] = field(default_factory=dict, repr=False, compare=False)

    def policy_for(self, domain: str, overrides: Optional[Mapping[str, Any]] = None) -> ForgettingPolicy:
        """The effective forgetting policy of ``domain`` (SPEC section 5).

        The top-level ``memory:`` block, then the domain's own block, then
        ``overrides`` (command-line options; None values are ignored), merged key by
        key with :func:`forgetting.merge_settings`.  No policy anywhere means
        ``none``.  A bad setting becomes a :class:`ScenarioError` naming where it
        came from: ``memory``, ``domains.<d>.memory`` or ``<command line>``.
        """
        if domain not in self.domains:
            raise ScenarioError(self.source, "", f"unknown domain '{domain}' (known: {_names(self.domains)})")
        layers = (
            ("memory", self.memory),
            (f"domains.{domain}.memory", self.domains[domain].memory),
            (COMMAND_LINE, dict(overrides) if overrides is not None else None),
        )
        for path, layer in layers:
            for key, value in (layer or {}).items():
                problem = _memory_setting_problem(key, value)
                if problem is not None:
                    where = path if path == COMMAND_LINE else f"{path}.{key}"
                    raise ScenarioError(self.source, where, problem, self.lines.get(where, self.lines.get(path)))
        try:
            return merge_settings(*(layer for _, layer in layers))
        except PolicyError as err:
            # Every single value is valid, so a parameter is missing: blame the
            # most specific layer that chose the policy.
            path = "memory"
            for candidate, layer in layers:
                if layer and layer.get("policy") is not None:
                    path = candidate
            raise ScenarioError(self.source, path, f"domain '{domain}': {err}", self.lines.get(path)) from None

    def domain_of(self, entity: str) -> str:
        """The domain ``entity`` belongs to; ScenarioError if no domain has it."""
        for name, spec in self.domains.items():
            if entity in spec.entities:
                return name
        raise ScenarioError(self.source, "", f"unknown entity '{entity}' (known: {_names(self.entities())})")

    def entities(self) -> list[str]:
        """Every entity of every domain, in file order."""
        return [entity for spec in self.domains.values() for entity in spec.entities]

    def properties(self) -> set[str]:
        """Every property: the union of all preference orders."""
        return {prop for spec in self.domains.values() for prop in spec.preference}

    def consultants(self, sink: Optional["EventSink"] = None) -> dict[str, Consultant]:
        """A fresh core :class:`Consultant` per domain (entity order, preference,
        threshold as in the file; ``sink`` receives every WM event)."""
        return {
            name: Consultant(name, spec.entities, spec.preference, spec.threshold, sink)
            for name, spec in self.domains.items()
        }


# ------------------------------------------------------ file format (pydantic)
Name = Annotated[str, Field(min_length=1)]
Certainty = Annotated[float, Field(json_schema_extra={"minimum": 0, "maximum": 1})]


def _facts_form(value: Any) -> Optional[str]:
    """Which form an entity's facts take: a property list or a certainty mapping."""
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


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class MemoryBlock(_Strict):
    """A ``memory:`` block: forgetting settings (SPEC sections 2 and 5)."""

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


class DomainBlock(_Strict):
    """One domain: its LTM, preference order, threshold and own memory settings."""

    threshold: float = Field(
        DEFAULT_THRESHOLD,
        description="a property holds iff its certainty >= threshold",
        json_schema_extra={"minimum": 0, "maximum": 1},
    )
    preference: list[Name] = Field(description="the domain's properties, most preferred first")
    entities: dict[Name, Facts] = Field(
        default_factory=dict, description="entity -> facts, in entity order; names unique across the file"
    )
    memory: Optional[MemoryBlock] = Field(None, description="this domain's own settings, merged over the top-level ones")


class TurnEntry(_Strict):
    """One dialogue turn.  Human: ``description`` or ``text``; robot: ``target``."""

    time: float = Field(description="seconds from t = 0; never negative, never decreasing")
    speaker: Literal["human", "robot"]
    target: Optional[Name] = Field(None, description="robot: the entity to describe; human: ground truth for scoring")
    description: Optional[list[Name]] = Field(None, description="human: properties in utterance order")
    text: Optional[str] = Field(None, description="human: the description in English, parsed with the lexicon")
    domain: Optional[Name] = Field(None, description="human: the domain to resolve in, when not implied")
    context: Optional[list[Name]] = Field(None, description="robot: explicit context set (distractors)")


class ScenarioFile(_Strict):
    """An fsreg scenario or KB file (SPEC section 5)."""

    model_config = ConfigDict(title="fsreg scenario")

    name: Optional[Name] = Field(None, description="defaults to the file name without extension")
    domains: dict[Name, DomainBlock] = Field(description="the knowledge domains, one consultant each")
    memory: Optional[MemoryBlock] = Field(None, description="default settings for every domain")
    dialogue: Optional[list[TurnEntry]] = Field(None, description="time-stamped turns; absent in a KB file")


#: Keys allowed in each kind of mapping, for "unknown key" messages.
_KNOWN_KEYS = {
    "scenario": tuple(ScenarioFile.model_fields),
    "domain": tuple(DomainBlock.model_fields),
    "memory": tuple(MemoryBlock.model_fields),
    "turn": tuple(TurnEntry.model_fields),
}


def scenario_json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of the scenario file format."""
    schema = ScenarioFile.model_json_schema()
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **schema}


# ------------------------------------------------------------------- YAML
class DuplicateKeyError(yaml.YAMLError):
    """A mapping names the same key twice (raised by :class:`ScenarioLoader`)."""

    def __init__(self, mapping: yaml.MappingNode, key: Any, first: yaml.Node, second: yaml.Node) -> None:
        super().__init__(f"duplicate key {key!r}")
        self.mapping, self.key, self.first, self.second = mapping, key, first, second


class ScenarioLoader(yaml.SafeLoader):
    """A SafeLoader that rejects duplicate mapping keys.

    Use :meth:`load_tree`, which also returns the node tree: every node keeps its
    ``start_mark``, so a path in the document can be mapped to a line.
    """

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: dict[Any, yaml.Node] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue  # "<<" merges are allowed to be overridden
            key = self.construct_object(key_node, deep=True)
            try:
                first = seen.get(key)
            except TypeError:
                continue  # unhashable: SafeConstructor reports it
            if first is not None:
                raise DuplicateKeyError(node, key, first, key_node)
            seen[key] = key_node
        return super().construct_mapping(node, deep=deep)

    #: The document's root node, once composed (kept for error messages).
    root: Optional[yaml.Node] = None

    def load_tree(self) -> tuple[Optional[yaml.Node], Any]:
        """The single document's root node (None if empty) and its Python value."""
        self.root = self.get_single_node()
        return self.root, (self.construct_document(self.root) if self.root is not None else None)


def _line(node: yaml.Node) -> int:
    return node.start_mark.line + 1


def _find_node(root: Optional[yaml.Node], loc: PathLoc) -> tuple[Optional[int], bool]:
    """The line of the node at ``loc`` (its key's line for a mapping entry), best
    effort: the deepest node found, and whether the whole path was found."""
    node, line = root, (_line(root) if root is not None else None)
    for segment in loc:
        found = None
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                if isinstance(key_node, yaml.ScalarNode) and key_node.value == str(segment):
                    found, line = value_node, _line(key_node)
                    break
        elif isinstance(node, yaml.SequenceNode) and isinstance(segment, int) and 0 <= segment < len(node.value):
            found = node.value[segment]
            line = _line(found)
        if found is None:
            return line, False
        node = found
    return line, True


def _path_to(root: yaml.Node, target: yaml.Node) -> Optional[PathLoc]:
    """The path from ``root`` to the node ``target`` (identity), or None."""
    stack: list[tuple[yaml.Node, PathLoc]] = [(root, ())]
    seen: set[int] = set()
    while stack:
        node, loc = stack.pop()
        if node is target:
            return loc
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                key = key_node.value if isinstance(key_node, yaml.ScalarNode) else "?"
                stack.append((value_node, loc + (key,)))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, loc + (i,)) for i, item in enumerate(node.value))
    return None


def render_path(loc: Sequence[Union[str, int]]) -> str:
    """``("dialogue", 3, "description", 1)`` -> ``"dialogue[3].description[1]"``."""
    out = ""
    for segment in loc:
        if isinstance(segment, int) and not isinstance(segment, bool):
            out += f"[{segment}]"
        else:
            out += f".{segment}" if out else str(segment)
    return out


# ------------------------------------------------------------------ loading
def load_scenario(path: Union[str, os.PathLike], lexicon: Optional["Lexicon"] = None) -> Scenario:
    """Read and validate a scenario or KB file.

    ``lexicon`` parses text turns; when None and the file has text turns,
    ``Lexicon.load()`` (the default lexicon) is used.  Every problem, including a
    missing or unreadable file, is a :class:`ScenarioError`.
    """
    source = os.fspath(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(source, "", "file not found") from None
    except IsADirectoryError:
        raise ScenarioError(source, "", "is a directory, not a scenario file") from None
    except UnicodeDecodeError as err:
        raise ScenarioError(source, "", f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    except OSError as err:
        raise ScenarioError(source, "", f"cannot read the file: {err.strerror or err}") from None
    return parse_scenario(text, source=source, lexicon=lexicon)


def parse_scenario(text: str, source: str = "<string>", lexicon: Optional["Lexicon"] = None) -> Scenario:
    """Validate scenario YAML ``text``; ``source`` names it in error messages.

    ``name`` defaults to the stem of ``source``.  See :func:`load_scenario`.
    """
    root, data = _parse_yaml(text, source)
    if data is None:
        raise ScenarioError(source, "", "empty file: expected a mapping with 'domains'", 1)
    if not isinstance(data, dict):
        raise ScenarioError(source, "", f"the top level must be a mapping with 'domains', not {_describe(data)}", _line(root))
    try:
        model = ScenarioFile.model_validate(data)
    except ValidationError as err:
        raise _structure_error(err, source, root) from None
    return _Checker(source, root, lexicon).scenario(model)


def _parse_yaml(text: str, source: str) -> tuple[Optional[yaml.Node], Any]:
    loader = ScenarioLoader(text)
    try:
        return loader.load_tree()
    except DuplicateKeyError as err:
        loc = (_path_to(loader.root, err.mapping) or ()) if loader.root is not None else ()
        loc += (str(err.key),)
        message = f"duplicate key '{err.key}' (first at line {_line(err.first)})"
        raise ScenarioError(source, render_path(loc), message, _line(err.second)) from None
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        problem = err.problem or err.context or "syntax error"
        if err.context and err.problem:
            started = f" started at line {err.context_mark.line + 1}" if err.context_mark else ""
            problem += f" ({err.context}{started})"
        raise ScenarioError(source, "", f"not valid YAML: {problem}", mark.line + 1 if mark else None) from None
    except yaml.YAMLError as err:
        raise ScenarioError(source, "", f"not valid YAML: {err}") from None
    except RecursionError:
        raise ScenarioError(source, "", "not a scenario: YAML nested too deeply") from None
    finally:
        loader.dispose()


# ------------------------------------------------------- structural errors
def _structure_error(err: ValidationError, source: str, root: Optional[yaml.Node]) -> ScenarioError:
    """The first pydantic error (by line) as a ScenarioError.

    A missing key ranks after every other problem: with a misspelt key
    (``prefernce``), "unknown key ..., known: ..." is the helpful message.
    """
    errors = err.errors()
    problems = [_pydantic_problem(error, source, root) for error in errors]
    ranked = sorted(
        zip(errors, problems),
        key=lambda pair: (pair[0]["type"] == "missing", pair[1].line is None, pair[1].line or 0),
    )
    return ranked[0][1]


def _pydantic_problem(error: Mapping[str, Any], source: str, root: Optional[yaml.Node]) -> ScenarioError:
    loc = list(error["loc"])
    # Drop the tag pydantic adds for the facts union: domains.<d>.entities.<e>.<tag>.
    if len(loc) >= 5 and loc[0] == "domains" and loc[2] == "entities" and loc[4] in ("list", "map"):
        del loc[4]
    kind, value = error["type"], error.get("input")
    if loc and loc[-1] == "[key]":
        loc.pop()
        key = loc[-1] if loc else value
        message = f"key {_expected(kind, error['msg'])}, got {_describe(key)}"
        line, _ = _find_node(root, tuple(loc))
        return ScenarioError(source, render_path(loc[:-1] + [str(key)]), message, line)
    if kind == "extra_forbidden":
        known = _KNOWN_KEYS[_mapping_kind(loc[:-1])]
        message = f"unknown key '{loc[-1]}' (known: {', '.join(known)})"
    elif kind == "missing":
        parent = loc[:-1]
        line, _ = _find_node(root, tuple(parent))
        return ScenarioError(source, render_path(parent), f"missing required key '{loc[-1]}'", line)
    else:
        message = f"{_expected(kind, error['msg'])}, got {_describe(value)}"
    line, _ = _find_node(root, tuple(loc))
    return ScenarioError(source, render_path(loc), message, line)


def _mapping_kind(loc: Sequence[Any]) -> str:
    """Which model validates the mapping at ``loc``."""
    if not loc:
        return "scenario"
    if loc[-1] == "memory":
        return "memory"
    if loc[0] == "dialogue":
        return "turn"
    return "domain"


_EXPECTED = {
    "string_type": "must be a string",
    "float_type": "must be a number",
    "int_type": "must be a whole number",
    "list_type": "must be a list",
    "dict_type": "must be a mapping",
    "model_type": "must be a mapping",
    "model_attributes_type": "must be a mapping",
    "finite_number": "must be a finite number",
    "string_too_short": "must not be empty",
}


def _expected(kind: str, pydantic_message: str) -> str:
    if kind in _EXPECTED:
        return _EXPECTED[kind]
    return pydantic_message.replace("Input should be", "must be")


def _describe(value: Any) -> str:
    """A short description of a wrong value for a message."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()} (YAML reads yes/no/on/off/true/false as booleans; quote it if you mean text)"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return f"a {type(value).__name__}"


def _names(names: Sequence[str] | Mapping[str, Any], limit: Optional[int] = None) -> str:
    """``a, b, c`` (or the first ``limit`` and a count), for messages."""
    names = list(names)
    if not names:
        return "none"
    if limit is not None and len(names) > limit:
        return f"{', '.join(names[:limit])}, ... ({len(names)} in all)"
    return ", ".join(names)


def _memory_setting_problem(key: str, value: Any) -> Optional[str]:
    """What is wrong with one ``memory:`` setting, by the core's rules, or None."""
    if key not in MEMORY_KEYS:
        return f"unknown memory setting '{key}' (known: {', '.join(MEMORY_KEYS)})"
    if value is None:
        return None
    try:
        check_setting(key, value)
    except PolicyError as err:
        return str(err)
    return None


# --------------------------------------------------------- semantic checks
class _Checker:
    """The checks of SPEC section 5 that need more than types; builds the Scenario."""

    def __init__(self, source: str, root: Optional[yaml.Node], lexicon: Optional["Lexicon"]) -> None:
        self.source = source
        self.root = root
        self.lexicon = lexicon

    def fail(self, loc: PathLoc, message: str) -> ScenarioError:
        line, _ = _find_node(self.root, loc)
        return ScenarioError(self.source, render_path(loc), message, line)

    def line(self, loc: PathLoc) -> Optional[int]:
        line, found = _find_node(self.root, loc)
        return line if found else None

    # ------------------------------------------------------------ whole file
    def scenario(self, model: ScenarioFile) -> Scenario:
        if not model.domains:
            raise self.fail(("domains",), "no domains: a scenario needs at least one")
        domains: dict[str, DomainSpec] = {}
        owner: dict[str, str] = {}  # entity -> domain
        all_properties = {p for block in model.domains.values() for p in block.preference}
        for name, block in model.domains.items():
            domains[name] = self.domain(name, block, owner, all_properties)
        memory = self.memory_block(("memory",), model.memory)
        lines = self.lines(model)
        scenario = Scenario(
            name=model.name if model.name is not None else Path(self.source).stem,
            source=self.source,
            domains=domains,
            memory=memory,
            dialogue=(),
            lines=lines,
        )
        for name in domains:
            scenario.policy_for(name)  # a policy missing its parameter is an error
        return replace(scenario, dialogue=tuple(self.dialogue(model.dialogue or [], scenario)))

    def lines(self, model: ScenarioFile) -> dict[str, int]:
        paths: list[PathLoc] = [("memory",)]
        for name in model.domains:
            paths += [("domains", name), ("domains", name, "memory")]
        paths += [("dialogue", i) for i in range(len(model.dialogue or []))]
        found = {render_path(loc): self.line(loc) for loc in paths}
        return {path: line for path, line in found.items() if line is not None}

    # ---------------------------------------------------------------- domains
    def domain(self, name: str, block: DomainBlock, owner: dict[str, str], all_properties: set[str]) -> DomainSpec:
        here = ("domains", name)
        try:
            threshold = check_certainty("threshold", block.threshold)
        except KnowledgeError as err:
            raise self.fail(here + ("threshold",), str(err)) from None
        first: dict[str, int] = {}
        for i, prop in enumerate(block.preference):
            if prop in first:
                raise self.fail(
                    here + ("preference", i),
                    f"property '{prop}' is listed twice in the preference order (also at preference[{first[prop]}])",
                )
            first[prop] = i
        entities: dict[str, dict[str, float]] = {}
        for entity, facts in block.entities.items():
            at = here + ("entities", entity)
            if entity in owner:
                raise self.fail(
                    at,
                    f"duplicate entity '{entity}': already in domain '{owner[entity]}' "
                    "(an entity belongs to exactly one domain; names are unique across the file)",
                )
            owner[entity] = name
            entities[entity] = self.facts(at, name, block.preference, facts, all_properties)
        memory = self.memory_block(here + ("memory",), block.memory)
        return DomainSpec(name, tuple(block.preference), entities, threshold, memory)

    def facts(
        self,
        at: PathLoc,
        domain: str,
        preference: Sequence[str],
        facts: Union[list[str], dict[str, float]],
        all_properties: set[str],
    ) -> dict[str, float]:
        """An entity's facts as {property: certainty}; list form means certainty 1."""
        known = set(preference)
        # (path key, property, certainty): list items are addressed by index.
        items: list[tuple[Union[int, str], str, float]]
        if isinstance(facts, list):
            items = [(i, prop, 1.0) for i, prop in enumerate(facts)]
        else:
            items = [(prop, prop, certainty) for prop, certainty in facts.items()]
        out: dict[str, float] = {}
        for key, prop, certainty in items:
            if prop not in known:
                where = " (it is in another domain's preference order)" if prop in all_properties else " (it is in no preference order)"
                raise self.fail(
                    at + (key,),
                    f"unknown property '{prop}'{where}: an entity's properties must be in its domain's "
                    f"preference order (domain '{domain}' knows: {_names(preference)})",
                )
            if prop in out:
                raise self.fail(at + (key,), f"property '{prop}' is listed twice for entity '{at[-1]}'")
            try:
                out[prop] = check_certainty(f"certainty of '{prop}' for '{at[-1]}'", certainty)
            except KnowledgeError as err:
                raise self.fail(at + (key,), str(err)) from None
        return out

    # ----------------------------------------------------------------- memory
    def memory_block(self, at: PathLoc, block: Optional[MemoryBlock]) -> Optional[dict]:
        """A ``memory:`` block's non-null settings, each checked by the core's rules."""
        if block is None:
            return None
        settings = {k: v for k, v in block.model_dump(exclude_unset=True).items() if v is not None}
        for key, value in settings.items():
            problem = _memory_setting_problem(key, value)
            if problem is not None:
                raise self.fail(at + (key,), problem)
        return settings

    # --------------------------------------------------------------- dialogue
    def dialogue(self, entries: Sequence[TurnEntry], scenario: Scenario) -> list[Turn]:
        turns: list[Turn] = []
        previous: Optional[float] = None
        for index, entry in enumerate(entries):
            at = ("dialogue", index)
            if entry.time < 0:
                raise self.fail(at + ("time",), f"negative time {entry.time}: times are seconds from t = 0")
            if previous is not None and entry.time < previous:
                raise self.fail(
                    at + ("time",),
                    f"decreasing time: {entry.time} is before the previous turn's {previous} "
                    "(turns are in time order; equal times are allowed)",
                )
            previous = entry.time
            check = self.human_turn if entry.speaker == "human" else self.robot_turn
            check(at, entry, scenario)
            turns.append(
                Turn(
                    index=index,
                    time=entry.time,
                    speaker=entry.speaker,
                    target=entry.target,
                    description=tuple(entry.description) if entry.description is not None else None,
                    text=entry.text,
                    domain=entry.domain,
                    context=tuple(entry.context) if entry.context is not None else None,
                )
            )
        return turns

    def human_turn(self, at: PathLoc, entry: TurnEntry, scenario: Scenario) -> None:
        if entry.context is not None:
            raise self.fail(at + ("context",), "only robot turns have a context")
        if entry.description is not None and entry.text is not None:
            raise self.fail(at, "a human turn gives either description or text, not both")
        if entry.description is None and entry.text is None:
            raise self.fail(at, "a human turn needs a description (a list of properties) or text")
        if entry.domain is not None and entry.domain not in scenario.domains:
            raise self.fail(at + ("domain",), f"unknown domain '{entry.domain}' (known: {_names(scenario.domains)})")
        if entry.description is not None:
            if not entry.description:
                raise self.fail(at + ("description",), "empty description")
            properties, whole, indexed = entry.description, at + ("description",), True
        else:
            properties = self.parse_text(at + ("text",), entry.text or "", scenario)
            whole, indexed = at + ("text",), False
        domain = self.turn_domain(entry.domain, properties, whole, indexed, scenario)
        if entry.target is not None:
            self.entity_in(at + ("target",), entry.target, domain, scenario, "the description's domain")

    def robot_turn(self, at: PathLoc, entry: TurnEntry, scenario: Scenario) -> None:
        if entry.target is None:
            raise self.fail(at, "a robot turn needs a target (the entity to describe)")
        for key in ("description", "text"):
            if getattr(entry, key) is not None:
                raise self.fail(at + (key,), f"a robot turn has no {key}: the robot generates it")
        domain = self.entity_in(at + ("target",), entry.target, None, scenario, "")
        if entry.domain is not None and entry.domain != domain:
            raise self.fail(
                at + ("domain",), f"domain '{entry.domain}' is not the target's domain ('{entry.target}' is in '{domain}')"
            )
        for i, entity in enumerate(entry.context or ()):
            self.entity_in(at + ("context", i), entity, domain, scenario, "the target's domain")

    def entity_in(self, at: PathLoc, entity: str, domain: Optional[str], scenario: Scenario, what: str) -> str:
        """Check ``entity`` exists (and is in ``domain`` if given); return its domain."""
        owner = next((name for name, spec in scenario.domains.items() if entity in spec.entities), None)
        if owner is None:
            candidates = scenario.domains[domain].entities if domain is not None else scenario.entities()
            scope = f"domain '{domain}' has" if domain is not None else "known"
            raise self.fail(at, f"unknown entity '{entity}' ({scope}: {_names(list(candidates), MAX_LISTED)})")
        if domain is not None and owner != domain:
            raise self.fail(at, f"entity '{entity}' is in domain '{owner}', not in {what} '{domain}'")
        return owner

    def parse_text(self, at: PathLoc, text: str, scenario: Scenario) -> list[str]:
        """The properties of a text turn, as the simulator parses them (all properties)."""
        if not text.strip():
            raise self.fail(at, "empty text")
        lexicon = self.get_lexicon(at)
        properties = list(lexicon.parse(text, scenario.properties()).properties)
        if not properties:
            raise self.fail(at, f"no known property in text {text!r}")
        return properties

    def get_lexicon(self, at: PathLoc) -> "Lexicon":
        if self.lexicon is None:
            try:
                from .realisation import Lexicon
            except ImportError as err:
                raise self.fail(at, f"text turns need the lexicon, which cannot be imported: {err}") from None
            try:
                self.lexicon = Lexicon.load()
            except (OSError, ValueError, yaml.YAMLError) as err:
                raise self.fail(at, f"text turns need the lexicon, which cannot be loaded: {err}") from None
        return self.lexicon

    def turn_domain(
        self,
        named: Optional[str],
        properties: Sequence[str],
        whole: PathLoc,
        indexed: bool,
        scenario: Scenario,
    ) -> str:
        """The domain a human description resolves in (SPEC section 3): the named
        one, else the only domain whose preference order has every property.

        Errors about one property point at ``whole[i]`` when ``indexed`` (a
        description list), else at ``whole`` (a text)."""

        def where(i: int) -> PathLoc:
            return whole + (i,) if indexed else whole

        domains = scenario.domains
        if named is not None:
            preference = domains[named].preference
            for i, prop in enumerate(properties):
                if prop not in preference:
                    raise self.fail(where(i), f"unknown property '{prop}' (domain '{named}' knows: {_names(preference)})")
            return named
        for i, prop in enumerate(properties):
            if not any(prop in spec.preference for spec in domains.values()):
                known = "; ".join(f"domain '{d}' knows: {_names(spec.preference)}" for d, spec in domains.items())
                raise self.fail(where(i), f"unknown property '{prop}' ({known})")
        fitting = domains_knowing(properties, {d: spec.preference for d, spec in domains.items()})
        if len(fitting) == 1:
            return fitting[0]
        if fitting:
            raise self.fail(
                whole,
                f"domain not determined: several domains know every property ({', '.join(fitting)}); "
                "name one with 'domain:'",
            )
        owners = "; ".join(
            f"'{p}': {', '.join(d for d, spec in domains.items() if p in spec.preference)}" for p in dict.fromkeys(properties)
        )
        raise self.fail(
            whole, f"domain not determined: no domain knows every property (candidate domains per property: {owners})"
        )
