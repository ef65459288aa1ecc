"""Node parameters of a live graph read and set by a client (:class:`ParameterAccess`, a part of ``GraphClient``).

Through each node's rcl_interfaces parameter services: list, describe, get, and set
atomically, every value checked before anything is sent (the node and the parameter
exist, not read-only, of the declared type and range, the node's own checks as data
from :mod:`fsreg_ros.ros.node_parameters`, the WM Manager's memory settings as a whole
policy), then read back.  Conversions between text or Python values and
``ParameterValue`` are module functions.
"""

from __future__ import annotations

import difflib
import time
from typing import Any, Mapping, Optional, Sequence

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParametersAtomically

from ..contract.codec import printable
from .client_base import ClientError, Spinning, describe_graph


class ParameterAccess(Spinning):
    """Parameter services of the graph's nodes (state set up by ``GraphClient``: ``_param_clients``).

    Uses ``node_names`` and ``domains`` from the client's readiness.
    """

    def _param_client(self, node_name: str, srv_type, suffix: str):
        key = (node_name, suffix)
        if key not in self._param_clients:
            self._param_clients[key] = self.node.create_client(srv_type, f"{node_name}/{suffix}")
        return self._param_clients[key]

    def _service_call(self, client, request, timeout: float, what: str):
        """Call a parameter service (idempotent: sent again after 2, 4, ... s without a reply, until ``timeout``)."""
        self.spin_until(client.service_is_ready, timeout, f"{what}: service {client.srv_name} is not available",
                        "not-ready")
        deadline, attempt = time.monotonic() + timeout, 2.0
        while True:
            future = client.call_async(request)
            try:
                self.spin_until(future.done, min(attempt, max(0.0, deadline - time.monotonic())), what)
                return future.result()
            except ClientError:
                client.remove_pending_request(future)
                if time.monotonic() >= deadline:
                    raise
                attempt *= 2

    def require_node(self, node_name: str, timeout: Optional[float] = None) -> None:
        """Raise ClientError unless ``node_name`` is a node of the graph whose parameter services answer.

        ``usage`` at once for a name the graph does not have (:meth:`node_names`);
        ``not-ready`` if its parameter services are not found within ``timeout``.
        """
        if node_name not in self.node_names():
            raise ClientError(f"no node {printable(repr(node_name), 80)} in graph {describe_graph(self.graph)} (its "
                              f"nodes: {', '.join(self.node_names())})", "usage")
        client = self._param_client(node_name, ListParameters, "list_parameters")
        self.spin_until(client.service_is_ready, self.timeout if timeout is None else timeout,
                        f"{node_name}: service {client.srv_name} is not available", "not-ready")

    def list_parameters(self, node_name: str, timeout: Optional[float] = None) -> list[str]:
        """Return the names of node ``node_name``'s parameters, sorted."""
        timeout = self.timeout if timeout is None else timeout
        client = self._param_client(node_name, ListParameters, "list_parameters")
        reply = self._service_call(client, ListParameters.Request(), timeout, f"{node_name}: list parameters")
        return sorted(reply.result.names)

    def describe_parameters(self, node_name: str, names: Sequence[str], timeout: Optional[float] = None) -> dict:
        """Return node ``node_name``'s descriptors of ``names`` (rcl_interfaces ParameterDescriptor), by name."""
        timeout = self.timeout if timeout is None else timeout
        client = self._param_client(node_name, DescribeParameters, "describe_parameters")
        reply = self._service_call(client, DescribeParameters.Request(names=list(names)), timeout,
                                   f"{node_name}: describe parameters")
        return dict(zip(names, reply.descriptors))

    def get_parameters(self, node_name: str, names: Optional[Sequence[str]] = None,
                       timeout: Optional[float] = None) -> dict[str, Any]:
        """Return node ``node_name``'s parameter values (all of them without ``names``), as Python values."""
        timeout = self.timeout if timeout is None else timeout
        names = self.list_parameters(node_name, timeout) if names is None else list(names)
        client = self._param_client(node_name, GetParameters, "get_parameters")
        reply = self._service_call(client, GetParameters.Request(names=names), timeout,
                                   f"{node_name}: get parameters")
        return {name: python_value(value) for name, value in zip(names, reply.values)}

    def set_parameters(self, node_name: str, values: Mapping[str, Any], timeout: Optional[float] = None) -> dict:
        """Set parameters of node ``node_name`` (e.g. ``wm_manager``) all at once, or none; the values now in force.

        Checked before anything is sent, each error naming the node, the key and what is
        allowed (ClientError ``usage``): a node or parameter the graph does not have, a
        read-only parameter, a value of the wrong type or outside the declared range
        (converted from text to the declared type first), and for the WM Manager the
        memory settings as the whole effective policy of every domain.  A change the
        node refuses raises ``rejected`` with its reason.  The values returned are read
        back from the node after the change.
        """
        return self.set_many({node_name: values}, timeout)[node_name]

    def set_many(self, changes: Mapping[str, Mapping[str, Any]], timeout: Optional[float] = None) -> dict:
        """Set parameters of several nodes (node -> values): every value of every node checked first, then all or none.

        As :meth:`set_parameters` for each node; nothing is sent until every node's
        values passed the checks.  Should a node still refuse its change, the nodes set
        before it are set back to the values they had, and the error says so.
        Returns node -> the values now in force (read back).
        """
        timeout = self.timeout if timeout is None else timeout
        checked = {node: self._checked(node, values, timeout) for node, values in changes.items()}
        # what a later node's refusal would set back: every node but the last (one node: nothing to read)
        before = {node: self.get_parameters(node, list(values), timeout) for node, values in list(changes.items())[:-1]}
        done: list[str] = []
        for node, messages in checked.items():
            try:
                self._apply(node, messages, timeout)
            except ClientError as err:
                undone = self._undo(done, before, timeout)
                raise ClientError(f"{err}{undone}", err.kind) from None
            done.append(node)
        return {node: self.get_parameters(node, list(values), timeout) for node, values in changes.items()}

    def _undo(self, done: Sequence[str], before: Mapping[str, Mapping[str, Any]], timeout: float) -> str:
        """Set the nodes in ``done`` back to ``before``; what the error adds (nothing when none was set)."""
        if not done:
            return ""
        try:
            for node in done:
                self._apply(node, self._checked(node, before[node], timeout, check=False), timeout)
        except ClientError as err:
            return f" ({', '.join(done)} changed and could not be set back: {err})"
        return f" (nothing changed: {', '.join(done)} set back)"

    def _apply(self, node_name: str, messages: list, timeout: float) -> None:
        setter = self._param_client(node_name, SetParametersAtomically, "set_parameters_atomically")
        result = self._service_call(setter, SetParametersAtomically.Request(parameters=messages), timeout,
                                    f"{node_name}: set parameters").result
        if not result.successful:
            raise ClientError(f"{node_name} refused {', '.join(m.name for m in messages)}: "
                              f"{result.reason or 'no reason given'}", "rejected")

    def _checked(self, node_name: str, values: Mapping[str, Any], timeout: float, check: bool = True) -> list:
        """Return ``values`` as the Parameter messages to send, after every check (:meth:`set_parameters`).

        ``check`` false: only the type conversion and the node's read-only and range checks.
        """
        from . import node_parameters
        from .memory_parameters import check_change, parameter_names

        self.require_node(node_name, timeout)
        known = self.list_parameters(node_name, timeout)
        names = list(values)
        for name in names:
            if name not in known:
                close = difflib.get_close_matches(name, known, n=1)
                hint = f"did you mean {close[0]}?" if close else f"its parameters: {', '.join(known)}"
                raise ClientError(f"{node_name}: no parameter {printable(repr(name), 80)} ({hint})", "usage")
        described = self.describe_parameters(node_name, names, timeout)
        executable = "consultant" if node_name.startswith("consultant_") else node_name
        catalogue = node_parameters.node_parameters(executable, self.domains())
        messages, typed = [], {}
        for name in names:
            desc = described[name]
            if desc.read_only:
                runner = name in catalogue and catalogue[name].runner
                source = f"by fsreg-up from {node_parameters.RUNNER_SOURCES.get(name, 'its options')}" if runner \
                    else "fsreg-up --params-file"
                raise ClientError(f"{node_name}: {name} is read-only (set when the node starts: {source})", "usage")
            value = parameter_value(f"{node_name}: {name}", values[name], desc.type)
            typed[name] = python_value(value)
            problem = range_problem(desc, typed[name])
            if problem:
                raise ClientError(f"{node_name}: {name}: {problem}", "usage")
            messages.append(ParameterMsg(name=name, value=value))
        if not check:  # values read back from the node, set back after a refusal elsewhere
            return messages
        for name in names:  # the node's own checks (choices, the settings table), as data
            if name in catalogue:
                try:
                    node_parameters.check_parameter(catalogue[name], typed[name])
                except node_parameters.ParameterError as err:
                    raise ClientError(f"{node_name}: {name}: {err}", "usage") from None
        if node_name == "wm_manager" and any(n in parameter_names(self.domains()) for n in names):
            current = self.get_parameters(node_name, parameter_names(self.domains()), timeout)
            try:
                check_change(current, typed, self.domains())
            except ValueError as err:
                raise ClientError(f"{node_name}: {printable(str(err), 300)}", "usage") from None
        return messages


def parameter_value(name: str, value: Any, kind: int) -> ParameterValue:
    """Return ``value`` (text from a command line, or a Python value) as a ParameterValue of type ``kind``."""
    out = ParameterValue(type=kind)
    text = value if isinstance(value, str) else None
    try:
        if kind == ParameterType.PARAMETER_BOOL:
            if text is not None:
                lowered = text.strip().lower()
                if lowered not in ("true", "false"):
                    raise ValueError
                value = lowered == "true"
            if not isinstance(value, bool):
                raise ValueError
            out.bool_value = value
        elif kind == ParameterType.PARAMETER_INTEGER:
            number = int(text.strip()) if text is not None else value
            if isinstance(number, bool) or not isinstance(number, int) or not -2**63 <= number < 2**63:
                raise ValueError
            out.integer_value = number
        elif kind == ParameterType.PARAMETER_DOUBLE:
            number = float(text.strip()) if text is not None else float(value)
            if isinstance(value, bool) or number != number or number in (float("inf"), float("-inf")):
                raise ValueError
            out.double_value = number
        elif kind == ParameterType.PARAMETER_STRING:
            if not isinstance(value, str):
                raise ValueError
            out.string_value = value
        elif kind == ParameterType.PARAMETER_STRING_ARRAY:
            items = [v.strip() for v in text.strip().strip("[]").split(",") if v.strip()] if text is not None \
                else list(value)
            out.string_array_value = [str(v) for v in items]
        else:
            raise ClientError(f"{name}: a parameter of a type this client does not set ({kind})", "usage")
    except (ValueError, TypeError, AttributeError):
        expected = {ParameterType.PARAMETER_BOOL: "true or false", ParameterType.PARAMETER_INTEGER: "a whole number",
                    ParameterType.PARAMETER_DOUBLE: "a finite number", ParameterType.PARAMETER_STRING: "text"}
        raise ClientError(f"{name}: expected {expected.get(kind, 'a value of its type')}, got "
                          f"{printable(repr(value), 60)}", "usage") from None
    return out


def python_value(value: ParameterValue) -> Any:
    """Return a ParameterValue as a Python value (None when not set)."""
    kind = value.type
    if kind == ParameterType.PARAMETER_BOOL:
        return bool(value.bool_value)
    if kind == ParameterType.PARAMETER_INTEGER:
        return int(value.integer_value)
    if kind == ParameterType.PARAMETER_DOUBLE:
        return float(value.double_value)
    if kind == ParameterType.PARAMETER_STRING:
        return str(value.string_value)
    arrays = {ParameterType.PARAMETER_BYTE_ARRAY: "byte_array_value", ParameterType.PARAMETER_BOOL_ARRAY:
              "bool_array_value", ParameterType.PARAMETER_INTEGER_ARRAY: "integer_array_value",
              ParameterType.PARAMETER_DOUBLE_ARRAY: "double_array_value",
              ParameterType.PARAMETER_STRING_ARRAY: "string_array_value"}
    if kind in arrays:
        return [v.item() if hasattr(v, "item") else v for v in getattr(value, arrays[kind])]
    return None


def range_problem(desc, value: Any) -> Optional[str]:
    """Return what is wrong with a number outside a descriptor's declared range (None: in range, or no range)."""
    ranges = list(desc.integer_range) or list(desc.floating_point_range)
    if not ranges or isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    low, high = sorted((ranges[0].from_value, ranges[0].to_value))
    if low <= value <= high:
        return None
    kind = "a whole number" if desc.integer_range else "a number"
    return f"expected {kind} in [{low:g}, {high:g}], got {value!r}"
