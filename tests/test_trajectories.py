"""References from files and user objects: the paper's manoeuvre is eqs. 37-38 with their
derivatives, a sine's rate and acceleration are its pose's, a bad CSV is refused naming the line,
an evaluate of one time at a time is wrapped."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.references.trajectories import (
    ScalarEvaluate,
    SineTrajectory,
    as_trajectory,
    paper_manoeuvre,
)
from stewart_drake.run.scenario import (
    Scenario,
)
from stewart_drake.run.simulate import run_experiment


def test_the_paper_manoeuvre_is_eqs_37_38_with_their_derivatives():
    """phi = (pi/6) sin 2t rad, Z = 0.30 + 0.05 sin 2t m, the other axes at home; the rates and
    accelerations differentiated by hand."""
    t = np.linspace(0.0, 10.0, 41)
    x, v, a = paper_manoeuvre().evaluate(t)
    zero = np.zeros_like(t)
    np.testing.assert_allclose(x[:, 0], np.pi / 6 * np.sin(2 * t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(v[:, 0], np.pi / 3 * np.cos(2 * t), rtol=0, atol=1e-14)
    np.testing.assert_allclose(a[:, 0], -2 * np.pi / 3 * np.sin(2 * t), rtol=0, atol=1e-14)
    np.testing.assert_allclose(x[:, 5], 0.30 + 0.05 * np.sin(2 * t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(v[:, 5], 0.10 * np.cos(2 * t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(a[:, 5], -0.20 * np.sin(2 * t), rtol=0, atol=1e-15)
    for k in range(1, 5):
        for got in (x[:, k], v[:, k], a[:, k]):
            np.testing.assert_array_equal(got, zero)


def test_a_sine_s_rate_and_acceleration_are_the_derivatives_of_its_pose():
    """Every axis with its own amplitude, frequency, phase and offset: the rate against a central
    difference of the pose, the acceleration against one of the rate (step 1e-6 s: the
    differences' error is about 1e-8 of the value)."""
    sine = SineTrajectory(
        amplitude=(0.1, -0.05, 0.02, 0.01, 0.004, -0.02),
        frequency_hz=(0.2, 0.5, 1.1, 0.3, 2.0, 0.25),
        phase=(0.0, 0.4, -1.0, 2.5, 3.0, -0.3),
        offset=(0.01, 0.0, -0.02, 0.001, 0.0, 0.3),
    )
    t, h = np.linspace(0.05, 6.0, 97), 1e-6
    x, v, a = sine.evaluate(t)
    ahead, behind = sine.evaluate(t + h), sine.evaluate(t - h)
    np.testing.assert_allclose(v, (ahead[0] - behind[0]) / (2 * h), rtol=0, atol=2e-8)
    np.testing.assert_allclose(a, (ahead[1] - behind[1]) / (2 * h), rtol=0, atol=1e-7)
    # and the pose itself at t = 0: offset + amplitude sin(phase)
    np.testing.assert_allclose(
        sine.evaluate(0.0)[0],
        np.add(sine.offset, np.multiply(sine.amplitude, np.sin(sine.phase))),
        atol=1e-15,
    )


def test_bad_csv_files_name_the_line(tmp_path):
    f = tmp_path / "r.csv"
    f.write_text("t,x\n0,1\n")
    with pytest.raises(InvalidConfigError, match=r"header t,phi,theta,psi,X,Y,Z"):
        as_trajectory(f)
    f.write_text("t,phi,theta,psi,X,Y,Z\n0,0,0,0,0,0,0.3\n0.1,0,0,0,0,0,nan\n")
    with pytest.raises(InvalidConfigError, match=r"line 3: expected 7 finite numbers"):
        as_trajectory(f)
    f.write_text("t,phi,theta,psi,X,Y,Z\n0,0,0,0,0,0,0.3\n0.1,0,0,0,0,0,0.3\n")
    with pytest.raises(InvalidConfigError, match=r"at least 3 samples"):
        as_trajectory(f)
    with pytest.raises(MissingFileError):
        as_trajectory(tmp_path / "none.csv")


def test_an_evaluate_of_one_time_is_wrapped():
    class OneAtATime:
        name = "scalar"

        def evaluate(self, t):
            if np.ndim(t):
                raise TypeError("one time at a time")
            return tuple(np.asarray(v)[0] for v in paper_manoeuvre().evaluate(np.array([t])))

    wrapped = as_trajectory(OneAtATime())
    assert isinstance(wrapped, ScalarEvaluate) and wrapped.name == "scalar"
    t = np.array([0.1, 0.2, 0.3])
    for got, want in zip(wrapped.evaluate(t), paper_manoeuvre().evaluate(t)):
        np.testing.assert_allclose(got, want, rtol=1e-15)
    result = run_experiment(Scenario(duration_s=0.2), reference=OneAtATime())
    assert result.config_summary["trajectory"] == "scalar" and result.metrics["finite"]
    with pytest.raises(InvalidConfigError, match="an object with evaluate"):
        as_trajectory(3.0)


def test_the_spline_of_samples_is_drake_s_c2_spline_held_at_its_ends():
    """CubicSplineTrajectory (scipy's not-a-knot spline, coefficient arrays) against Drake's
    PiecewisePolynomial.CubicWithContinuousSecondDerivatives on uneven samples: pose, rate and
    acceleration agree, and outside the samples both hold the end's values."""
    from pydrake.trajectories import PiecewisePolynomial

    from stewart_drake.references.samples import CubicSplineTrajectory

    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.01, 0.2, 40)) - 0.01
    poses = rng.normal(scale=[0.1, 0.1, 0.1, 0.01, 0.01, 0.01], size=(40, 6))
    ours = CubicSplineTrajectory(t, poses, name="s")
    drake = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, poses.T, False)
    q = np.concatenate([[t[0] - 1.0], np.linspace(t[0], t[-1], 997), [t[-1] + 1.0]])
    for k, mine in enumerate(ours.evaluate(q)):
        theirs = (
            np.asarray(drake.MakeDerivative(k).vector_values(q.tolist())).T
            if k
            else (np.asarray(drake.vector_values(q.tolist())).T)
        )
        assert mine.shape == (q.size, 6)
        assert np.abs(mine - theirs).max() <= 1e-9 * np.abs(theirs).max(), k
    assert ours.evaluate(5.0)[0].shape == (6,) and (ours.start_time, ours.end_time) == (t[0], t[-1])


def test_the_spline_s_derivatives_made_per_stretch_are_scipy_s_whole_ones_to_the_bit():
    """The rate and acceleration are made for the intervals asked only (no whole-spline copies):
    every value equals scipy's ``derivative(1)`` and ``derivative(2)`` of the whole spline, at
    the breakpoints themselves, between them, in stretches and one time at a time."""
    from scipy.interpolate import CubicSpline

    from stewart_drake.references.samples import CubicSplineTrajectory

    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.05, 0.3, 500))
    poses = rng.standard_normal((500, 6))
    whole = CubicSpline(t, poses, axis=0, bc_type="not-a-knot")
    ours = CubicSplineTrajectory(t, poses)
    for q in (
        np.linspace(t[0] - 1.0, t[-1] + 1.0, 20_001),
        t,
        t[200:203],
        np.asarray(t[7]),
        rng.uniform(t[0], t[-1], 999),
    ):
        clamped = np.clip(q, t[0], t[-1])
        for k, value in enumerate(ours.evaluate(q)):
            np.testing.assert_array_equal(
                value, whole.derivative(k)(clamped) if k else whole(clamped)
            )
