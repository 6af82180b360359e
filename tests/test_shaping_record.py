"""What a shaper did, counted and said (run/shaping_record.py): the counts a sequence of periods
adds, worked out here period by period, and the clause a user reads, word for word."""

import math

import numpy as np
import pytest

from stewart_drake.run import shaping_record as flags
from stewart_drake.run.shaping_record import ShapingRecord, count_joined, count_shaped

H = 0.01


def test_no_period_counts_zero_and_no_time():
    r = ShapingRecord.initial_values()
    assert r.shape == (12,)
    times = [
        ShapingRecord.FIELDS.index(f) for f in ("joined_s", "first_shaped_s", "first_limited_s")
    ]
    assert times == [2, 10, 11]
    assert np.isnan(r[times]).all() and not np.delete(r, times).any()
    assert ShapingRecord.from_values(H, r) == ShapingRecord(H)
    for wrong in (r[:-1], np.append(r, 0.0)):  # a state of another layout is not read
        with pytest.raises(ValueError, match="zip"):
            ShapingRecord.from_values(H, wrong)


def _counted() -> np.ndarray:
    """Two periods of approach, four joined, then three shaped (module docstring)."""
    r = ShapingRecord.initial_values()
    count_shaped(r, 0.0, flags.SHAPED_FLAG, None)  # before joining: the approach
    count_shaped(r, 0.01, flags.SHAPED_FLAG | flags.LIMITED_FLAG, np.ones(6))
    count_joined(r, 0.02, 3)
    count_joined(r, 0.05)
    count_shaped(
        r,
        0.06,
        flags.SHAPED_FLAG | flags.LIMITED_FLAG | flags.CLIPPED_FLAG,
        [1e-3, 0, 0, 3e-4, 4e-4, 0],
    )
    count_shaped(
        r, 0.07, flags.SHAPED_FLAG | flags.SCALED_FLAG | flags.OVER_FLAG, [0, 5e-4, 0, 1e-4, 0, 0]
    )
    count_shaped(r, 0.08, flags.SHAPED_FLAG | flags.LIMITED_FLAG, None)
    return r


def test_a_sequence_of_periods_is_counted_as_worked_out_by_hand():
    record = ShapingRecord.from_values(H, _counted())
    assert record == ShapingRecord(
        period_s=H,
        periods=9,
        approach=2,
        joined_s=0.02,  # the first joined period, not the later one
        shaped=3,
        limited=2,
        clipped=1,
        scaled=1,
        over=1,
        departure_m=5e-4,  # |(0.3, 0.4, 0)| mm: the largest, the approach's not counted
        departure_rad=1e-3,
        first_shaped_s=0.06,
        first_limited_s=0.06,
    )
    assert all(
        type(getattr(record, f)) is int
        for f in ("periods", "approach", "shaped", "limited", "clipped", "scaled", "over")
    )
    assert record.departure_m == pytest.approx(5e-4, rel=1e-12)
    assert record.as_dict() == {
        "period_s": H,
        "periods": 9,
        "approach": 2,
        "shaped": 3,
        "limited": 2,
        "clipped": 1,
        "scaled": 1,
        "over": 1,
        "joined_s": 0.02,
        "departure_m": record.departure_m,
        "departure_rad": 1e-3,
        "first_shaped_s": 0.06,
        "first_limited_s": 0.06,
    }


def test_the_clause_says_every_count_with_its_unit():
    record = ShapingRecord.from_values(H, _counted())
    assert math.degrees(1e-3) == pytest.approx(0.0573, abs=5e-5)
    assert record.words() == (
        "joined the followed reference at t = 0.020 s, from where it started; shaped to the "
        "robot's limits in 3 of 9 periods (0.03 s, from t = 0.060 s), at most 0.5 mm and "
        "0.0573 deg from the followed reference (stopped short of a pose not admissible for "
        "0.02 s from t = 0.060 s; the acceleration scaled for a motor's torque or speed in 1; "
        "clipped to the box of the limits in 1; a motor over its limit even without "
        "acceleration in 1; going back onto the followed reference in the others)"
    )


def test_the_clause_of_a_reference_scaled_only():
    record = ShapingRecord(
        H, periods=425, joined_s=0.0, shaped=76, scaled=76, departure_m=1.98e-4,
        first_shaped_s=1.23,
    )  # fmt: skip
    assert record.words() == (
        "shaped to the robot's limits in 76 of 425 periods (0.76 s, from t = 1.230 s), at most "
        "0.198 mm and 0 deg from the followed reference (the pose admissible throughout; the "
        "acceleration scaled for a motor's torque or speed in 76; going back onto the followed "
        "reference in the others)"
    )


@pytest.mark.parametrize(
    "record, words",
    [
        (
            ShapingRecord(H, periods=5),
            "never joined the followed reference in 5 periods: it could not be reached within "
            "the robot's limits",
        ),
        (
            ShapingRecord(H, periods=100, joined_s=0.0),
            "the followed reference within the robot's limits throughout (100 periods): not "
            "shaped, the pose admissible throughout",
        ),
        (
            ShapingRecord(H, periods=100, approach=20, joined_s=0.2),
            "the followed reference within the robot's limits throughout from t = 0.200 s (80 "
            "periods): not shaped, the pose admissible throughout",
        ),
    ],
    ids=["never joined", "throughout", "after an approach"],
)
def test_the_clause_of_a_reference_not_shaped(record, words):
    assert record.words() == words
