"""Density features (paper eqs. 35-36, well-posed variant): hand-computed windows, edge cases, and
the Drake system against the numpy function."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Adder, ConstantVectorSource, Sine

from stewart_drake.base.errors import InvalidConfigError, SimulationDivergedError
from stewart_drake.control.features import (
    DensityFeatures,
    density_features,
    density_features_series,
)

EPS = 1e-9


def test_hand_computed_window():
    # window of m + 1 = 3 samples, oldest first; channel j of e and T hand-worked below.
    e = np.array(
        [
            [1.0, -2.0, 0.0, 0.5, 4.0, 1e-3],
            [-2.0, 2.0, 0.0, 0.5, 0.0, 1e-3],
            [3.0, -2.0, 0.0, 0.5, 0.0, 4e-3],
        ]
    )
    T = np.array(
        [
            [0.1, 0.0, -1.0, 2.0, 0.0, 5.0],
            [0.1, 0.0, 1.0, 2.0, 0.0, -5.0],
            [0.4, 6.0, -0.5, 2.0, 0.0, 5.0],
        ]
    )
    rho = density_features(e, T, eps=EPS)
    # rho = |x(t)| / (mean |x| + eps)
    expected_e = [3 / (2 + EPS), 2 / (2 + EPS), 0.0, 0.5 / (0.5 + EPS), 0.0, 4e-3 / (2e-3 + EPS)]
    expected_T = [
        0.4 / (0.2 + EPS),
        6 / (2 + EPS),
        0.5 / (2.5 / 3 + EPS),
        2 / (2 + EPS),
        0.0,
        5 / (5 + EPS),
    ]
    np.testing.assert_allclose(rho, expected_e + expected_T, rtol=1e-14, atol=0)
    assert rho.shape == (12,)


def test_signed_sum_crossing_zero_stays_finite():
    # Eq. 35 as printed: (m + 1) 0.5 / (1 - 1.5 + 0.5) = 1.5 / 0, infinite. Ours: 0.5 / (1 + eps).
    col = np.array([1.0, -1.5, 0.5])
    e = np.tile(col[:, None], (1, 6))
    rho = density_features(e, e, eps=EPS)
    np.testing.assert_allclose(rho, 0.5 / (1.0 + EPS), rtol=1e-14)


def test_zeros_constants_spikes():
    m1 = 50
    zeros = np.zeros((m1, 6))
    np.testing.assert_array_equal(density_features(zeros, zeros), np.zeros(12))
    for c in (1e-12, 1e-6, 1.0, -3.0, 1e300):
        const = np.full((m1, 6), c)
        np.testing.assert_allclose(
            density_features(const, const, eps=EPS), abs(c) / (abs(c) + EPS), rtol=1e-12
        )
    spike_now = zeros.copy()
    spike_now[-1] = 1e3  # the newest sample: rho -> m + 1
    np.testing.assert_allclose(
        density_features(spike_now, zeros)[:6], 1e3 / (1e3 / m1 + EPS), rtol=1e-12
    )
    assert 49.99 < density_features(spike_now, zeros)[0] <= m1
    spike_old = zeros.copy()
    spike_old[0] = 1e3  # an old spike lowers the density of the current sample
    spike_old[-1] = 1.0
    np.testing.assert_allclose(density_features(spike_old, zeros)[:6], 1.0 / (1001 / m1 + EPS))


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, (8, 12), elements=st.floats(allow_nan=False, allow_infinity=False)))
def test_finite_and_bounded_for_all_finite_inputs(x):
    rho = density_features(x[:, :6], x[:, 6:], eps=EPS)
    assert np.all(np.isfinite(rho))
    assert np.all(rho >= 0) and np.all(rho <= 8 * (1 + 1e-12))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_input_raises(bad):
    e = np.ones((5, 6))
    e[2, 3] = bad
    with pytest.raises(ValueError, match=r"e_window .*non-finite.*\(2, 3\)"):
        density_features(e, np.ones((5, 6)))


def test_bad_settings_raise():
    with pytest.raises(InvalidConfigError):
        density_features(np.ones((3, 6)), np.ones((3, 6)), eps=0.0)
    with pytest.raises(ValueError):
        density_features(np.ones((3, 6)), np.ones((4, 6)))
    with pytest.raises(InvalidConfigError):
        DensityFeatures(window=0)
    with pytest.raises(InvalidConfigError):
        DensityFeatures(period_s=-1e-3)


def test_series_matches_explicit_windows_including_start_of_run():
    rng = np.random.default_rng(0)
    e, T = rng.normal(size=(12, 6)), rng.normal(size=(12, 6))
    window = 4
    rho = density_features_series(e, T, window=window)
    for k in range(12):
        lo = max(0, k - window + 1)
        np.testing.assert_allclose(
            rho[k], density_features(e[lo : k + 1], T[lo : k + 1]), rtol=1e-14
        )
    np.testing.assert_allclose(rho[0], 1.0 / (1.0 + EPS / np.abs(np.r_[e[0], T[0]])), rtol=1e-14)


def _simulate(sources, window, period_s, t_final):
    builder = DiagramBuilder()
    features = builder.AddSystem(DensityFeatures(window=window, period_s=period_s))
    for port, source in zip(("e_bar", "T"), sources):
        builder.Connect(builder.AddSystem(source).get_output_port(0), features.GetInputPort(port))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(t_final)
    context = features.GetMyContextFromRoot(simulator.get_context())
    return features.get_rho_output_port().Eval(context)


def test_system_matches_numpy_on_sines():
    # Signals that change sign and a window (4) shorter than the run (11 samples at 1 ms): the
    # ring buffer must wrap in the right order.
    amp_e, f_e, ph_e = (
        np.array([1e-3, 2e-3, 1e-3, 1e-3, 5e-4, 2e-4]),
        np.arange(1, 7) * 40.0,
        np.linspace(0, 1, 6),
    )
    amp_T, f_T, ph_T = np.linspace(0.1, 1, 6), np.arange(1, 7) * 25.0, np.linspace(1, 2, 6)
    rho = _simulate([Sine(amp_e, f_e, ph_e), Sine(amp_T, f_T, ph_T)], 4, 1e-3, 0.0105)
    t = np.arange(11) * 1e-3
    e = amp_e * np.sin(f_e * t[:, None] + ph_e)
    T = amp_T * np.sin(f_T * t[:, None] + ph_T)
    np.testing.assert_allclose(rho, density_features_series(e, T, window=4)[-1], rtol=1e-12)
    np.testing.assert_allclose(rho, density_features(e[-4:], T[-4:]), rtol=1e-12)


def test_system_with_constant_sources():
    e0 = np.array([0.0, 1e-3, -2e-3, 0.0, 1e-4, -5e-4])
    T0 = np.array([0.3, -0.3, 0.0, 1.0, -1.0, 0.2])
    rho = _simulate([ConstantVectorSource(e0), ConstantVectorSource(T0)], 50, 1e-3, 0.0035)
    expected = density_features(np.tile(e0, (4, 1)), np.tile(T0, (4, 1)))  # 4 samples so far
    np.testing.assert_allclose(rho, expected, rtol=1e-14)
    np.testing.assert_allclose(rho, [0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1, 1], atol=1e-5)


def test_system_raises_on_non_finite_input():
    e0 = np.zeros(6)
    e0[4] = np.nan
    with pytest.raises(SimulationDivergedError, match="non-finite e_bar"):
        _simulate([ConstantVectorSource(e0), ConstantVectorSource(np.ones(6))], 5, 1e-3, 0.002)


def test_features_from_the_controllers_window_equal_those_it_samples_itself():
    """The LQI buffers [e_bar, T] at its instants for the features (no callback of theirs per
    period): rho from that window equals rho of a DensityFeatures sampling the same signals,
    with a window (5) shorter than the run, so the ring wraps."""
    from stewart_drake.control.lqi.controller import LqiDiagram
    from stewart_drake.control.lqi.driver import LqiDriver
    from stewart_drake.robot.geometry import X_HOME, StewartGeometry
    from stewart_drake.robot.statics import holding_torques

    geometry, offset = StewartGeometry(), 5e-4
    builder = DiagramBuilder()
    lqi = builder.AddSystem(
        LqiDiagram(geometry, LqiDriver(), period_s=1e-3, offset_s=offset, feature_window=5)
    )
    pose = builder.AddSystem(
        Sine(np.r_[1e-3 * np.ones(6), np.zeros(6)], 30.0 * np.ones(12), np.linspace(0, 1, 12))
    )
    shift = builder.AddSystem(ConstantVectorSource(np.r_[X_HOME, np.zeros(6)]))
    x = builder.AddSystem(Adder(2, 12))
    builder.Connect(pose.get_output_port(0), x.get_input_port(0))
    builder.Connect(shift.get_output_port(), x.get_input_port(1))
    builder.Connect(x.get_output_port(), lqi.GetInputPort("x"))
    for port, value in (
        ("x_d", np.r_[X_HOME, np.zeros(12)]),
        ("T_ff", holding_torques(geometry, X_HOME)),
        ("omega", [1.0, 1.0]),
    ):
        builder.Connect(
            builder.AddSystem(ConstantVectorSource(value)).get_output_port(), lqi.GetInputPort(port)
        )
    applied = builder.AddSystem(
        Sine(np.linspace(0.1, 0.6, 6), 25.0 * np.ones(6), np.linspace(1, 2, 6))
    )
    builder.Connect(applied.get_output_port(0), lqi.GetInputPort("motor_torque_applied"))
    sampled = builder.AddSystem(DensityFeatures(window=5, period_s=1e-3, offset_s=offset))
    builder.Connect(lqi.GetOutputPort("e_bar"), sampled.GetInputPort("e_bar"))
    builder.Connect(applied.get_output_port(0), sampled.GetInputPort("T"))
    buffered = builder.AddSystem(DensityFeatures(window=5, buffered=True))
    builder.Connect(lqi.GetOutputPort("feature_window"), buffered.GetInputPort("feature_window"))
    simulator = Simulator(builder.Build())
    checked = 0
    for t in (0.0007, 0.0033, 0.0121, 0.0208):
        simulator.AdvanceTo(t)
        root = simulator.get_context()
        rho = [
            f.get_rho_output_port().Eval(f.GetMyContextFromRoot(root)) for f in (sampled, buffered)
        ]
        assert np.any(rho[0] != 0.0)
        np.testing.assert_array_equal(rho[1], rho[0])
        checked += 1
    assert checked == 4
