"""Scenario files: load, validate and represent a scenario or KB file.

A scenario file is YAML with ``name``, ``domains``, ``memory`` and ``dialogue``; a
knowledge-base (KB) file for a consultant is the same format without a dialogue.
The format is described key by key in ``docs/scenario-format.md``.

* :mod:`.model` -- the validated data (:class:`Scenario`, :class:`DomainSpec`, :class:`Turn`).
* :mod:`.schema` -- the file's structure as pydantic models and its JSON Schema.
* :mod:`.checks` -- the checks of meaning; builds the :class:`Scenario`.
* :mod:`.load` -- :func:`load_scenario` / :func:`parse_scenario`: YAML, structure, meaning.
* :mod:`.coverage` -- what a lexicon cannot say of a scenario: one warning, a lexicon skeleton.

Choices where the format could be read several ways:

* ``null`` for a ``memory:`` setting means "not set here" (the next layer down applies).
* ``entities`` may be left out or empty (entities can join at run time);
  ``dialogue`` may be left out, empty or null (a KB file).
* A human turn's ``target`` (ground truth) must be an entity of the turn's domain;
  a robot turn may name ``domain:`` only if it is its target's domain.
* A property may not be listed twice in one entity's facts or one preference order.
* ``Turn.domain`` is the ``domain:`` as written (None when absent): reference
  resolution determines it at run time, and validation checks that it can.
"""

from ..io.yaml_source import render_path
from .coverage import coverage_warning, lexicon_template, unsayable
from .load import load_scenario, parse_scenario
from .model import COMMAND_LINE, MEMORY_KEYS, DomainSpec, Scenario, ScenarioError, Turn
from .schema import scenario_json_schema

__all__ = [
    "COMMAND_LINE",
    "MEMORY_KEYS",
    "DomainSpec",
    "Scenario",
    "ScenarioError",
    "Turn",
    "coverage_warning",
    "lexicon_template",
    "load_scenario",
    "parse_scenario",
    "render_path",
    "scenario_json_schema",
    "unsayable",
]
