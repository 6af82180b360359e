"""The principal direction of a motion and the parabolic peak, one definition each
(stewart_drake/base/signals.py): checked against directions and vertices written down by hand,
not against the code's own SVD or formula."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.base.signals import (
    direction_words,
    parabolic_peak,
    principal_direction,
    principal_displacement,
)

T = np.linspace(0.0, 8.0, 400)


def _poses(direction, amplitude=0.01, rotation=0.0, offset=(0.0, 0.0, 0.25)):
    """(n, 6) poses moving sin(t) along ``direction`` about ``offset``, rotating ``rotation``."""
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    x = np.zeros((T.size, 6))
    x[:, 0] = rotation * np.sin(3 * T)
    x[:, 3:6] = np.asarray(offset) + amplitude * np.sin(T)[:, None] * u
    return x


@pytest.mark.parametrize(
    ("direction", "expected"),
    [
        ((0, 0, 1), (0, 0, 1)),
        ((0, 0, -1), (0, 0, 1)),  # signed: its largest component positive
        ((3, 0, 4), (0.6, 0, 0.8)),
        ((0, -4, 3), (0, 0.8, -0.6)),
    ],
)
def test_the_direction_of_a_motion_along_a_line_is_that_line(direction, expected):
    u = principal_direction(_poses(direction, rotation=0.5))  # a rotation is never counted
    np.testing.assert_allclose(u, expected, atol=1e-12)
    assert (
        direction_words(u)
        == {
            (0, 0, 1): "Z",
            (0.6, 0, 0.8): "(0.6, 0, 0.8)",
            (0, 0.8, -0.6): "(0, 0.8, -0.6)",
        }[expected]
    )


def test_a_diagonal_is_not_the_coordinate_that_moves_most():
    """Along (0.6, 0, 0.8) Z moves most peak to peak, but the motion is the diagonal: its
    displacement along it has the motion's whole amplitude, 10 mm, where Z sees 8."""
    x = _poses((3, 0, 4))
    s, u = principal_displacement(x)
    assert np.ptp(s) == pytest.approx(0.01 * np.ptp(np.sin(T)), rel=1e-12)
    assert np.ptp(x[:, 5]) == pytest.approx(0.8 * np.ptp(s), rel=1e-12)
    assert abs(np.mean(s)) < 1e-15 and u[0] == pytest.approx(0.6)


def test_an_elliptic_motion_takes_its_long_axis():
    """X 10 mm and Y 4 mm in quadrature: the principal direction is X, not a blend."""
    x = np.zeros((T.size, 3))
    x[:, 0], x[:, 1] = 0.01 * np.sin(T * np.pi), 0.004 * np.cos(T * np.pi)
    np.testing.assert_allclose(principal_direction(x), (1, 0, 0), atol=1e-9)


def test_two_samples_make_a_direction_the_line_between_them():
    two = np.array([[0.0, 0.0, 0.0], [0.0, -0.003, 0.004]])
    np.testing.assert_allclose(principal_direction(two), (0, -0.6, 0.8), atol=1e-12)


@pytest.mark.parametrize(
    ("u", "words"),
    [
        ((0.0, 0.0, -1.0), "-Z"),
        ((-1.0, 0.0, 0.0), "-X"),
        ((0.0, 1.0, 0.0), "Y"),
        # Either side of 1e-3 from an axis: named within it, in components beyond it.
        ((0.0, 1 - 0.9e-3, 0.0424), "Y"),
        ((0.0, -(1 - 0.9e-3), 0.0424), "-Y"),
        ((0.0, 1 - 1.1e-3, 0.0469), "(0, 0.999, 0.0469)"),
    ],
)
def test_direction_words_name_an_axis_with_its_sign_and_nothing_else(u, words):
    assert direction_words(u) == words


def test_a_still_motion_has_z_and_wrong_samples_are_refused():
    np.testing.assert_array_equal(principal_direction(np.ones((5, 6))), (0, 0, 1))
    for bad, words in (
        (np.zeros((5, 4)), r"\(n, 6\) poses or \(n, 3\) translations, n >= 2, got \(5, 4\)"),
        (np.zeros((1, 6)), r"n >= 2, got \(1, 6\)"),
        (np.full((5, 3), np.nan), "finite samples"),
    ):
        with pytest.raises(InvalidConfigError, match=words):
            principal_direction(bad)


def test_the_robots_verdict_and_the_diagrams_report_measure_one_lag_along_one_direction():
    """A platform moving along the diagonal (0.6, 0, 0.8) 20 ms behind its command, 0.3 mm off
    it on Z (a calibration offset), and a carriage 8 ms behind its own: the robot's verdict
    (``live.session_surrogate``) and the Diagram's pair report (``base.pair_figures``) both judge
    the diagonal, find 20 and 8 ms to 0.1 ms, and agree on the relative latency, +12 ms, to
    0.5 ms; Z, the coordinate that moves most, is not the direction judged."""
    from stewart_drake.base.pair_figures import relative_latency as diagrams
    from stewart_drake.live.session_surrogate import judged_relative_latency as robots

    t = np.arange(0.0, 12.0, 0.01)
    u = np.array([0.6, 0.0, 0.8])

    def breath(t):
        return 0.008 * np.sin(2 * np.pi * t / 4.0) + 0.002 * np.sin(2 * np.pi * t / 1.3)

    x_c, x_m = np.zeros((t.size, 6)), np.zeros((t.size, 6))
    x_c[:, 3:6] = breath(t)[:, None] * u
    x_m[:, 3:6] = breath(t - 0.020)[:, None] * u + np.array([0.0, 0.0, 3e-4])
    s_c, s_m = breath(t + 0.5), breath(t + 0.5 - 0.008)
    robot = robots(t, x_m, x_c, s_m, s_c, tolerance_s=0.01)
    diagram = diagrams(t, x_c, x_m, s_c, s_m)
    np.testing.assert_allclose(robot.platform_direction, u, atol=1e-9)
    np.testing.assert_allclose(diagram.direction, u, atol=1e-9)
    assert robot.platform_axis == "(0.6, 0, 0.8)"
    assert robot.platform_lag_s == pytest.approx(0.020, abs=1e-4)
    assert robot.surrogate_lag_s == pytest.approx(0.008, abs=1e-4)
    assert robot.relative_s == pytest.approx(0.012, abs=2e-4)
    assert diagram.relative_s == pytest.approx(robot.relative_s, abs=5e-4)


@pytest.mark.parametrize("vertex", [-0.45, -0.2, 0.0, 0.13, 0.4])
def test_the_parabolic_peak_is_the_vertex_of_the_parabola_through_three_samples(vertex):
    # y = 7 - 3 (x - vertex)^2 sampled at -1, 0, 1: its vertex, whatever its height or width.
    a, b, c = (7.0 - 3.0 * (x - vertex) ** 2 for x in (-1.0, 0.0, 1.0))
    assert parabolic_peak(a, b, c) == pytest.approx(vertex, abs=1e-12)
    assert parabolic_peak(a + 100.0, b + 100.0, c + 100.0) == pytest.approx(vertex, abs=1e-12)


def test_the_parabolic_peak_of_a_sampled_gaussian_refines_toward_its_true_peak():
    # A peak 0.3 samples right of the middle: the refinement lands nearer it than the sample.
    a, b, c = np.exp(-0.5 * ((np.array([-1.0, 0.0, 1.0]) - 0.3) / 1.5) ** 2)
    shift = parabolic_peak(a, b, c)
    assert 0.2 < shift < 0.4


@pytest.mark.parametrize(
    "three",
    [
        (1.0, 1.0, 1.0),
        (2.0, 1.0, 2.0),
        (0.0, 1.0, 3.0),
        (np.nan, 1.0, 0.5),
        (-np.inf, 1.0, 0.5),  # a log of zero power beside the peak: no finite vertex
    ],
)
def test_no_parabolic_peak_where_the_three_make_no_maximum(three):
    assert parabolic_peak(*three) == 0.0


@pytest.mark.parametrize(("share", "periodic"), [(0.29, False), (0.31, True)])
def test_a_motion_is_periodic_from_three_tenths_of_its_power_in_its_peak(share, periodic):
    """Either side of the one threshold (PERIOD_POWER_SHARE, 0.3), read by the Kalman model's
    period: a sine of 4 s beside three sines of equal amplitude a, every one a whole number of
    cycles in the 100 s, so that the 4 s sine's share of the power is 1 / (1 + 3 a^2), set to
    ``share`` by a."""
    from stewart_drake.base.signals import PERIOD_POWER_SHARE, dominant_period
    from stewart_drake.references.predictors import filter_period

    assert PERIOD_POWER_SHARE == 0.3
    t = 0.05 * np.arange(2000)
    a = np.sqrt((1.0 / share - 1.0) / 3.0)
    v = np.sin(2 * np.pi * t / 4.0) + a * sum(np.sin(2 * np.pi * t / p) for p in (2.0, 1.0, 0.5))
    period, measured = dominant_period(t, v)
    assert period == pytest.approx(4.0, rel=1e-5) and measured == pytest.approx(share, abs=2e-3)
    found = filter_period(v, 0.05)
    assert (found == pytest.approx(4.0, rel=1e-5)) if periodic else np.isnan(found)
