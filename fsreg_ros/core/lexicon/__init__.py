"""The lexicon: how properties are said (realisation) and heard (the text parser).

* :mod:`.lexicon` -- :class:`Lexicon`: the realiser and the parser over one lexicon.
* :mod:`.source` -- lexicon files: structure, reading, extending the built-in one, checks.
* :mod:`.words` -- the tokenizer and the parser's phrase tables.
"""

from .lexicon import Domain, Entry, Lexicon
from .source import LexiconError
from .words import ParseResult, tokenize

__all__ = ["Domain", "Entry", "Lexicon", "LexiconError", "ParseResult", "tokenize"]
