"""Lexicon files: their structure (pydantic), reading, and extending the built-in one.

The format is described at the top of ``config/lexicon.yaml``.  A lexicon file
given by the user (``--lexicon``, the nodes' ``lexicon`` parameter) *extends* the
built-in ``config/lexicon.yaml``: its properties replace built-in entries of the
same name, its domains add members (and may set the noun), its function words and
negators are added, and its ``default_noun`` replaces the built-in one.
"""

from __future__ import annotations

import os
from typing import Annotated, Any, Mapping, Optional, Union

import yaml
from pydantic import AfterValidator, Field

from ..io.paths import config_path
from ..io.validation import Strict, validate
from ..io.yaml_source import PathLoc, SourceError, describe_value, find_line, node_line, read_yaml, render_path
from .words import tokenize

#: Words :meth:`Lexicon.realise` itself puts around the lexicon's words.
REALISER_WORDS = frozenset({"the", "with", "and"})


class LexiconError(SourceError):
    """A bad lexicon: names the file and the path inside it.

    For example ``lexicon.yaml:12: properties.male.noun: must be a string, got a list``.
    """


def _has_words(text: str) -> str:
    if not tokenize(text):
        raise ValueError(f"{text!r} has no words")
    return text


Words = Annotated[str, AfterValidator(_has_words)]


class EntryBlock(Strict):
    """How one property is said and heard (a ``properties:`` item)."""

    noun: Optional[Words] = Field(None, description="it can head the description ('man')")
    adjective: Optional[Words] = Field(None, description="pre-modifier ('red')")
    order: Optional[int] = Field(None, description="adjective order, ascending left to right")
    words: Optional[Words] = Field(None, description="post-modifier after 'with' ('lab coat')")
    article: Optional[str] = Field(None, description="function word(s) before words ('a')")
    phrases: Optional[list[Words]] = Field(None, description="extra ways a human may say it")
    negates: Optional[Words] = Field(None, description="the property it is the negation of")


class DomainEntry(Strict):
    """A ``domains:`` item: default head noun and member properties."""

    noun: Optional[Words] = None
    properties: Optional[list[str]] = None


class LexiconFile(Strict):
    """A lexicon file (every key optional)."""

    default_noun: Optional[Words] = None
    function_words: Optional[list[Words]] = None
    negators: Optional[list[Words]] = None
    domains: Optional[dict[str, Optional[DomainEntry]]] = None
    properties: Optional[dict[str, Optional[EntryBlock]]] = None


_KNOWN = {
    "file": tuple(LexiconFile.model_fields),
    "domain": tuple(DomainEntry.model_fields),
    "entry": tuple(EntryBlock.model_fields),
}


def _known_keys(loc: list) -> tuple:
    if not loc:
        return _KNOWN["file"]
    return _KNOWN["domain"] if loc[0] == "domains" else _KNOWN["entry"]


class LexiconSource:
    """A validated lexicon file: the model, and where it came from (for messages).

    After :meth:`extended_by`, ``model`` is the merged lexicon while ``own`` is the
    extending file's own content, so an error in it is reported at its own line and
    item (``domains.faces.properties[0]``), not at the merged list's index.
    """

    def __init__(self, model: LexiconFile, source: str, root: Optional[yaml.Node] = None,
                 own: Optional[LexiconFile] = None) -> None:
        self.model = model
        self.source = source
        self.root = root
        self.own = own if own is not None else model

    def own_members(self, domain: str) -> list[str]:
        """Return the members of ``domain`` as this file lists them (its own list, its own order)."""
        block = (self.own.domains or {}).get(domain)
        return list(block.properties or []) if block else []

    def fail(self, loc: PathLoc, message: str) -> LexiconError:
        """Return the error ``message`` at ``loc`` in this file."""
        line, _ = find_line(self.root, loc) if loc else (None, False)
        return LexiconError(self.source, render_path(loc), message, line)

    def extended_by(self, extra: "LexiconSource") -> "LexiconSource":
        """Return this lexicon with ``extra``'s content added (see the module docstring)."""
        base, more = self.model, extra.model
        domains = {name: entry or DomainEntry() for name, entry in (base.domains or {}).items()}
        for name, entry in (more.domains or {}).items():
            old = domains.get(name, DomainEntry())
            entry = entry or DomainEntry()
            members = list(old.properties or [])
            members += [p for p in entry.properties or [] if p not in members]
            domains[name] = DomainEntry(noun=entry.noun or old.noun, properties=members)
        merged = LexiconFile(
            default_noun=more.default_noun or base.default_noun,
            function_words=_union(base.function_words, more.function_words),
            negators=_union(base.negators, more.negators),
            domains=domains,
            properties={**(base.properties or {}), **(more.properties or {})},
        )
        return LexiconSource(merged, extra.source, extra.root, own=more)


def _union(first: Optional[list[str]], second: Optional[list[str]]) -> Optional[list[str]]:
    if first is None or second is None:
        return second if first is None else first
    return list(dict.fromkeys([*first, *second]))


def parse_mapping(data: Any, source: str, root: Optional[yaml.Node] = None) -> LexiconSource:
    """Return the validated lexicon ``data`` (parsed YAML); errors name ``source``."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        line = node_line(root) if root is not None else None
        raise LexiconError(source, "", f"must be a mapping, not {describe_value(data)}", line)
    model = validate(LexiconFile, data, source, root, LexiconError, _known_keys)
    return LexiconSource(model, source, root)


def read_lexicon(path: Union[str, os.PathLike]) -> LexiconSource:
    """Return the validated lexicon file ``path``; LexiconError naming the file otherwise."""
    root, data = read_yaml(path, LexiconError)
    return parse_mapping(data, os.fspath(path), root)


def builtin_path() -> str:
    """Return the path of the built-in lexicon (``config/lexicon.yaml``)."""
    try:
        return str(config_path("lexicon.yaml"))
    except FileNotFoundError as err:
        raise LexiconError("lexicon.yaml", "", str(err)) from None
