"""The lexicon: how properties are said (realisation) and heard (the text parser).

* :mod:`.lexicon` -- :class:`Lexicon`: the realiser and the parser over one lexicon, and its checks.
* :mod:`.source` -- lexicon files: structure, reading, extending the built-in one.
* :mod:`.words` -- the tokenizer and the parser's phrase tables.

What a lexicon cannot say of a scenario is :mod:`fsreg_ros.core.scenario.coverage`'s (the
scenario package builds on this one).
"""

from .lexicon import Domain, Entry, Lexicon, attribute_entry
from .source import LexiconError
from .words import ParseResult, tokenize

__all__ = ["Domain", "Entry", "Lexicon", "LexiconError", "ParseResult", "attribute_entry", "tokenize"]
