"""The lexicon: English realisation of descriptions and the text parser stub (one model).

Realisation of robot descriptions and parsing of the human's ``text:`` turns.

* :meth:`Lexicon.realise` turns a description (a list of property names) into a
  referring expression without changing its content: the head noun comes from the
  first property with a ``noun`` in the description (``male`` -> "the man with ..."),
  else the domain's default noun ("the person with light hair, a lab coat and
  glasses").  Properties with an ``adjective`` become pre-modifiers sorted by their
  ``order`` (ties keep description order); all others become post-modifiers after
  "with", in description (selection) order, joined as "A", "A and B", "A, B and C".
  A second noun property is said as its adjective if it has one, else as a
  post-modifier.
* A property the lexicon does not list is said by a documented default
  (:func:`attribute_entry`): an ``attribute=value`` name whose value is a word is said
  as its value, as the head noun when the attribute is ``type``, ``kind``, ``shape``,
  ``category`` or ``class`` (``shape=cube`` -> "the ... cube"), else as an adjective in
  conventional English order by attribute (:data:`ATTRIBUTE_ORDER`: size before age
  before shape before colour before origin and material, so ``size=small``,
  ``colour=red``, ``shape=cube`` is "the small red cube").  Anything else (a plain
  name, a numeric or boolean value) is said as its name with ``-``, ``_`` and ``=``
  read as spaces, as a post-modifier; :meth:`Lexicon.can_say` is false for it, and
  :mod:`.coverage` lists such properties in one warning and writes a lexicon skeleton
  for them.
* :meth:`Lexicon.parse` is the TLDL parser stub: it maps text to the properties of a
  given collection, longest phrase first, in order of appearance (first occurrence
  wins), and reports the words it does not know.  Every property's name (with ``-``
  also read as a space), noun, adjective, post-modifier words and extra phrases are
  phrases for it; "without X" (any ``negators`` word) means the negation of X
  (``no-X``, or the property whose ``negates`` is X) where that is in play;
  function words are known and ignored.

So ``set(parse(realise(d, domain), props).properties) == set(d)`` for every
description over a domain's properties (tested, with hypothesis, on the shipped
lexicon).  The file format is described at the top of ``config/lexicon.yaml``; reading
and extending files is :mod:`.source`'s job, words and phrases :mod:`.words`'s; the checks
that need the built lexicon are :func:`check`, here.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Collection, Iterable, Mapping, Optional, Sequence

from ..io.yaml_source import PathLoc
from .source import REALISER_WORDS, EntryBlock, LexiconSource, builtin_path, parse_mapping, read_lexicon
from .words import ParseResult, Phrase, PhraseTable, tokenize, variants

#: Used when the lexicon has no ``function_words`` (the parser stub's list).
DEFAULT_FUNCTION_WORDS = (
    "the", "a", "an", "with", "and", "in", "wearing", "who", "has", "is", "one", "person",
)
#: Used when the lexicon has no ``negators``.
DEFAULT_NEGATORS = ("without", "no", "not")
#: Default head nouns for domains the lexicon gives no ``noun``.
DEFAULT_DOMAIN_NOUNS = {"faces": "person", "objects": "object", "locations": "place"}
#: Head noun for any other domain, unless the lexicon sets ``default_noun``.
FALLBACK_NOUN = "thing"
#: Kept compiled phrase tables (one per property collection parsed against).
TABLE_CACHE_SIZE = 128
#: Attributes whose value names the thing itself: said as the head noun (``shape=cube`` -> "cube").
HEAD_ATTRIBUTES = ("type", "kind", "shape", "category", "class")
#: Adjective order of ``attribute=value`` properties the lexicon does not list, by attribute (conventional
#: English order: opinion, size, age, shape, colour, origin, material; position words first).  Attributes are
#: compared lower-cased; a name ending in ``colour``/``color`` counts as colour.  Others: :data:`OTHER_ORDER`.
ATTRIBUTE_ORDER = {
    "position": 5, "side": 5, "location": 5,
    "quality": 10, "opinion": 10, "condition": 10, "state": 10,
    "size": 20, "height": 20, "length": 20, "width": 20, "weight": 20,
    "age": 30,
    "texture": 40, "pattern": 40, "finish": 40,
    "colour": 50, "color": 50, "hue": 50, "shade": 50,
    "orientation": 60, "direction": 60,
    "origin": 65, "material": 70, "purpose": 75,
}
OTHER_ORDER = 45
#: Values that are not words to say (flags and counts).
FLAG_VALUES = frozenset({"true", "false", "yes", "no", "on", "off", "none", "null"})


def attribute_entry(prop: str) -> Optional["Entry"]:
    """Return the default entry of an ``attribute=value`` property (None if ``prop`` is not one with a word value).

    See the module docstring: the value is the head noun for :data:`HEAD_ATTRIBUTES`,
    else an adjective ordered by :data:`ATTRIBUTE_ORDER`.
    """
    attribute, sep, value = prop.partition("=")
    words = " ".join(tokenize(value.replace("_", " ")))
    if not sep or not attribute.strip() or not words or words in FLAG_VALUES:
        return None
    if any(ch.isdigit() for ch in words):  # counts and codes are not words to say
        return None
    key = attribute.strip().lower()
    if key in HEAD_ATTRIBUTES:
        return Entry(prop, noun=words)
    order = ATTRIBUTE_ORDER.get(key)
    if order is None:
        order = ATTRIBUTE_ORDER["colour"] if key.endswith(("colour", "color")) else OTHER_ORDER
    return Entry(prop, adjective=words, order=order)


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

    @classmethod
    def from_block(cls, name: str, block: EntryBlock) -> "Entry":
        """Return the entry of property ``name`` as a lexicon file gives it."""
        return cls(
            name=name,
            noun=block.noun,
            adjective=block.adjective,
            order=block.order or 0,
            words=block.words or "",
            article=(block.article or "").strip(),
            phrases=tuple(block.phrases or ()),
            negates=block.negates,
        )

    def post_modifier(self) -> str:
        """Return the text after "with": article and words ("a lab coat", "glasses").

        Without words or a noun: the name, with ``-``, ``_`` and ``=`` read as spaces.
        """
        words = self.words or self.noun or " ".join(self.name.replace("_", " ").replace("=", " ").split("-"))
        return f"{self.article} {words}" if self.article else words

    def own_phrases(self) -> list[Phrase]:
        """Return the property's name as phrases, with ``-`` also read as a space."""
        return variants(self.name)

    def other_phrases(self) -> list[Phrase]:
        """Noun, adjective, post-modifier words and extra phrases (and '-' variants)."""
        texts = [self.noun, self.adjective, self.words, *self.phrases]
        return [p for text in texts if text for p in variants(text)]

    def positive(self) -> Optional[str]:
        """Return the property this one negates: ``negates``, else X for a name ``no-X``."""
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


class Lexicon:
    """Realiser and text parser over a validated lexicon.

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
        self._tables: dict[frozenset[str], PhraseTable] = {}

    # -- construction ------------------------------------------------------------

    @classmethod
    def load(cls, path: str | os.PathLike | None = None) -> "Lexicon":
        """Return the built-in lexicon (``config/lexicon.yaml``), extended by the file ``path`` if given.

        Raises :class:`LexiconError` naming the file for a missing, unreadable,
        malformed or invalid file.
        """
        builtin = read_lexicon(builtin_path())
        if path is None:
            return cls.from_source(builtin)
        return cls.from_source(builtin.extended_by(read_lexicon(path)))

    @classmethod
    def from_mapping(cls, data: Any, source: str = "<mapping>") -> "Lexicon":
        """Return the lexicon ``data`` (the parsed YAML, on its own); errors name ``source``."""
        return cls.from_source(parse_mapping(data, source))

    @classmethod
    def from_source(cls, where: LexiconSource) -> "Lexicon":
        """Return the lexicon of a validated file, after the checks of :func:`.source.check`."""
        model = where.model
        entries = {
            name: Entry.from_block(name, block or EntryBlock()) for name, block in (model.properties or {}).items()
        }
        domains = {
            name: Domain(block.noun, tuple(dict.fromkeys(block.properties or ()))) if block else Domain()
            for name, block in (model.domains or {}).items()
        }
        lexicon = cls(
            entries,
            domains,
            DEFAULT_FUNCTION_WORDS if model.function_words is None else tuple(model.function_words),
            DEFAULT_NEGATORS if model.negators is None else tuple(model.negators),
            model.default_noun or FALLBACK_NOUN,
            where.source,
        )
        check(lexicon, where)
        return lexicon

    # -- queries -------------------------------------------------------------------

    @property
    def domains(self) -> tuple[str, ...]:
        """Domains the lexicon lists, in file order."""
        return tuple(self._domains)

    def properties(self, domain: Optional[str] = None) -> tuple[str, ...]:
        """Every property the lexicon describes (file order), or ``domain``'s members."""
        return tuple(self._entries) if domain is None else self.domain_properties(domain)

    def domain_properties(self, domain: str) -> tuple[str, ...]:
        """Return the properties the lexicon lists for ``domain`` (empty if none)."""
        entry = self._domains.get(domain)
        return entry.properties if entry else ()

    def entry(self, prop: str) -> Entry:
        """Return the lexical entry of ``prop``: the lexicon's, else the default (:func:`attribute_entry`; its name)."""
        return self._entries.get(prop) or attribute_entry(prop) or Entry(prop)

    def __contains__(self, prop: object) -> bool:
        return prop in self._entries

    def can_say(self, prop: str) -> bool:
        """Return whether ``prop`` is said in words of its own: listed, or an ``attribute=value`` with a word value."""
        return prop in self._entries or attribute_entry(prop) is not None

    def noun_for(self, domain: str) -> str:
        """Return the domain's default head noun.

        That is its ``noun``, else the built-in default (faces -> person,
        objects -> object, locations -> place), else ``default_noun``.
        """
        entry = self._domains.get(domain)
        if entry is not None and entry.noun:
            return entry.noun
        return DEFAULT_DOMAIN_NOUNS.get(domain, self.default_noun)

    # -- realisation ---------------------------------------------

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

    # -- parsing --------------------------------------------------

    def parse(self, text: str, properties: Collection[str]) -> ParseResult:
        """Map ``text`` to properties of ``properties`` and report the words not known.

        Longest phrase first, in order of appearance, first occurrence wins.

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
                    unknown.extend(tokens[j: j + positive.length])
                    i = j + positive.length
                    continue
            if word in self.function_words:
                i += 1
            elif "-" in word:
                tokens[i: i + 1] = word.split("-")
            else:
                unknown.append(word)
                i += 1
        return ParseResult(properties=list(found), unknown_words=unknown)

    def _table(self, properties: Collection[str]) -> PhraseTable:
        """Return the compiled phrase table for ``properties`` (cached by frozenset)."""
        key = frozenset(properties)
        table = self._tables.get(key)
        if table is None:
            if len(self._tables) >= TABLE_CACHE_SIZE:
                self._tables.clear()
            table = self._tables[key] = self._compile(key)
        return table

    def _compile(self, properties: frozenset[str]) -> PhraseTable:
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
        return PhraseTable(phrases, negated)


def _join(items: Sequence[str]) -> str:
    """Join as 'A', 'A and B', 'A, B and C' (no Oxford comma)."""
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def check(lexicon: Lexicon, where: LexiconSource) -> None:
    """Check what needs more than types; raise LexiconError naming ``where``'s file.

    Entries: ``order`` only with an adjective, no property negating itself;
    articles are function words; no phrase is only the realiser's own words.
    Domains: members are listed properties, once each; within a domain each
    phrase has one owner and the default noun none.
    """
    glue = set(REALISER_WORDS)
    for name, block in (where.model.properties or {}).items():
        block = block or EntryBlock()
        if block.order is not None and block.adjective is None:
            raise where.fail(("properties", name, "order"), "only used with an adjective")
        if block.negates == name:
            raise where.fail(("properties", name, "negates"), "a property cannot negate itself")
        for word in tokenize(block.article or ""):
            if word not in lexicon.function_words:
                raise where.fail(("properties", name, "article"), f"'{word}' is not a function word")
            glue.add(word)
    for name in lexicon.properties():
        entry = lexicon.entry(name)
        for phrase in (*entry.own_phrases(), *entry.other_phrases()):
            if set(phrase) <= glue:
                said = " ".join(phrase)
                raise where.fail(("properties", name), f"phrase '{said}' uses only the realiser's own words")
    for domain in where.model.domains or {}:
        seen: set[str] = set()
        for i, prop in enumerate(where.own_members(domain)):  # the file's own list: errors name its own items
            if prop not in lexicon:
                raise where.fail(("domains", domain, "properties", i), f"'{prop}' is not in properties")
            if prop in seen:
                raise where.fail(("domains", domain, "properties", i), f"'{prop}' listed twice")
            seen.add(prop)
        _check_domain_phrases(lexicon, domain, where)


def _check_domain_phrases(lexicon: Lexicon, domain: str, where: LexiconSource) -> None:
    owner: dict[Phrase, str] = {}
    for prop in lexicon.domain_properties(domain):
        entry = lexicon.entry(prop)
        for phrase in dict.fromkeys((*entry.own_phrases(), *entry.other_phrases())):
            other = owner.setdefault(phrase, prop)
            if other != prop:
                own = where.own_members(domain)
                culprit = prop if prop in own else other
                loc: PathLoc = ("domains", domain, "properties") + ((own.index(culprit),) if culprit in own else ())
                raise where.fail(loc, f"phrase '{' '.join(phrase)}' belongs to both '{other}' and '{prop}'")
    noun = tuple(tokenize(lexicon.noun_for(domain)))
    if noun in owner:
        message = f"default noun '{' '.join(noun)}' is also a phrase of '{owner[noun]}'"
        raise where.fail(("domains", domain, "noun"), message)
