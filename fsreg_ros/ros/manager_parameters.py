"""The WM Manager node's parameters: ``domains`` checked, the rest declared, every change validated first.

Owns :class:`ManagerParameters`: ``domains`` (string array, required, read-only: names
that can be part of a service name, no domain twice, none clashing with a parameter),
the memory settings node-wide and per domain (:mod:`fsreg_ros.ros.memory_parameters`, from
the settings table) and ``service_timeout``.  A change is validated as the effective
policy of every domain and rejected with a reason if any is invalid, or if it changes a
node-wide setting a domain overrides (:func:`~fsreg_ros.ros.memory_parameters.check_change`).
What an accepted change does is the node's (it tells the core manager).
"""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    ParameterUninitializedException,
)
from rclpy.parameter import Parameter
from rclpy.validate_topic_name import validate_topic_name

from ..contract import manage_service
from ..core.forgetting.policies import ForgettingPolicy
from .carrier import log_warning
from .memory_parameters import SETTINGS, check_change, declare_memory_parameters, effective_policies, parameter_names
from .node_base import StartupError, accepted, descriptor, rejected

#: Range of ``service_timeout``, seconds.
TIMEOUT_RANGE = (0.01, 3600.0)


def declare_domains(node) -> list[str]:
    """Declare ``domains`` and return them; StartupError naming what is wrong with them."""
    node.declare_parameter(
        "domains",
        Parameter.Type.STRING_ARRAY,
        descriptor("consultant domains to manage (one consultant node each)", read_only=True),
    )
    try:
        names = [d for d in (node.get_parameter("domains").value or []) if d]
    except ParameterUninitializedException:
        names = []
    if not names:
        raise StartupError("parameter 'domains' must name at least one consultant domain")
    if len(set(names)) != len(names):
        raise StartupError(f"parameter 'domains' names a domain twice: {names}")
    for name in names:
        try:
            validate_topic_name(manage_service(name), is_service=True)
        except (InvalidServiceNameException, InvalidTopicNameException):
            raise StartupError(f"domain {name!r} cannot be part of a ROS service name") from None
        if name in SETTINGS or name == "service_timeout":
            raise StartupError(f"domain {name!r} clashes with a parameter name")
    return names


class ManagerParameters:
    """The parameters of a WM Manager node managing ``names``: declared at once (StartupError if invalid)."""

    def __init__(self, node, names: list[str]) -> None:
        self.node, self.names = node, names
        self.param_names = parameter_names(names) + ["service_timeout"]
        timeout = ParameterDescriptor(
            description="deadline of each consultant call, and of sync's wait for configuration, s",
            floating_point_range=[FloatingPointRange(from_value=TIMEOUT_RANGE[0], to_value=TIMEOUT_RANGE[1], step=0.0)],
        )
        try:
            declare_memory_parameters(node, names)
            node.declare_parameter("service_timeout", 10.0, timeout)
            self.policies()
        except (InvalidParameterTypeException, InvalidParameterValueException) as err:
            raise StartupError(" ".join(str(err).split())) from None
        except ValueError as err:
            raise StartupError(str(err)) from None

    @property
    def timeout(self) -> float:
        """``service_timeout`` now, seconds."""
        return float(self.node.get_parameter("service_timeout").value)

    def values(self) -> dict[str, Any]:
        """Every parameter this class owns (but ``domains``), by name, as set now."""
        return {name: self.node.get_parameter(name).value for name in self.param_names}

    def policies(self) -> dict[str, ForgettingPolicy]:
        """Every domain's effective policy from the parameters as set now; ValueError if invalid."""
        return effective_policies(self.values(), self.names)

    def on_set(self, params: list[Parameter]) -> SetParametersResult:
        """Accept a change only if every domain's effective policy stays valid (rclpy's on-set callback)."""
        values = self.values()
        changes = {param.name: param.value for param in params if param.name in values}
        if not changes:
            return accepted()
        try:
            check_change(values, changes, self.names)
        except ValueError as err:
            log_warning(self.node.get_logger(), f"rejected parameter change: {err}")
            return rejected(str(err))
        return accepted()

    def memory_changed(self, params: list[Parameter]) -> bool:
        """Whether ``params`` (set) include a memory setting (not only ``service_timeout``)."""
        return any(p.name in self.param_names and p.name != "service_timeout" for p in params)
