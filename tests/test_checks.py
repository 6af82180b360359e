"""checks.py: user input as finite numbers of the right shape and range, or a typed error that
names the argument and says what to change."""

import numpy as np
import pytest

from stewart_drake.base.checks import (
    MAX_POSITION_M,
    as_array,
    as_number,
    as_poses,
    available_memory_bytes,
    check_int,
    check_memory,
    check_multiple,
    format_bytes,
)
from stewart_drake.base.errors import InvalidConfigError, StewartError


def test_as_number_accepts_the_closed_or_half_open_range_and_returns_a_float():
    assert as_number("gain", 0.0, 0.0, 1.0) == 0.0
    assert as_number("gain", 1, 0.0, 1.0) == 1.0 and type(as_number("gain", 1, 0.0)) is float
    assert as_number("gain", np.float32(0.5), 0.0, 1.0) == 0.5
    assert as_number("gain", np.array(2.5)) == 2.5  # a 0-d array is one number
    with pytest.raises(InvalidConfigError, match=r"gain must be a finite number in \(0, 1\]"):
        as_number("gain", 0.0, 0.0, 1.0, lo_open=True)
    with pytest.raises(
        InvalidConfigError,
        match=r"gain must be a finite number in \[0, 1\], "
        r"got 1.5",
    ):
        as_number("gain", 1.5, 0.0, 1.0)
    with pytest.raises(InvalidConfigError, match=r"in \[-inf, 2\], got -?inf"):
        as_number("gain", -np.inf, hi=2.0)


@pytest.mark.parametrize(
    "value, says",
    [
        (True, "must be one number"),
        (np.bool_(False), "must be one number"),
        ([1.0], "must be one number"),
        (np.ones(2), "must be one number"),
        ("0.3", r"must be a number, got '0.3' \(a string\)"),
        (b"1", r"\(a string\)"),
        (None, "must be a number, got None"),
        (float("nan"), "must be a finite number"),
    ],
)
def test_as_number_refuses_what_is_not_one_finite_number_naming_the_field(value, says):
    with pytest.raises(InvalidConfigError, match=says) as info:
        as_number("servo.gear_ratio", value, 0.0)
    assert str(info.value).startswith("servo.gear_ratio must be")


def test_as_number_raises_the_error_class_it_is_given():
    class Custom(InvalidConfigError):
        pass

    with pytest.raises(Custom, match="x must be"):
        as_number("x", -1.0, 0.0, error=Custom)


def test_as_array_names_the_first_bad_index_and_the_shape_wanted():
    a = np.arange(6.0)
    assert as_array("x", a) is a  # float64 is not copied
    np.testing.assert_array_equal(as_array("x", [1, 2]), [1.0, 2.0])
    with pytest.raises(InvalidConfigError, match=r"x has a non-finite value inf at index \(1, 2\)"):
        as_array("x", [[0, 0, 0], [0, 0, np.inf]])
    with pytest.raises(InvalidConfigError, match=r"x must have shape \(6,\), got \(5,\)"):
        as_array("x", np.zeros(5), shape=(6,))
    with pytest.raises(InvalidConfigError, match=r"x must have shape \(\.\.\., 6\), got \(\)"):
        as_array("x", 1.0, last=6)
    with pytest.raises(InvalidConfigError, match="x must be numbers, got 'abc'"):
        as_array("x", "abc")


def test_as_poses_refuses_millimetres_for_metres():
    ok = np.zeros((2, 6))
    ok[:, 5] = MAX_POSITION_M
    assert as_poses("x", ok).shape == (2, 6)
    ok[1, 5] = 3000.0  # 3 km: a pose in mm
    with pytest.raises(InvalidConfigError, match="poses are in m, not mm"):
        as_poses("x", ok)
    assert as_poses("x", np.zeros((0, 6))).shape == (0, 6)  # an empty batch is fine


def test_check_multiple_gives_the_ratio_or_the_nearest_valid_period():
    assert check_multiple("log period", 0.01, "the control period", 1e-3) == 10
    assert check_multiple("log period", 3e-3 * (1 + 1e-9), "h", 1e-3) == 3  # float noise
    with pytest.raises(
        InvalidConfigError,
        match=r"log period \(0.0025 s\) must be a whole "
        r"multiple of h \(0.001 s\); the nearest valid "
        r"value is 0.002 s",
    ):
        check_multiple("log period", 2.5e-3, "h", 1e-3)
    with pytest.raises(InvalidConfigError, match="nearest valid value is 0.001 s"):
        check_multiple("log period", 1e-4, "h", 1e-3)
    for bad, shown in ((float("nan"), "nan"), (0.0, "0.0"), (-1e-3, "-0.001")):
        with pytest.raises(
            InvalidConfigError,
            match=rf"^log period must be a finite number in \(0, inf\], got {shown}$",
        ):
            check_multiple("log period", bad, "h", 1e-3)
    with pytest.raises(InvalidConfigError, match="^log period must be a number, got '1e-3'"):
        check_multiple("log period", "1e-3", "h", 1e-3)


def test_check_int_takes_integers_at_both_bounds_and_refuses_one_past_them():
    assert check_int("seed", 0, 0, 3) == 0 and check_int("seed", np.int64(3), 0, 3) == 3
    assert type(check_int("seed", np.int32(2), 0, 3)) is int
    assert check_int("count", 10**12, 1) == 10**12  # no upper bound
    for value in (-1, 4):
        with pytest.raises(
            InvalidConfigError, match=rf"^seed must be an integer in \[0, 3\], got {value}$"
        ):
            check_int("seed", value, 0, 3)
    with pytest.raises(
        InvalidConfigError,
        match=r"^resolution must be an integer >= 3 \(a grid through the home pose\), got 2$",
    ):
        check_int("resolution", 2, 3, why="a grid through the home pose")
    for value, shown in ((True, "True"), (3.0, "3.0"), ("3", "'3'"), (None, "None")):
        with pytest.raises(
            InvalidConfigError, match=rf"count must be an integer >= 1, got {shown}$"
        ):
            check_int("count", value, 1)


def test_format_bytes_and_the_memory_check():
    assert [format_bytes(n) for n in (12e3, 4.2e9, 1.5e15, 1e20)] == [
        "12 kB",
        "4.2 GB",
        "1.5 PB",
        "1e+20 bytes",
    ]
    check_memory("a small request", 1.0, "nothing")  # fits anywhere
    if available_memory_bytes() is None:
        pytest.skip("this machine does not say its memory: the check is skipped")
    with pytest.raises(
        InvalidConfigError,
        match=r"^a run: more memory needed than any machine has, and than the .* available on "
        r"this machine; "
        r"shorten --duration$",
    ):
        check_memory("a run", float("inf"), "shorten --duration")
    assert issubclass(InvalidConfigError, StewartError)
