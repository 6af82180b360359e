"""The one table of units and the one reader of a length with an angle (base/units.py), as the
tolerance (verify, reproduce) and the tracker's noise (calibrate) take it: factors written out
here, not read from the table under test."""

import argparse
import math

import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.base.units import UNITS, length_and_angle
from stewart_drake.calibration.calibrate_options import noise_argument
from stewart_drake.organ_motion.fidelity import parse_tolerance

BIG = (1.0, math.pi)


def test_the_table_holds_the_si_factors():
    assert UNITS["m"] == {"m": 1.0, "cm": 0.01, "mm": 0.001, "um": 1e-6}
    assert UNITS["rad"]["deg"] == pytest.approx(0.017453292519943295, rel=1e-15)
    assert UNITS["rad"]["mrad"] == 1e-3 and UNITS["rad"]["urad"] == 1e-6
    assert UNITS["s"] == {"s": 1.0, "ms": 0.001, "min": 60.0}


@pytest.mark.parametrize(
    "text, m, rad",
    [
        ("0.1mm,0.1deg", 1e-4, 0.1 * math.pi / 180),
        ("20urad, 5 um", 5e-6, 2e-5),  # either order, spaces
        ("2CM,3MRAD", 0.02, 3e-3),  # a device's capitals
        (".5m,1e-3rad", 0.5, 1e-3),
    ],
)
def test_a_length_and_an_angle_are_read_in_si(text, m, rad):
    assert length_and_angle(text, "--x", BIG, "too big") == pytest.approx((m, rad), rel=1e-12)


@pytest.mark.parametrize(
    "text, words",
    [
        ("0.1mm", "one length and one angle"),
        ("0.1mm,0.2mm", "one length and one angle"),
        ("0.1Mm,0.1deg", "is not one of"),  # mixed case: no millimetre
        ("0.1in,0.1deg", "is not one of"),
        ("-1mm,0.1deg", "positive number"),
        ("0mm,0.1deg", "positive number"),
        ("infmm,0.1deg", "one length and one angle"),
        ("2m,0.1deg", "too big"),
        ("1mm,4rad", "too big"),
    ],
)
def test_what_is_not_a_length_and_an_angle_is_refused_naming_the_option(text, words):
    with pytest.raises(InvalidConfigError, match="--x") as refused:
        length_and_angle(text, "--x", BIG, "too big")
    assert words in str(refused.value)


def test_zero_only_where_the_caller_takes_it():
    assert length_and_angle("0um,0urad", "--x", BIG, "too big", zero=True) == (0.0, 0.0)
    with pytest.raises(InvalidConfigError, match="non-negative"):
        length_and_angle("-1um,0urad", "--x", BIG, "too big", zero=True)


def test_the_tolerance_and_the_noise_are_read_by_the_one_reader():
    assert parse_tolerance("20urad,5um") == pytest.approx((5e-6, 2e-5))
    assert noise_argument("20urad,5um") == pytest.approx((5e-6, 2e-5))  # either order now
    assert noise_argument("0um,0urad") == (0.0, 0.0)  # a perfect tracker
    assert noise_argument("1mm,10mrad") == pytest.approx((1e-3, 1e-2))  # the largest
    for bad in ("5,20urad", "2mm,1urad", "5um,11mrad", "5um"):
        with pytest.raises(argparse.ArgumentTypeError, match="expected a length and an angle"):
            noise_argument(bad)
    with pytest.raises(InvalidConfigError, match="--tolerance.*at most 1 m and 180 deg"):
        parse_tolerance("2m,1deg")
    with pytest.raises(InvalidConfigError, match="--tolerance: one length and one angle"):
        parse_tolerance("0mm,1deg")
