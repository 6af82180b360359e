"""YAML forms of frozen value types, and the conversion both ways.

The robot's geometry, the servo and the LQI's scales are frozen dataclasses with tuple fields
(values a controller keeps and compares). Drake's ``yaml_load_typed`` fills mutable dataclasses
with concrete field types, so each has a YAML form written out in the scenario's vocabulary,
with the same field names, units and defaults, lists where the value type has tuples
(``Robot``, ``Motors`` in ``simulation/scenario.py``, ``LqiScalesConfig`` in
``control/lqi/driver.py``); a test keeps each form field for field equal to its value type.
"""

import dataclasses
from typing import ClassVar


def _tuples(value):
    """Lists (nested too) as tuples, the value type's form; anything else as it is."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def _lists(value):
    """Tuples (nested too) as lists, the YAML form's; anything else as it is."""
    return [_lists(v) for v in value] if isinstance(value, tuple) else value


class ValueMirror:
    """Base of a YAML form (a dataclass): :meth:`build` gives the value type back."""

    #: The frozen value type the form mirrors (set by each subclass).
    value_class: ClassVar[type] = object

    def build(self):
        """The value type with these fields (lists, nested too, become tuples); validated by its
        constructor."""
        return self.value_class(
            **{f.name: _tuples(getattr(self, f.name)) for f in dataclasses.fields(self)}
        )

    @classmethod
    def from_value(cls, value):
        """The form of a value-type instance (e.g. ``Robot.from_value(StewartGeometry())``)."""
        return cls(**{f.name: _lists(getattr(value, f.name)) for f in dataclasses.fields(cls)})
