"""Loading a scenario or KB file: YAML, then structure, then meaning.

Every problem in any stage becomes exactly one :class:`ScenarioError` naming the
file, the path inside it (``dialogue[3].text``), the line where known, and what
is wrong:

1. **YAML**: :mod:`fsreg_ros.core.yaml_source` (libyaml's C parser, strict keys).
2. **Structure**: the pydantic models of :mod:`.schema`.
3. **Meaning**: :class:`.checks.Checker`.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Optional, Union

from ..validation import validate
from ..yaml_source import describe_value, load_yaml, node_line, read_text
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

    ``name`` defaults to the stem of ``source``.  See :func:`load_scenario`.
    """
    root, data = load_yaml(text, source, ScenarioError)
    if data is None:
        raise ScenarioError(source, "", "empty file: expected a mapping with 'domains'", 1)
    if not isinstance(data, dict):
        raise ScenarioError(
            source, "", f"the top level must be a mapping with 'domains', not {describe_value(data)}", node_line(root)
        )
    model = validate(ScenarioFile, data, source, root, ScenarioError, _known_keys, _drop_facts_tag)
    return Checker(source, root, lexicon).scenario(model)


def _known_keys(loc: list) -> tuple:
    return KNOWN_KEYS[mapping_kind(loc)]


def _drop_facts_tag(loc: list) -> list:
    """Drop the tag pydantic adds for the facts union: ``domains.<d>.entities.<e>.<tag>``."""
    if len(loc) >= 5 and loc[0] == "domains" and loc[2] == "entities" and loc[4] in ("list", "map"):
        del loc[4]
    return loc
