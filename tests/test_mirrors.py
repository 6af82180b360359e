"""mirrors.py: a YAML form and its frozen value type convert both ways, lists for tuples.
(Field-for-field equality of every form with its value type: test_station.py.)"""

import dataclasses
from dataclasses import dataclass, field

import pytest
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.base.mirrors import ValueMirror
from stewart_drake.control.lqi.driver import LqiScales, LqiScalesConfig


@dataclass(frozen=True)
class Pair:
    a: tuple = (1.0, 2.0)
    b: float = 3.0

    def __post_init__(self):
        if len(self.a) != 2:
            raise InvalidConfigError(f"Pair.a needs 2 values, got {self.a}")


@dataclass
class PairForm(ValueMirror):
    value_class = Pair
    a: list[float] = field(default_factory=lambda: [1.0, 2.0])
    b: float = 3.0


def test_build_gives_the_value_type_with_tuples_and_from_value_gives_lists():
    form = PairForm(a=[4.0, 5.0], b=6.0)
    value = form.build()
    assert type(value) is Pair and value == Pair((4.0, 5.0), 6.0)
    assert isinstance(value.a, tuple)
    back = PairForm.from_value(value)
    assert back == form and isinstance(back.a, list)
    assert PairForm().build() == Pair()  # the defaults agree


def test_build_is_validated_by_the_value_type():
    with pytest.raises(InvalidConfigError, match="Pair.a needs 2 values"):
        PairForm(a=[1.0]).build()


def test_lqi_scales_round_trip_through_yaml():
    scales = LqiScales(pose=(2e-3,) * 6, torque=0.5)
    form = LqiScalesConfig.from_value(scales)
    text = yaml_dump_typed(form)
    loaded = yaml_load_typed(schema=LqiScalesConfig, data=text)
    assert loaded.build() == scales
    assert [f.name for f in dataclasses.fields(LqiScalesConfig)] == [
        f.name for f in dataclasses.fields(LqiScales)
    ]
    assert LqiScalesConfig().build() == LqiScales()
