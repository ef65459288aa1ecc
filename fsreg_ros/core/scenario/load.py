"""Loading a scenario or KB file: YAML, then structure, then meaning.

Every problem in any stage becomes exactly one :class:`ScenarioError` naming the
file, the path inside it (``dialogue[3].text``), the line where known, and what
is wrong:

1. **YAML**: :mod:`fsreg_ros.core.io.yaml_source` (libyaml's C parser, strict keys).
2. **Structure**: the pydantic models of :mod:`.schema`.
3. **Meaning**: :class:`.checks.Checker`.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Optional, Union

from ..io.validation import validate
from ..io.yaml_source import collector_paused, describe_value, load_yaml, node_line, read_text
from .checks import Checker
from .model import Scenario, ScenarioError
from .schema import KNOWN_KEYS, ScenarioFile, mapping_kind

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..lexicon import Lexicon


def load_scenario(path: Union[str, os.PathLike], lexicon: Optional["Lexicon"] = None) -> Scenario:
    """Read and validate a scenario or KB file.

    ``lexicon`` parses text turns; when None and the file has text turns,
    ``Lexicon.load()`` (the default lexicon) is used.  Every problem, including a
    missing, unreadable or binary file, is a :class:`ScenarioError`.
    """
    return parse_scenario(read_text(path, ScenarioError), source=os.fspath(path), lexicon=lexicon)


def parse_scenario(text: str, source: str = "<string>", lexicon: Optional["Lexicon"] = None) -> Scenario:
    """Validate scenario YAML ``text``; ``source`` names it in error messages.

    ``name`` defaults to the stem of ``source``.  See :func:`load_scenario`.  The
    garbage collector stays paused until the YAML node tree (kept for the line
    numbers of error messages) has been released.
    """
    with collector_paused():
        return _parse(text, source, lexicon)


def _parse(text: str, source: str, lexicon: Optional["Lexicon"]) -> Scenario:
    root, data = load_yaml(text, source, ScenarioError)
    if data is None:
        raise ScenarioError(source, "", "empty file: expected a mapping with 'domains'", 1)
    if not isinstance(data, dict):
        raise ScenarioError(
            source, "", f"the top level must be a mapping with 'domains', not {describe_value(data)}", node_line(root)
        )
    data, set_aside = _set_aside_plain_facts(data)
    model = validate(ScenarioFile, data, source, root, ScenarioError, _known_keys, _drop_facts_tag)
    for name, entities in set_aside.items():
        model.domains[name].entities = entities
    return Checker(source, root, lexicon).scenario(model)


def _set_aside_plain_facts(data: dict) -> tuple[dict, dict[str, dict]]:
    """Take out the ``entities`` of each domain whose every entity is a list of names.

    Those are most of a large world (10,000 entities x 40 facts) and pydantic would
    accept them as they are (``str`` keys and items, none empty), so validating them
    one by one would only cost time; they go back into the model afterwards.  A
    domain with any other entity keeps its entities, so every structural error is
    still pydantic's, found and reported exactly as before.  Returns the data to
    validate (``data`` itself when nothing was taken out) and domain -> entities.
    """
    domains = data.get("domains")
    if not isinstance(domains, dict):
        return data, {}
    set_aside: dict[str, dict] = {}
    for name, block in domains.items():
        entities = block.get("entities") if isinstance(block, dict) else None
        if isinstance(name, str) and isinstance(entities, dict) and entities and all(
            type(entity) is str and entity and _plain_names(facts) for entity, facts in entities.items()
        ):
            set_aside[name] = entities
    if not set_aside:
        return data, {}
    slim = {
        name: ({**block, "entities": {}} if name in set_aside else block) for name, block in domains.items()
    }
    return {**data, "domains": slim}, set_aside


def _plain_names(facts: object) -> bool:
    """Tell whether ``facts`` is a list of non-empty strings (by C-level passes: a world has 400,000 of them)."""
    return type(facts) is list and _STR_ONLY.issuperset(map(type, facts)) and "" not in facts


_STR_ONLY = frozenset((str,))


def _known_keys(loc: list) -> tuple:
    return KNOWN_KEYS[mapping_kind(loc)]


def _drop_facts_tag(loc: list) -> list:
    """Drop the tag pydantic adds for the facts union: ``domains.<d>.entities.<e>.<tag>``."""
    if len(loc) >= 5 and loc[0] == "domains" and loc[2] == "entities" and loc[4] in ("list", "map"):
        del loc[4]
    return loc
