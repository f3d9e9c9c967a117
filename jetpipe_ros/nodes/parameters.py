"""Declare a parameter schema (:class:`~jetpipe_ros.model.params.ParamSpec`) on an rclpy node.

Each parameter gets a ``ParameterDescriptor`` with its description, unit and range, so
``ros2 param describe`` shows them and rclpy refuses out-of-range values. Start-up problems
(wrong type, out of range, unknown name, a parameters file whose section for the node does not
apply to it: :func:`skipped_sections`) are collected, not raised one by one, so a node can
report every bad parameter of a file at once. At run time (``ros2 param set``),
:func:`set_explained` widens integers given for floating-point parameters, as start-up does, and
words rclpy's terse refusals ("expected '3' got '2'", "undeclared parameter(s): []") so that
they name the parameter and the types.
"""

from __future__ import annotations

import array
import sys
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from jetpipe_ros.fileio import load_yaml, ros_sections
from jetpipe_ros.model.errors import ParameterError
from jetpipe_ros.model.params import ParamSpec, check_value


class StartupError(RuntimeError):
    """The node cannot start; ``messages`` says why, one line per problem."""

    def __init__(self, messages: list[str]) -> None:
        super().__init__("; ".join(messages))
        self.messages = messages


def parameter_overrides(node: Node) -> dict[str, Parameter[Any]]:
    """Values given to this node by ``--params-file`` and ``-p``, by name.

    rclpy (9.1.2) silently ignores overrides nobody declares and has no public call that lists
    them, so this reads the private ``Node._parameter_overrides``; it is the one place that does.
    """
    return dict(node._parameter_overrides)


def descriptor(spec: ParamSpec, read_only: bool) -> ParameterDescriptor:
    """The ROS descriptor of ``spec``: description with unit, range, read-only flag."""
    desc = ParameterDescriptor(description=spec.describe(), read_only=read_only)
    if spec.choices:
        desc.additional_constraints = f"one of: {', '.join(spec.choices)}"
    if spec.length is not None:
        desc.additional_constraints = f"exactly {spec.length} numbers"
    elif spec.kind is list:
        desc.additional_constraints = "1 or more numbers"
    if spec.low is not None and spec.high is not None:
        if spec.kind is float:
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
        elif spec.kind is int:
            desc.integer_range = [IntegerRange(
                from_value=int(spec.low), to_value=int(spec.high), step=0)]
    return desc


def _widened(spec: ParamSpec, value: Any) -> Any:
    """``value`` as floats when the spec wants floats and YAML gave integers, else None.

    YAML reads ``mass: 2`` as an integer; ROS would refuse it for a double parameter, while the
    offline tools (``load_params``) accept it. Widening keeps one file valid for both.
    """
    if spec.kind is float and type(value) is int:
        return float(value)
    if spec.kind is list and isinstance(value, (list, tuple, array.array)) and value \
            and all(type(v) is int for v in value):
        return [float(v) for v in value]
    return None


def declare(node: Node, specs: Iterable[ParamSpec], read_only: bool) -> list[str]:
    """Declare ``specs`` on ``node`` with their overrides; return one message per bad value.

    A value is bad if rclpy refuses it (wrong type, out of range) or the schema does (not one
    of the choices, wrong list length).
    """
    overrides = parameter_overrides(node)
    errors = []
    for spec in specs:
        desc = descriptor(spec, read_only)
        given = overrides.get(spec.name)
        widened = _widened(spec, given.value) if given is not None else None
        shown = f" = {_shown(given.value)}" if given is not None else ""
        try:
            if widened is not None:
                node.declare_parameter(spec.name, widened, desc, ignore_override=True)
            else:
                node.declare_parameter(spec.name, spec.default, desc)
            check_value(spec, value(node, spec.name))
        except InvalidParameterTypeException:
            errors.append(f"parameter {spec.name}{shown} has the wrong type: expected "
                          f"{_KIND_NAMES[spec.kind]}; {spec.describe()}")
        except InvalidParameterValueException:
            errors.append(f"parameter {spec.name}{shown} is out of range; {spec.describe()}")
        except ParameterError as exc:
            errors.append(str(exc))
    return errors


_KIND_NAMES = {bool: "true or false", int: "an integer", float: "a number", str: "a string",
               list: "a list of numbers"}


def _shown(v: Any) -> str:
    return repr(list(v) if isinstance(v, array.array) else v)


#: What each rclpy parameter type is, in words.
TYPE_NAMES = {
    Parameter.Type.NOT_SET: "no value", Parameter.Type.BOOL: "a bool (true or false)",
    Parameter.Type.INTEGER: "an integer", Parameter.Type.DOUBLE: "a floating-point number",
    Parameter.Type.STRING: "a string", Parameter.Type.BYTE_ARRAY: "a byte array",
    Parameter.Type.BOOL_ARRAY: "a list of bools", Parameter.Type.INTEGER_ARRAY:
    "a list of integers", Parameter.Type.DOUBLE_ARRAY: "a list of floating-point numbers",
    Parameter.Type.STRING_ARRAY: "a list of strings"}


def set_explained(node: Node, parameters: list[Parameter[Any]], setter: Any) -> Any:
    """Set ``parameters`` on ``node`` through ``setter`` (rclpy's ``set_parameters_atomically``)
    after widening integers given for floating-point parameters; an undeclared name or a wrong
    type gets a result naming the parameter and the expected and given types instead."""
    widened = []
    for p in parameters:
        if not node.has_parameter(p.name):
            return SetParametersResult(successful=False, reason=(
                f"node {node.get_name()} has no parameter {p.name!r} (ros2 param list shows "
                f"them)"))
        descriptor = node.describe_parameter(p.name)
        want = Parameter.Type(descriptor.type)
        if descriptor.dynamic_typing or p.type_ in (want, Parameter.Type.NOT_SET):
            widened.append(p)
        elif want == Parameter.Type.DOUBLE and p.type_ == Parameter.Type.INTEGER:
            widened.append(Parameter(p.name, Parameter.Type.DOUBLE, float(p.value)))
        elif want == Parameter.Type.DOUBLE_ARRAY and p.type_ == Parameter.Type.INTEGER_ARRAY:
            widened.append(Parameter(p.name, Parameter.Type.DOUBLE_ARRAY,
                                     [float(v) for v in p.value]))
        else:
            return SetParametersResult(successful=False, reason=(
                f"parameter {p.name}: expected {TYPE_NAMES.get(want, want.name)}, got "
                f"{TYPE_NAMES.get(p.type_, p.type_.name)} ({_shown(p.value)})"))
    return setter(widened)


def unknown_overrides(node: Node, known: Iterable[str]) -> list[str]:
    """Names given to the node that are neither in ``known`` nor declared (typos), sorted."""
    known = set(known)
    return sorted(name for name in parameter_overrides(node)
                  if name not in known and not node.has_parameter(name))


def skipped_sections(node: Node, cli_args: Sequence[str] | None = None) -> list[str]:
    """Why a ``--params-file`` given to the process (``sys.argv``) or to the node itself
    (``cli_args``, as given to its constructor) would leave ``node`` without the parameters
    meant for it, one line per file: the file has a
    section for a node of this name and none that applies to this one. rcl skips such a file
    silently: ``actuator_sim:`` is read from the root namespace, so under
    ``-r __ns:=/axis1`` the node would run at its defaults (``/**/actuator_sim:`` applies in any
    namespace: :func:`~jetpipe_ros.fileio.ros_sections`). Files that cannot be read are left
    to rcl, which reports them."""
    args = [*sys.argv, *(cli_args or [])]
    name, fqn = node.get_name(), node.get_fully_qualified_name()
    problems = []
    for flag, path in zip(args, args[1:]):
        if flag != "--params-file":
            continue
        try:
            tree = load_yaml(path)
        except Exception:  # noqa: BLE001 - rcl reports what it cannot read
            continue
        if not isinstance(tree, Mapping) or ros_sections(tree, fqn):
            continue
        meant = [k for k in tree if isinstance(k, str) and k.rsplit("/", 1)[-1] == name]
        if meant:
            problems.append(
                f"{path}: section {', '.join(repr(k) for k in meant)} does not apply to "
                f"{fqn} (a section without a leading '/' is read from the root namespace), so "
                f"none of its parameters would be used; key it '/**/{name}:' (any namespace) "
                f"or '{fqn}:'")
    return problems


def value(node: Node, name: str) -> Any:
    """A declared parameter's value, with arrays as plain lists."""
    v = node.get_parameter(name).value
    return list(v) if isinstance(v, (array.array, tuple)) else v
