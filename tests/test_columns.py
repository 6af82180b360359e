"""The column helpers of base: interpolation column by column and the unit-bearing CSV reader."""

import numpy as np
import pytest

from stewart_drake.base.columns import interp_columns


def test_interp_columns_is_np_interp_per_column_and_the_hand_value():
    t = np.array([0.0, 1.0, 3.0])
    Y = np.array([[0.0, 10.0], [2.0, 20.0], [6.0, -20.0]])
    t_new = np.array([-1.0, 0.5, 2.0, 4.0])
    got = interp_columns(t_new, t, Y)
    # By hand: held at the ends, halfway between the samples inside.
    assert got.tolist() == [[0.0, 10.0], [1.0, 15.0], [4.0, 0.0], [6.0, -20.0]]
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 1, 50))
    Y = rng.normal(size=(50, 4))
    t_new = rng.uniform(-0.1, 1.1, 200)
    expected = np.column_stack([np.interp(t_new, t, Y[:, c]) for c in range(4)])
    assert np.array_equal(interp_columns(t_new, t, Y), expected)


def test_interp_columns_wraps_with_a_period_and_fills_out():
    phase = np.array([0.0, 0.25, 0.5, 0.75])
    Y = np.array([[0.0], [1.0], [0.0], [-1.0]])
    got = interp_columns(np.array([0.875, 1.0]), phase, Y, period=1.0)
    assert got.tolist() == [[-0.5], [0.0]]  # between 0.75 (-1) and 1.0 = 0 (0): wrapped
    out = np.zeros((2, 1), dtype=np.float32)
    assert interp_columns(np.array([0.125, 0.375]), phase, Y, out=out) is out
    assert out.tolist() == [[0.5], [0.5]]


@pytest.mark.parametrize(
    "Y, out, message",
    [
        (np.zeros(3), None, r"Y of shape \(3,\): expected \(3, k\)"),
        (np.zeros((2, 2)), None, r"Y of shape \(2, 2\): expected \(3, k\)"),
        (np.zeros((3, 2)), np.zeros((4, 2)), r"out of shape \(4, 2\): expected \(5, 2\)"),
    ],
)
def test_interp_columns_refuses_shapes_it_cannot_fill(Y, out, message):
    with pytest.raises(ValueError, match=message):
        interp_columns(np.linspace(0, 1, 5), np.array([0.0, 0.5, 1.0]), Y, out=out)
