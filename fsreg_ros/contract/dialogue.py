"""Schemas of the dialogue pipeline: human utterances, their semantics, RR results, REG requests and expressions."""

from __future__ import annotations

from typing import Literal, Optional

from pydantic import model_validator

from .base import Id, Message, Number, Stamp
from .wm import Origin


class HumanUtterance(Stamp):
    """``dialogue/human``: what the human said, as text or as properties."""

    id: Id
    text: Optional[str] = None
    description: Optional[list[str]] = None
    domain: Optional[str] = None

    @model_validator(mode="after")
    def _one_form(self) -> "HumanUtterance":
        if (self.text is None) == (self.description is None):
            raise ValueError("give exactly one of 'text' and 'description'")
        return self


class Semantics(Stamp):
    """``dialogue/semantics``: the parser's reading of one utterance, for RR."""

    id: Id
    description: list[str]
    domain: Optional[str] = None
    text: Optional[str] = None
    unknown_words: Optional[list[str]] = None


class RRResult(Message):
    """``rr/result``: which entity the human meant (``status`` says how sure)."""

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


class RegRequest(Stamp):
    """``reg/request``: describe ``target`` (optionally against a context set)."""

    id: Id
    target: str
    context: Optional[list[str]] = None


class RegExpression(Message):
    """``reg/expression``: the referring expression for one request.

    ``origins`` is parallel to ``description``: for a property taken from WM, what had made
    it enter Q[target]; null for the others (alignment names it, core/alignment.py).
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


class RegError(Message):
    """``reg/expression`` for a request REG could not answer."""

    error: str
    id: Optional[Id] = None
    target: Optional[str] = None
    time: Optional[Number] = None
