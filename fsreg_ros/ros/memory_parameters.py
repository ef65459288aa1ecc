"""The WM Manager's memory parameters: one per row of the settings table, node-wide and per domain.

Generated from :mod:`fsreg_ros.core.forgetting.settings`: ``<setting>`` (the table's default, its
bounds as the declared range, its help as the description) for every domain, and
``<domain>.<setting>`` for one domain, defaulting to the row's inherit marker (``""``, 0,
or -1 for ``seed``: use the node-wide value).  A per-domain parameter declares no ROS
range (a range would have to include the marker, and rclpy's refusal would then say
"Min: 0" where the table says at least 1); its ``additional_constraints`` state the rule,
and the node refuses a value outside the table's bounds with the table's own words.
:func:`effective_policies` turns a set of values into each domain's policy, checked by
the core's rules, so a parameter change is validated as whole effective policies;
:func:`check_change` is the one check of a change at run time (the node's callback,
``fsreg-ctl set``): besides the policies, a node-wide setting that a domain overrides
would change nothing there, so changing it is refused with the reason (never
"successful" and ignored).
"""

from __future__ import annotations

from typing import Any, Optional, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from ..core.forgetting import settings
from ..core.forgetting.policies import ForgettingPolicy, PolicyError, check_setting

#: The memory settings, each a node-wide parameter and one per domain.
SETTINGS = settings.names()


def setting_descriptor(key: str, domain: Optional[str] = None) -> ParameterDescriptor:
    """Return a memory setting's descriptor, from its row of the settings table.

    A numeric setting's range is its bounds.  A per-domain setting has no declared
    range (its inherit marker is below the bounds, so it is never a real value, and a
    range cannot express "the marker or the bounds"): ``additional_constraints`` says
    the rule, :func:`effective_policies` enforces it.
    """
    row = settings.setting(key)
    text = row.description
    if domain is not None:
        text = f"domain '{domain}' {text}; {row.inherit!r} = inherit '{key}'"
    out = ParameterDescriptor(description=text)
    if not row.is_parameter:
        return out
    if domain is not None:
        out.additional_constraints = f"{row.inherit!r} (inherit) or {row.bounds_text}"
    elif row.choices:
        out.additional_constraints = row.bounds_text
    elif row.kind is float:
        out.floating_point_range = [FloatingPointRange(from_value=float(row.low), to_value=float(row.high), step=0.0)]
    else:
        out.integer_range = [IntegerRange(from_value=int(row.low), to_value=int(row.high), step=1)]
    return out


def parameter_names(domains: Sequence[str]) -> list[str]:
    """Return every memory parameter's name: the node-wide ones, then each domain's."""
    return list(SETTINGS) + [f"{d}.{key}" for d in domains for key in SETTINGS]


def declare_memory_parameters(node, domains: Sequence[str]) -> None:
    """Declare the memory parameters on ``node`` (rclpy raises if a given value is out of range)."""
    for row in settings.TABLE:
        node.declare_parameter(row.name, row.default, setting_descriptor(row.name))
    for domain in domains:
        for row in settings.TABLE:
            node.declare_parameter(f"{domain}.{row.name}", row.inherit, setting_descriptor(row.name, domain))


def effective_policies(values: dict[str, Any], domains: Sequence[str]) -> dict[str, ForgettingPolicy]:
    """Return every domain's effective policy from parameter values; ValueError naming what is invalid."""
    try:
        for key in SETTINGS:
            check_setting(key, values[key])
    except PolicyError as err:
        raise ValueError(str(err)) from None
    policies = {}
    for domain in domains:
        merged = {}
        for row in settings.TABLE:
            own = values[f"{domain}.{row.name}"]
            if own != row.inherit:
                try:
                    check_setting(row.name, own)
                except PolicyError as err:
                    raise ValueError(f"{domain}.{row.name}: {err} ({row.inherit!r} inherits '{row.name}')") from None
            merged[row.name] = values[row.name] if own == row.inherit else own
        try:
            policies[domain] = ForgettingPolicy.from_settings(merged)
        except PolicyError as err:
            raise ValueError(f"domain '{domain}': {err}") from None
    return policies


def check_change(current: dict[str, Any], changes: dict[str, Any],
                 domains: Sequence[str]) -> dict[str, ForgettingPolicy]:
    """Return every domain's effective policy after ``changes``; ValueError naming what is refused.

    Refused: an invalid policy (:func:`effective_policies`), and a node-wide setting
    changed while a domain sets its own (after the change): it would not apply there.
    """
    values = {**current, **changes}
    policies = effective_policies(values, domains)
    for key in SETTINGS:
        if key not in changes or changes[key] == current.get(key):
            continue
        inherit = settings.setting(key).inherit
        own = [d for d in domains if values[f"{d}.{key}"] != inherit]
        if own:
            given = ", ".join(f"{d}.{key}={values[f'{d}.{key}']!r}" for d in own)
            raise ValueError(f"{key}: not changed: {given} overrides the node-wide value (which applies only to "
                             f"domains that inherit it); set {own[0]}.{key} instead, or {own[0]}.{key}={inherit!r} "
                             "to inherit")
    return policies
