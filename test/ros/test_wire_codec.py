"""The one decoding of wire text (``contract.codec``): whatever arrives, a value or a one-line MessageError.

Issue 38.1: one ``ltm/assert`` of 76 kB whose ``id`` nested 3,000 deep killed the
consultant and the WM Manager: the oversized path read the id with a decoder that
raised ``RecursionError``.  Every reader of wire text (``parse``, ``id_of``,
``leading_id``) now goes through one decoder that refuses too deep a nesting, a lone
surrogate and non-finite numbers, and raises nothing but ``MessageError``.
"""

from __future__ import annotations

import pytest

from fsreg_ros.contract.codec import MAX_DEPTH, MessageError, TooLarge, id_of, leading_id, parse

#: The message of issue 38.1: over 64 KiB, its id an array nested 3,000 deep.
ISSUE_38 = '{"id":' + "[" * 3000 + "]" * 3000 + ',"pad":"' + "x" * 70_000 + '"}'


def nested(depth: int, inner: str = "") -> str:
    """An object whose field ``a`` nests arrays so that the whole text nests ``depth`` levels."""
    return '{"a":' + "[" * (depth - 1) + inner + "]" * (depth - 1) + "}"


def test_the_oversized_message_of_issue_38_is_refused_and_its_id_read_without_raising():
    with pytest.raises(TooLarge, match="over the limit of 65536"):
        parse(ISSUE_38, max_bytes=65_536)
    assert leading_id(ISSUE_38) is None  # an id nested 3,000 deep is no usable id
    assert id_of(ISSUE_38) is None


@pytest.mark.parametrize("text, expected", [
    (nested(MAX_DEPTH + 1), f"nested deeper than {MAX_DEPTH} levels: "),
    (nested(100_000), f"nested deeper than {MAX_DEPTH} levels: "),
    ("[" * 100_000, f"nested deeper than {MAX_DEPTH} levels: "),
    ('{"a":' + '{"b":' * 5_000 + "1" + "}" * 5_001, f"nested deeper than {MAX_DEPTH} levels: "),
    ('{"a": "x\\ud800"}', "a string with a lone surrogate (not Unicode): "),
    ('{"\\udfff": 1}', "a string with a lone surrogate (not Unicode): "),
    ('{"a": "x\ud800"}', "a string with a lone surrogate (not Unicode): "),  # the character itself, not escaped
    ('{"a": NaN}', "not JSON (NaN is not a JSON number)"),
    ('{"a": [1e999]}', "field 'a'[0]: 1e999 is too large for a number (not finite)"),
    ('{"a": ' + "9" * 5000 + "}", "not JSON (Exceeds the limit (4300 digits)"),
    ("null", "expected a JSON object, got null"),
    ('{"a": 1} x', "not JSON (Extra data"),
], ids=["33-deep", "100000-deep", "array-100000-deep", "objects-5000-deep", "lone-surrogate", "surrogate-key",
        "raw-surrogate", "nan", "1e999", "5000-digits", "null", "trailing"])
def test_every_hostile_text_is_refused_in_one_line_and_nothing_else_raises(text, expected):
    with pytest.raises(MessageError) as info:
        parse(text, max_bytes=1_000_000)
    assert str(info.value).startswith(expected)
    assert "\n" not in str(info.value) and len(str(info.value)) < 300
    assert id_of(text) is None  # no id is read off a refused text


def test_the_contracts_depth_and_unicode_are_accepted():
    assert parse(nested(MAX_DEPTH))["a"]  # the deepest nesting allowed
    assert parse('{"a": "\\ud83d\\ude00 \\u00e9"}') == {"a": "\U0001F600 \u00e9"}  # a surrogate pair is a character
    assert parse('{"id": 7, "facts": [{"entity": "e", "properties": {"p": 1.0}}]}')["id"] == 7
    assert parse('{"id": 1, "id": 2}') == {"id": 2}  # a key twice: the last counts, for every reader here


@pytest.mark.parametrize("text, rid", [
    ('{"id": "r1", "pad": "' + "x" * 70_000 + '"}', "r1"),
    ('{"id": [[1]], "pad": "' + "x" * 70_000 + '"}', None),
    ('{"id": "\\ud800", "pad": "' + "x" * 70_000 + '"}', None),
    ('{"x": {"id": 3}, "id": 5, "pad": "' + "x" * 70_000 + '"}', 5),
    ('{"id": ' + "[" * 40_000, None),
])
def test_an_oversized_messages_id_is_read_off_its_head_and_never_raises(text, rid):
    assert leading_id(text) == rid
