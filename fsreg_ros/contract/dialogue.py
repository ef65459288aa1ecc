"""Schemas of the dialogue pipeline: human utterances, their semantics, RR results, REG requests and expressions.

Every request carries an ``id`` with one meaning and may carry a ``client`` (the
requester's own name); every answer echoes both, and the request's fingerprint as
``request`` (:mod:`fsreg_ros.contract.attribution`).  An error of kind ``IdConflict``
names the request holding the id in ``conflicts_with``.
"""

from __future__ import annotations

from typing import Literal, Optional

from pydantic import model_validator

from .base import Id, Message, Name, Names, Number, RequestRef, Stamp
from .wm import EntryStrength, Origin


class Request(Stamp):
    """A request of the pipeline: its ``id``, and optionally who sends it (``client``, echoed in the answer)."""

    id: Id
    client: Optional[Name] = None


class HumanUtterance(Request):
    """``dialogue/human``: what the human said, as text or as properties."""

    text: Optional[str] = None
    description: Optional[Names] = None
    domain: Optional[Name] = None

    @model_validator(mode="after")
    def _one_form(self) -> "HumanUtterance":
        if (self.text is None) == (self.description is None):
            raise ValueError("give exactly one of 'text' and 'description'")
        return self


class Semantics(Request):
    """``dialogue/semantics``: the parser's reading of one utterance, for RR.

    ``request``: the fingerprint of the utterance it was read from (RR's answer echoes it).
    """

    description: Names
    request: Optional[str] = None
    domain: Optional[Name] = None
    text: Optional[str] = None
    unknown_words: Optional[list[str]] = None


class RRResult(Message):
    """``rr/result``: which entity the human meant (``status`` says how sure), or why not (``error``)."""

    id: Optional[Id] = None
    time: Optional[Number] = None
    status: Literal["resolved", "ambiguous", "no-match", "error"]
    resolved: Optional[str] = None
    candidates: list[str] = []
    description: list[str] = []
    domain: Optional[str] = None
    text: Optional[str] = None
    unknown_words: Optional[list[str]] = None
    error: Optional[str] = None
    kind: Optional[str] = None
    conflicts_with: Optional[RequestRef] = None
    client: Optional[str] = None
    request: Optional[str] = None


class RegRequest(Request):
    """``reg/request``: describe ``target`` (optionally against a context set)."""

    target: Name
    context: Optional[Names] = None


class RegExpression(Message):
    """``reg/expression``: the referring expression for one request.

    ``origins`` is parallel to ``description``: for a property taken from WM, what had made
    it enter Q[target]; null for the others (alignment names it, core/algorithms/alignment.py).
    ``strengths`` is parallel to it too: for a property taken from WM, how strongly its entry
    was held when REG looked (episode age, episodes used in, activation); null for the others.
    """

    id: Id
    target: str
    time: Number
    domain: str
    algorithm: str
    description: list[str]
    sources: list[str]
    distinguishing: bool
    distractors_left: list[str]
    wm_before: list[str]
    text: str
    origins: list[Optional[Origin]] = []
    strengths: list[Optional[EntryStrength]] = []
    client: Optional[str] = None
    request: Optional[str] = None


class RegError(Message):
    """``reg/expression`` for a request REG could not answer."""

    error: str
    id: Optional[Id] = None
    target: Optional[str] = None
    time: Optional[Number] = None
    kind: Optional[str] = None
    conflicts_with: Optional[RequestRef] = None
    client: Optional[str] = None
    request: Optional[str] = None
