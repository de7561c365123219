"""One declarative parameter table per node: declarations, checks and docs from one place.

Each node's package has a `settings.py` whose `PARAMETERS` maps every parameter name
to a `Setting` (default, description, range or choices, read-only). From that table:
`declare` declares the parameters with their descriptors, `check` refuses values
outside the table (the same reasons at start-up and at set time), `on_change` is the
one mechanism by which a running node takes a change, and `tools/param_tables.py`
writes the docs' tables. The conversion of values into the cores' configuration
dataclasses is each `settings.py`'s own.

generate_parameter_library (ros2_control's and MoveIt Servo's) generates the same kind
of table from YAML; its Python generator is not on PyPI, from which this project
installs everything, so the table is written in Python here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ft_msgs_py import rclpy_private

#: Most values an array parameter may hold (critical points: 1365 positions).
MAX_ARRAY = 4096


@dataclass(frozen=True)
class Setting:
    """One parameter of a node's table.

    Attributes:
        default: the value when none is given; a `Parameter.Type` (an array type) for an
            array that is empty unless given.
        description: what it is, with its unit.
        bounds: (low, high), inclusive: a number's range, or every element's for an
            array. None: any finite value.
        choices: the strings a string parameter may take (empty: any).
        read_only: fixed once the node runs.
        off: a value allowed outside `bounds` that turns the feature off (0 for a
            gain whose smallest useful value is `bounds[0]`), or None.
    """

    default: object
    description: str
    bounds: tuple[float, float] | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = False
    off: float | None = None

    @property
    def type(self) -> Parameter.Type:
        """The parameter's ROS type."""
        if isinstance(self.default, Parameter.Type):
            return self.default
        return Parameter.Type.from_parameter_value(self.default)

    def descriptor(self) -> ParameterDescriptor:
        """The ROS descriptor: description, read-only, range and the constraints in words."""
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only)
        scalar = self.type in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER)
        if self.bounds is not None and scalar and self.off is None:
            low, high = self.bounds
            if self.type == Parameter.Type.DOUBLE:
                descriptor.floating_point_range = [FloatingPointRange(from_value=float(low),
                                                                      to_value=float(high))]
            else:
                descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high),
                                                         step=1)]
        descriptor.additional_constraints = self.constraints()
        return descriptor

    def constraints(self) -> str:
        """The allowed values in words ("" where the type alone says it)."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.bounds is None:
            return "finite" if self.type in (Parameter.Type.DOUBLE,
                                             Parameter.Type.DOUBLE_ARRAY) else ""
        low, high = (f"{bound:g}" for bound in self.bounds)
        each = "each " if _is_array(self.type) else ""
        off = f" or {self.off:g} (off)" if self.off is not None else ""
        return f"{each}{low} to {high}{off}"

    def refusal(self, name: str, value: object) -> str | None:
        """Why `value` is refused for this parameter, or None if the table allows it."""
        if isinstance(value, (list, tuple, np.ndarray)) and len(value) > MAX_ARRAY:
            return f"{name} has {len(value)} values (at most {MAX_ARRAY})"
        if self.choices and value not in self.choices:
            return f"{name} must be one of {', '.join(self.choices)}, not {value!r}"
        if self.type not in _NUMERIC:
            return None
        try:
            numbers = np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError):
            return f"{name} must be {'numbers' if _is_array(self.type) else 'a number'}"
        if not np.all(np.isfinite(numbers)):
            return f"{name} must be finite"
        if self.bounds is None:
            return None
        low, high = self.bounds
        for number in numbers:
            if not (low <= number <= high or number == self.off):
                return f"{name} = {number:g} is out of range: {self.constraints()}"
        return None


#: The types whose values are numbers (each element of an array).
_NUMERIC = (Parameter.Type.DOUBLE, Parameter.Type.INTEGER, Parameter.Type.DOUBLE_ARRAY,
            Parameter.Type.INTEGER_ARRAY)

#: A node's parameters, in declaration order.
Table = Mapping[str, Setting]


def _is_array(kind: Parameter.Type) -> bool:
    return kind in (Parameter.Type.DOUBLE_ARRAY, Parameter.Type.INTEGER_ARRAY,
                    Parameter.Type.STRING_ARRAY, Parameter.Type.BOOL_ARRAY,
                    Parameter.Type.BYTE_ARRAY)


def check(table: Table, changes: Mapping[str, object]) -> None:
    """Raise ValueError with the first reason the table refuses one of `changes`."""
    for name, given in changes.items():
        setting = table.get(name)
        reason = None if setting is None else setting.refusal(name, given)
        if reason is not None:
            raise ValueError(reason)


def declare(node: Node, table: Table) -> None:
    """Declare every parameter of `table` with its descriptor; every one has a value.

    An array whose default is its type is declared with an empty array of that type:
    `[]` in a parameters file (as `ros2 param dump` writes it) loads back as that, and
    rclpy's get_parameters service answers a request naming a parameter without a value
    with nothing at all. A start-up value the table refuses is logged as an ERROR and
    replaced by the default, so a typo in a launch file does not stop the node.
    """
    for name, setting in table.items():
        descriptor = setting.descriptor()
        try:
            node.declare_parameter(name, setting.default, descriptor)
        except (InvalidParameterValueException, InvalidParameterTypeException) as error:
            _use_default(node, setting, error)
            node.declare_parameter(name, setting.default, descriptor, ignore_override=True)
        if node.get_parameter_or(name).type_ == Parameter.Type.NOT_SET:
            rclpy_private.set_as_declared(node, Parameter(name, setting.type, []))
        reason = setting.refusal(name, node.get_parameter(name).value)
        if reason is not None:
            _use_default(node, setting, reason)
            rclpy_private.set_as_declared(node, Parameter(name, setting.type, _value(setting)))


def _use_default(node: Node, setting: Setting, error: object) -> None:
    shown = ("an empty list" if isinstance(setting.default, Parameter.Type)
             else repr(setting.default))
    node.get_logger().error(f"{error}; using the default, {shown}")


def _value(setting: Setting) -> object:
    return [] if isinstance(setting.default, Parameter.Type) else setting.default


def defaults(table: Table) -> dict[str, object]:
    """Every parameter's default value (an empty list for an array without one)."""
    return {name: _value(setting) for name, setting in table.items()}


def values(node: Node, table: Table, changes: Mapping[str, object] | None = None,
           ) -> dict[str, object]:
    """Every parameter's current value, with `changes` (name -> value) in place."""
    changes = changes or {}
    return {name: changes[name] if name in changes else node.get_parameter(name).value
            for name in table}


def on_change(node: Node, table: Table, check_values: Callable[[dict], object],
              apply: Callable[[set[str]], None]) -> None:
    """How a running node takes parameter changes: validated whole, then applied.

    A change is refused (its reason returned to the caller, the node's configuration
    kept) where the table refuses a value, or where `check_values(values)` raises
    ValueError or TypeError; `values` are every parameter's values with the change in
    place. Accepted, `apply(names)` gets the names of the parameters that changed.
    """
    def validate(params: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in params}
        try:
            check(table, changes)
            check_values(values(node, table, changes))
        except (ValueError, TypeError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(lambda params: apply({p.name for p in params}))


def rows(tables: Iterable[Table]) -> dict[str, Setting]:
    """Tables joined in order (a node's table from the shared ones and its own)."""
    joined: dict[str, Setting] = {}
    for table in tables:
        joined.update(table)
    return joined


def number(value: float) -> str:
    """A number as the docs show it."""
    return f"{value:g}" if isinstance(value, float) and math.isfinite(value) else str(value)
