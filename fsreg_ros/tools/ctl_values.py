"""``fsreg-ctl``'s argument values: ``assert``'s facts and ``set``'s assignments, checked before anything is sent.

A memory setting's value is checked against the settings table
(:mod:`fsreg_ros.core.forgetting.settings`); a refused value is a :class:`UsageError`
naming the item and the rule (exit 2).
"""

from __future__ import annotations

from typing import Any, Sequence

from ..contract.codec import printable
from ..core.forgetting import settings
from .ctl_table import UsageError

#: Memory settings: applied to every domain unless given as DOMAIN.KEY.
MEMORY_KEYS = settings.names()


def parse_facts(items: Sequence[str]) -> dict[str, float]:
    """Return ``PROP`` / ``PROP:C`` items as property -> certainty."""
    facts: dict[str, float] = {}
    for item in items:
        prop, sep, value = item.rpartition(":")
        if not sep:
            prop, value = item, "1"
        try:
            certainty = float(value)
        except ValueError:
            raise UsageError(f"assert: {printable(repr(item), 80)}: the certainty after ':' must be a number in "
                             "[0, 1]") from None
        if not prop or not 0.0 <= certainty <= 1.0:
            raise UsageError(f"assert: {printable(repr(item), 80)}: give PROP or PROP:C with C in [0, 1]")
        facts[prop] = certainty
    return facts


def parse_assignments(items: Sequence[str], domains: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Return ``KEY=VALUE`` items as node -> {parameter: value} (see the module docstring).

    A memory setting's value is checked against the settings table here (``inherit``
    for a domain's setting is its inherit marker); other values stay text, converted to
    the parameter's declared type by the client.
    """
    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"set: {printable(repr(item), 80)}: expected KEY=VALUE")
        node, colon, name = key.rpartition(":")
        if colon:
            if not node or not name:
                raise UsageError(f"set: {printable(repr(item), 80)}: expected NODE:KEY=VALUE")
            if node == "wm_manager" and memory_key(name, domains):
                value = memory_value(item, name, value, domains)
            out.setdefault(node, {})[name] = value
        elif key in MEMORY_KEYS:
            if key == "policy" and value.strip() != "inherit":  # the node-wide value, checked as the node does
                check_node_wide(item, key, value, domains)
            for domain in domains:
                name = f"{domain}.{key}"
                out.setdefault("wm_manager", {})[name] = memory_value(item, name, value, domains)
        else:
            out.setdefault("wm_manager", {})[key] = memory_value(item, key, value, domains) \
                if memory_key(key, domains) else value
    return out


def check_node_wide(item: str, key: str, value: str, domains: Sequence[str]) -> None:
    """Refuse a value the WM Manager refuses for its node-wide ``key`` (an empty policy: WM would silently be off)."""
    from ..ros.node_parameters import ParameterError, check_parameter, node_parameters

    try:
        check_parameter(node_parameters("wm_manager", domains)[key], value)
    except ParameterError as err:
        said = str(err) if str(err).startswith(key) else f"{key}: {err}"
        raise UsageError(f"set {printable(item, 120)}: wm_manager: {said}") from None


def memory_key(name: str, domains: Sequence[str]) -> bool:
    domain, dot, key = name.rpartition(".")
    return key in MEMORY_KEYS and (not dot or domain in domains)


def memory_value(item: str, name: str, text: str, domains: Sequence[str]) -> Any:
    """Return a memory setting's value from text, checked against the settings table; UsageError naming the rule."""
    domain, dot, key = name.rpartition(".")
    row = settings.setting(key)
    where = f"set {printable(item, 120)}: wm_manager: {name}"
    inherit = f", or 'inherit' (use the node-wide {key})" if dot else ""
    if text.strip() == "inherit":
        if not dot:
            raise UsageError(f"{where}: only a domain's setting (DOMAIN.{key}) inherits")
        return row.inherit
    if not row.is_parameter:
        return text
    rule = f"{row.bounds_text}{inherit}"
    if row.choices:
        if text not in row.choices:
            raise UsageError(f"{where}: expected {rule}, got {printable(repr(text), 60)}")
        return text
    rule = f"{row.bounds_text}{inherit}"
    try:
        value: Any = int(text) if row.kind is int else float(text)
    except (ValueError, OverflowError):
        raise UsageError(f"{where}: expected {rule}, got {printable(repr(text), 60)}") from None
    try:
        settings.check_value(key, value)
    except settings.PolicyError as err:
        raise UsageError(f"{where}: {err} (allowed: {rule})") from None
    return value


def inherits(name: str, value: Any, domains: Sequence[str]) -> bool:
    """Return whether a domain's memory setting is at its inherit marker (it follows the node-wide value)."""
    domain, dot, key = name.rpartition(".")
    return bool(dot) and domain in domains and key in MEMORY_KEYS and value == settings.setting(key).inherit
