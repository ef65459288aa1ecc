"""The lexicon: English realisation of descriptions and the text parser stub.

SPEC section 4 (realisation paragraph) and section 5 (the ``text:`` paragraph).

* :meth:`Lexicon.realise` turns a description (a list of property names) into a
  referring expression without changing its content: the head noun comes from the
  first property with a ``noun`` in the description (``male`` -> "the man with ..."),
  else the domain's default noun ("the person with light hair, a lab coat and
  glasses").  Properties with an ``adjective`` become pre-modifiers sorted by their
  ``order`` (ties keep description order); all others become post-modifiers after
  "with", in description (selection) order, joined as "A", "A and B", "A, B and C".
  A second noun property is said as its adjective if it has one, else as a
  post-modifier.  A property the lexicon does not know is said as its name with
  ``-`` read as a space, as a post-modifier.
* :meth:`Lexicon.parse` is the TLDL parser stub: it maps text to the properties of a
  given collection, longest phrase first, in order of appearance (first occurrence
  wins), and reports the words it does not know.  Every property's name (with ``-``
  also read as a space), noun, adjective, post-modifier words and extra phrases are
  phrases for it; "without X" (any ``negators`` word) means the negation of X
  (``no-X``, or the property whose ``negates`` is X) where that is in play;
  function words are known and ignored.

So ``set(parse(realise(d, domain), props).properties) == set(d)`` for every
description over a domain's properties (tested, with hypothesis, on the shipped
lexicon).  The file format is described at the top of ``config/lexicon.yaml``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Any, Collection, Iterable, Mapping, Optional, Sequence

import yaml

from .paths import config_path

#: Used when the lexicon has no ``function_words`` (SPEC section 5's list).
DEFAULT_FUNCTION_WORDS = (
    "the", "a", "an", "with", "and", "in", "wearing", "who", "has", "is", "one", "person",
)
#: Used when the lexicon has no ``negators``.
DEFAULT_NEGATORS = ("without", "no", "not")
#: Default head nouns for domains the lexicon gives no ``noun`` (SPEC section 4).
DEFAULT_DOMAIN_NOUNS = {"faces": "person", "objects": "object", "locations": "place"}
#: Head noun for any other domain, unless the lexicon sets ``default_noun``.
FALLBACK_NOUN = "thing"
#: Words :meth:`Lexicon.realise` itself puts around the lexicon's words.
REALISER_WORDS = frozenset({"the", "with", "and"})
#: Kept compiled phrase tables (one per property collection parsed against).
TABLE_CACHE_SIZE = 128

_TOKEN = re.compile(r"[^\W_]+(?:['-][^\W_]+)*")
_TOP_KEYS = ("default_noun", "function_words", "negators", "domains", "properties")
_DOMAIN_KEYS = ("noun", "properties")
_ENTRY_KEYS = ("noun", "adjective", "order", "words", "article", "phrases", "negates")

Phrase = tuple[str, ...]


class LexiconError(ValueError):
    """A bad lexicon: the message names the file and the path inside it,
    e.g. ``lexicon.yaml: properties.male.noun: must be a string``."""


@dataclass(frozen=True)
class ParseResult:
    """What :meth:`Lexicon.parse` heard (SPEC section 5)."""

    properties: list[str]  # in order of appearance, no duplicates (first occurrence wins)
    unknown_words: list[str]  # words not known, in order (reported, never dropped)


def tokenize(text: str) -> list[str]:
    """Lower-cased words of ``text``; hyphens and apostrophes inside a word are kept,
    all other punctuation (commas, periods, quotes, ``=``) separates words."""
    return _TOKEN.findall(text.lower().replace("\u2019", "'"))


def _variants(text: str) -> list[Phrase]:
    """``text`` as a phrase, and again with ``-`` read as a space (if different)."""
    out = []
    for variant in (text, text.replace("-", " ")):
        phrase = tuple(tokenize(variant))
        if phrase and phrase not in out:
            out.append(phrase)
    return out


@dataclass(frozen=True)
class Entry:
    """How one property is said and heard (one ``properties:`` item of the lexicon)."""

    name: str
    noun: Optional[str] = None  # can head the description ("man")
    adjective: Optional[str] = None  # pre-modifier ("red")
    order: int = 0  # adjective order, ascending left to right
    words: str = ""  # post-modifier after "with" ("lab coat"); see :meth:`post_modifier`
    article: str = ""  # before ``words`` ("a")
    phrases: tuple[str, ...] = ()  # extra phrases for the parser
    negates: Optional[str] = None  # the property this one negates

    def post_modifier(self) -> str:
        """The text after "with": article and words ("a lab coat", "glasses")."""
        words = self.words or self.noun or self.name.replace("-", " ")
        return f"{self.article} {words}" if self.article else words

    def own_phrases(self) -> list[Phrase]:
        """The property's name, with ``-`` also read as a space."""
        return _variants(self.name)

    def other_phrases(self) -> list[Phrase]:
        """Noun, adjective, post-modifier words and extra phrases (and '-' variants)."""
        texts = [self.noun, self.adjective, self.words, *self.phrases]
        return [p for text in texts if text for p in _variants(text)]

    def positive(self) -> Optional[str]:
        """The property this one negates: ``negates``, else X for a name ``no-X``."""
        if self.negates:
            return self.negates
        if self.name.startswith("no-") and len(self.name) > 3:
            return self.name[3:]
        return None


@dataclass(frozen=True)
class Domain:
    """A ``domains:`` item: the default head noun and the member properties."""

    noun: Optional[str] = None
    properties: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Match:
    prop: str
    length: int  # in tokens


class _PhraseTable:
    """Phrases of one collection of properties, indexed by their first word.

    ``positive`` maps phrases of X to ``no-X`` (or whatever negates X) for the
    negative properties in play, for "without X".  Candidates are tried longest
    first, so matching is linear in the text length for a fixed lexicon.
    """

    def __init__(self, phrases: Iterable[tuple[Phrase, str]], negated: Iterable[tuple[Phrase, str]]):
        self._phrases = self._index(phrases)
        self._negated = self._index(negated)

    @staticmethod
    def _index(pairs: Iterable[tuple[Phrase, str]]) -> dict[str, list[tuple[Phrase, str]]]:
        owner: dict[Phrase, str] = {}
        for phrase, prop in pairs:
            owner.setdefault(phrase, prop)  # the first (most specific) claim wins
        index: dict[str, list[tuple[Phrase, str]]] = {}
        for phrase, prop in owner.items():
            index.setdefault(phrase[0], []).append((phrase, prop))
        for candidates in index.values():
            candidates.sort(key=lambda item: -len(item[0]))
        return index

    @staticmethod
    def _longest(index, tokens: Sequence[str], i: int) -> Optional[_Match]:
        if i >= len(tokens):
            return None
        for phrase, prop in index.get(tokens[i], ()):
            if tuple(tokens[i : i + len(phrase)]) == phrase:
                return _Match(prop, len(phrase))
        return None

    def match(self, tokens: Sequence[str], i: int) -> Optional[_Match]:
        """The longest phrase of a property in play starting at ``tokens[i]``."""
        return self._longest(self._phrases, tokens, i)

    def match_negated(self, tokens: Sequence[str], i: int) -> Optional[_Match]:
        """The longest phrase of X at ``tokens[i]``, as the negation of X in play."""
        return self._longest(self._negated, tokens, i)


class Lexicon:
    """Realiser and text parser over a validated lexicon (SPEC sections 4 and 5).

    Build with :meth:`load` (a YAML file; default ``config/lexicon.yaml``) or
    :meth:`from_mapping`.  Immutable after construction apart from a cache of
    compiled phrase tables, one per property collection passed to :meth:`parse`.
    """

    def __init__(
        self,
        entries: Mapping[str, Entry],
        domains: Mapping[str, Domain],
        function_words: Iterable[str] = DEFAULT_FUNCTION_WORDS,
        negators: Iterable[str] = DEFAULT_NEGATORS,
        default_noun: str = FALLBACK_NOUN,
        source: str = "<lexicon>",
    ):
        self.source = source
        self._entries = dict(entries)
        self._rank = {name: i for i, name in enumerate(self._entries)}
        self._domains = dict(domains)
        self.default_noun = default_noun
        self.negators = frozenset(negators)
        # Default nouns are words realise() emits, so the parser must know them too.
        nouns = {self.noun_for(d) for d in {*self._domains, *DEFAULT_DOMAIN_NOUNS}}
        known = {w for text in (*function_words, *nouns, default_noun) for w in tokenize(text)}
        self.function_words = frozenset(known)
        self._tables: dict[frozenset[str], _PhraseTable] = {}

    # -- construction ------------------------------------------------------------

    @classmethod
    def load(cls, path: str | os.PathLike | None = None) -> "Lexicon":
        """Read and validate a lexicon file; ``None`` means ``config_path("lexicon.yaml")``.

        Raises :class:`LexiconError` naming the file for a missing, unreadable,
        malformed or invalid file.
        """
        if path is None:
            try:
                path = config_path("lexicon.yaml")
            except FileNotFoundError as exc:
                raise LexiconError(str(exc)) from exc
        source = str(path)
        try:
            with open(path, encoding="utf-8") as handle:
                data = yaml.load(handle, Loader=_StrictLoader)  # noqa: S506 - SafeLoader subclass
        except OSError as exc:
            raise LexiconError(f"{source}: cannot read: {exc.strerror or exc}") from exc
        except _DuplicateKey as exc:
            raise LexiconError(f"{source}: line {exc.line}: duplicate key '{exc.key}'") from exc
        except yaml.YAMLError as exc:
            raise LexiconError(f"{source}: not valid YAML: {exc}") from exc
        if data is None:
            data = {}
        return cls.from_mapping(data, source)

    @classmethod
    def from_mapping(cls, data: Mapping, source: str = "<mapping>") -> "Lexicon":
        """Validate ``data`` (the parsed YAML) and build the lexicon; errors name ``source``."""
        return _Validator(source).lexicon(data)

    # -- queries -------------------------------------------------------------------

    @property
    def domains(self) -> tuple[str, ...]:
        """Domains the lexicon lists, in file order."""
        return tuple(self._domains)

    def properties(self, domain: Optional[str] = None) -> tuple[str, ...]:
        """Every property the lexicon describes (file order), or ``domain``'s members."""
        return tuple(self._entries) if domain is None else self.domain_properties(domain)

    def domain_properties(self, domain: str) -> tuple[str, ...]:
        """The properties the lexicon lists for ``domain`` (empty if none)."""
        entry = self._domains.get(domain)
        return entry.properties if entry else ()

    def entry(self, prop: str) -> Entry:
        """The lexical entry of ``prop`` (a default one if the lexicon lacks it)."""
        return self._entries.get(prop) or Entry(prop)

    def __contains__(self, prop: object) -> bool:
        return prop in self._entries

    def noun_for(self, domain: str) -> str:
        """The domain's default head noun: its ``noun``, else the built-in default
        (faces -> person, objects -> object, locations -> place), else ``default_noun``."""
        entry = self._domains.get(domain)
        if entry is not None and entry.noun:
            return entry.noun
        return DEFAULT_DOMAIN_NOUNS.get(domain, self.default_noun)

    # -- realisation (SPEC section 4) ---------------------------------------------

    def realise(self, description: Sequence[str], domain: str) -> str:
        """English for ``description`` in ``domain``; never adds or drops content.

        With the shipped lexicon, ``["light-hair", "lab-coat", "glasses"]`` in
        ``faces`` is "the person with light hair, a lab coat and glasses",
        ``["male", "dark-hair"]`` is "the man with dark hair" and
        ``["large", "red", "chair"]`` in ``objects`` is "the large red chair".
        """
        head: Optional[str] = None
        adjectives: list[Entry] = []
        post: list[str] = []
        for prop in dict.fromkeys(description):  # repeated properties are said once
            entry = self.entry(prop)
            if head is None and entry.noun:
                head = entry.noun
            elif entry.adjective:
                adjectives.append(entry)
            else:
                post.append(entry.post_modifier())
        adjectives.sort(key=lambda e: e.order)  # stable: ties keep description order
        words = ["the", *(e.adjective for e in adjectives), head or self.noun_for(domain)]
        text = " ".join(words)
        if post:
            text += " with " + _join(post)
        return text

    # -- parsing (SPEC section 5) --------------------------------------------------

    def parse(self, text: str, properties: Collection[str]) -> ParseResult:
        """Map ``text`` to properties of ``properties`` (longest phrase first, in order
        of appearance, first occurrence wins) and report the words not known.

        An unknown hyphenated word is retried as its parts ("dark-haired" -> "dark",
        "haired").  A negator before a phrase of X means the negation of X in play;
        if only X itself is in play, the negator and X's words are reported unknown
        rather than read as X.
        """
        table = self._table(properties)
        tokens = tokenize(text)
        found: dict[str, None] = {}
        unknown: list[str] = []
        i = 0
        while i < len(tokens):
            hit = table.match(tokens, i)
            if hit is not None:
                found.setdefault(hit.prop)
                i += hit.length
                continue
            word = tokens[i]
            if word in self.negators:
                j = i + 1
                while j < len(tokens) and tokens[j] in self.function_words and table.match(tokens, j) is None:
                    j += 1
                negated = table.match_negated(tokens, j)
                if negated is not None:
                    found.setdefault(negated.prop)
                    i = j + negated.length
                    continue
                positive = table.match(tokens, j)
                if positive is not None:  # "without hat" with no negation of hat in play
                    unknown.append(word)
                    unknown.extend(tokens[j : j + positive.length])
                    i = j + positive.length
                    continue
            if word in self.function_words:
                i += 1
            elif "-" in word:
                tokens[i : i + 1] = word.split("-")
            else:
                unknown.append(word)
                i += 1
        return ParseResult(properties=list(found), unknown_words=unknown)

    def _table(self, properties: Collection[str]) -> _PhraseTable:
        """The compiled phrase table for ``properties`` (cached by frozenset)."""
        key = frozenset(properties)
        table = self._tables.get(key)
        if table is None:
            if len(self._tables) >= TABLE_CACHE_SIZE:
                self._tables.clear()
            table = self._tables[key] = self._compile(key)
        return table

    def _compile(self, properties: frozenset[str]) -> _PhraseTable:
        # Deterministic claims on a shared phrase: own names first, then lexicon
        # order, then properties outside the lexicon by name.
        ranked = sorted(properties, key=lambda p: (self._rank.get(p, len(self._rank)), p))
        entries = [self.entry(p) for p in ranked]
        phrases = [(ph, e.name) for e in entries for ph in e.own_phrases()]
        phrases += [(ph, e.name) for e in entries for ph in e.other_phrases()]
        negated = []
        for e in entries:
            positive = e.positive()
            if positive:
                pos = self.entry(positive)
                negated += [(ph, e.name) for ph in (*pos.own_phrases(), *pos.other_phrases())]
        return _PhraseTable(phrases, negated)


def _join(items: Sequence[str]) -> str:
    """Join as 'A', 'A and B', 'A, B and C' (no Oxford comma)."""
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


# -- loading and validation ----------------------------------------------------------


class _DuplicateKey(yaml.YAMLError):
    def __init__(self, key: Any, line: int):
        super().__init__(f"duplicate key {key!r}")
        self.key = key
        self.line = line


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate mapping keys instead of keeping the last."""


def _construct_mapping(loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # unhashable key: let SafeLoader report it
            break
        if duplicate:
            raise _DuplicateKey(key, key_node.start_mark.line + 1)
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


class _Validator:
    """Plain checks of a lexicon mapping; every error names the source and the path."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, path: str, message: str) -> LexiconError:
        return LexiconError(f"{self.source}: {path}: {message}" if path else f"{self.source}: {message}")

    # generic shapes

    def mapping(self, value: Any, path: str, allowed: Optional[Sequence[str]] = None) -> Mapping:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise self.fail(path, "must be a mapping")
        for key in value:
            if not isinstance(key, str):
                raise self.fail(path, f"key {key!r} must be a string")
            if allowed is not None and key not in allowed:
                raise self.fail(_join_path(path, key), f"unknown key (allowed: {', '.join(allowed)})")
        return value

    def string(self, value: Any, path: str, *, words: bool = True) -> str:
        if not isinstance(value, str):
            raise self.fail(path, "must be a string")
        if words and not tokenize(value):
            raise self.fail(path, f"{value!r} has no words")
        return value

    def optional_string(self, data: Mapping, key: str, path: str) -> Optional[str]:
        value = data.get(key)
        return None if value is None else self.string(value, _join_path(path, key))

    def strings(self, value: Any, path: str) -> list[str]:
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.fail(path, "must be a list of strings")
        return [self.string(item, f"{path}[{i}]") for i, item in enumerate(value)]

    # the lexicon

    def lexicon(self, data: Any) -> Lexicon:
        data = self.mapping(data, "", _TOP_KEYS)
        default_noun = FALLBACK_NOUN
        if data.get("default_noun") is not None:
            default_noun = self.string(data["default_noun"], "default_noun")
        function_words = DEFAULT_FUNCTION_WORDS
        if "function_words" in data:
            function_words = tuple(self.strings(data["function_words"], "function_words"))
        negators = DEFAULT_NEGATORS
        if "negators" in data:
            negators = tuple(self.strings(data["negators"], "negators"))
        raw_props = self.mapping(data.get("properties"), "properties")
        entries = {name: self.entry(name, raw, f"properties.{name}") for name, raw in raw_props.items()}
        raw_domains = self.mapping(data.get("domains"), "domains")
        domains = {name: self.domain(raw, f"domains.{name}", entries) for name, raw in raw_domains.items()}
        lexicon = Lexicon(entries, domains, function_words, negators, default_noun, self.source)
        self.check_words(lexicon, entries)
        for name in domains:
            self.check_domain(lexicon, name)
        return lexicon

    def entry(self, name: str, raw: Any, path: str) -> Entry:
        data = self.mapping(raw, path, _ENTRY_KEYS)
        order = data.get("order", 0)
        if order is None:
            order = 0
        if isinstance(order, bool) or not isinstance(order, int):
            raise self.fail(f"{path}.order", "must be an integer")
        adjective = self.optional_string(data, "adjective", path)
        if "order" in data and adjective is None:
            raise self.fail(f"{path}.order", "only used with an adjective")
        article = data.get("article")
        article = "" if article is None else self.string(article, f"{path}.article", words=False).strip()
        negates = self.optional_string(data, "negates", path)
        if negates == name:
            raise self.fail(f"{path}.negates", "a property cannot negate itself")
        return Entry(
            name=name,
            noun=self.optional_string(data, "noun", path),
            adjective=adjective,
            order=order,
            words=self.optional_string(data, "words", path) or "",
            article=article,
            phrases=tuple(self.strings(data.get("phrases"), f"{path}.phrases")),
            negates=negates,
        )

    def domain(self, raw: Any, path: str, entries: Mapping[str, Entry]) -> Domain:
        data = self.mapping(raw, path, _DOMAIN_KEYS)
        members = self.strings(data.get("properties"), f"{path}.properties")
        seen = set()
        for i, prop in enumerate(members):
            if prop not in entries:
                raise self.fail(f"{path}.properties[{i}]", f"'{prop}' is not in properties")
            if prop in seen:
                raise self.fail(f"{path}.properties[{i}]", f"'{prop}' listed twice")
            seen.add(prop)
        return Domain(noun=self.optional_string(data, "noun", path), properties=tuple(members))

    def check_words(self, lexicon: Lexicon, entries: Mapping[str, Entry]) -> None:
        """Articles must be function words; no phrase may be only the realiser's words."""
        glue = set(REALISER_WORDS)
        for name, entry in entries.items():
            for word in tokenize(entry.article):
                if word not in lexicon.function_words:
                    raise self.fail(f"properties.{name}.article", f"'{word}' is not a function word")
                glue.add(word)
        for name, entry in entries.items():
            for phrase in (*entry.own_phrases(), *entry.other_phrases()):
                if set(phrase) <= glue:
                    raise self.fail(
                        f"properties.{name}", f"phrase '{' '.join(phrase)}' uses only the realiser's own words"
                    )

    def check_domain(self, lexicon: Lexicon, domain: str) -> None:
        """Within a domain each phrase has one owner and the default noun none."""
        owner: dict[Phrase, str] = {}
        for prop in lexicon.domain_properties(domain):
            entry = lexicon.entry(prop)
            for phrase in dict.fromkeys((*entry.own_phrases(), *entry.other_phrases())):
                other = owner.setdefault(phrase, prop)
                if other != prop:
                    raise self.fail(
                        f"domains.{domain}.properties",
                        f"phrase '{' '.join(phrase)}' belongs to both '{other}' and '{prop}'",
                    )
        noun = tuple(tokenize(lexicon.noun_for(domain)))
        if noun in owner:
            raise self.fail(
                f"domains.{domain}.noun",
                f"default noun '{' '.join(noun)}' is also a phrase of '{owner[noun]}'",
            )


def _join_path(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key
