"""The lexicon: how properties are said (realisation) and heard (the text parser).

* :mod:`.lexicon` -- :class:`Lexicon`: the realiser and the parser over one lexicon.
* :mod:`.source` -- lexicon files: structure, reading, extending the built-in one, checks.
* :mod:`.words` -- the tokenizer and the parser's phrase tables.
* :mod:`.coverage` -- what a lexicon cannot say of a scenario: one warning, a lexicon skeleton.
"""

from .lexicon import Domain, Entry, Lexicon, attribute_entry
from .coverage import coverage_warning, lexicon_template, unsayable  # noqa: I100 - after .lexicon, which it uses
from .source import LexiconError
from .words import ParseResult, tokenize

__all__ = ["Domain", "Entry", "Lexicon", "LexiconError", "ParseResult", "attribute_entry", "coverage_warning",
           "lexicon_template", "tokenize", "unsayable"]
