"""Words and phrases: the tokenizer and the phrase tables of the text parser."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable, Optional, Sequence

_TOKEN = re.compile(r"[^\W_]+(?:['-][^\W_]+)*")

Phrase = tuple[str, ...]


@dataclass(frozen=True)
class ParseResult:
    """What :meth:`Lexicon.parse` heard."""

    properties: list[str]  # in order of appearance, no duplicates (first occurrence wins)
    unknown_words: list[str]  # words not known, in order (reported, never dropped)


def tokenize(text: str) -> list[str]:
    """Return the lower-cased words of ``text``.

    Hyphens and apostrophes inside a word are kept; all other punctuation
    (commas, periods, quotes, ``=``) separates words.
    """
    return _TOKEN.findall(text.lower().replace("\u2019", "'"))


def variants(text: str) -> list[Phrase]:
    """Return ``text`` as a phrase, and again with ``-`` read as a space (if different)."""
    out = []
    for variant in (text, text.replace("-", " ")):
        phrase = tuple(tokenize(variant))
        if phrase and phrase not in out:
            out.append(phrase)
    return out


@dataclass(frozen=True)
class Match:
    """A phrase of property ``prop`` found in the text, ``length`` tokens long."""

    prop: str
    length: int


class PhraseTable:
    """Phrases of one collection of properties, indexed by their first word.

    ``negated`` maps phrases of X to ``no-X`` (or whatever negates X) for the
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
    def _longest(index, tokens: Sequence[str], i: int) -> Optional[Match]:
        if i >= len(tokens):
            return None
        for phrase, prop in index.get(tokens[i], ()):
            if tuple(tokens[i: i + len(phrase)]) == phrase:
                return Match(prop, len(phrase))
        return None

    def match(self, tokens: Sequence[str], i: int) -> Optional[Match]:
        """Return the longest phrase of a property in play starting at ``tokens[i]``."""
        return self._longest(self._phrases, tokens, i)

    def match_negated(self, tokens: Sequence[str], i: int) -> Optional[Match]:
        """Return the longest phrase of X at ``tokens[i]``, as the negation of X in play."""
        return self._longest(self._negated, tokens, i)
