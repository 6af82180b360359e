"""References from files and user objects: the paper's manoeuvre is eqs. 37-38 with their
derivatives, a sine's rate and acceleration are its pose's, a bad CSV is refused naming the line,
an evaluate of one time at a time is wrapped. Every reference of the module against numbers
computed apart from it: a sine's quarter periods, the helix's circle, a step, a sweep's frequency,
phase (by quadrature), envelope and derivatives (by central differences), a cubic Drake holds
exactly; and the overflow check at its edge. These are the module's fast unit tests, the ones
tools/mutation.py runs."""

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


# -- every reference of the module against values computed apart from it ----------------------


def _finite_difference(trajectory, t, h):
    """The rate and acceleration by central differences of the pose and of the rate."""
    ahead, behind = trajectory.evaluate(t + h), trajectory.evaluate(t - h)
    return (ahead[0] - behind[0]) / (2 * h), (ahead[1] - behind[1]) / (2 * h)


def test_a_sine_at_its_quarter_periods():
    """x = offset + A sin(2 pi f t): at t = 0 the pose is the offset, the rate A 2 pi f and no
    acceleration; a quarter period later the pose is offset + A, the rate 0 and the acceleration
    -A (2 pi f)^2; the other axes stay at the offset."""
    offset = (0.0, 0.0, 0.0, 0.01, -0.02, 0.30)
    sine = SineTrajectory(amplitude=(0, 0, 0, 0, 0, 0.004), frequency_hz=(0, 0, 0, 0, 0, 2.5))
    sine = SineTrajectory(sine.amplitude, sine.frequency_hz, offset=offset)
    w = 2 * np.pi * 2.5
    x, v, a = sine.evaluate(np.array([0.0, 0.1, 0.2]))  # a quarter period is 0.1 s
    np.testing.assert_allclose(x[:, 5], [0.30, 0.304, 0.30], rtol=0, atol=1e-15)
    np.testing.assert_allclose(v[:, 5], [0.004 * w, 0.0, -0.004 * w], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a[:, 5], [0.0, -0.004 * w * w, 0.0], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(x[:, :5], np.tile(offset[:5], (3, 1)))
    np.testing.assert_array_equal(v[:, :5], 0.0)
    np.testing.assert_array_equal(a[:, :5], 0.0)


def test_every_registered_reference_carries_its_name():
    """A run labels its files by the reference's name: each name of TRAJECTORIES makes a
    reference of that name, through make_trajectory, as_trajectory and NamedReference; an unknown
    name is refused listing the known ones."""
    from stewart_drake.references.trajectories import (
        TRAJECTORIES,
        NamedReference,
        make_trajectory,
    )

    assert {"paper", "home", "helix", "step_phi", "step_Z", "sweep_theta", "sweep_Y"} <= set(
        TRAJECTORIES
    )
    t = np.linspace(0.0, 3.0, 7)
    for name in TRAJECTORIES:
        made = make_trajectory(name)
        assert made.name == name
        for other in (as_trajectory(name), NamedReference(name).make(None, 1.0, None)):
            assert other.name == name
            for mine, theirs in zip(other.evaluate(t), made.evaluate(t)):
                np.testing.assert_array_equal(mine, theirs)
    with pytest.raises(InvalidConfigError, match=r"unknown trajectory 'nope'; choose one of .*"):
        make_trajectory("nope")
    with pytest.raises(InvalidConfigError, match=r"'helix', 'home', 'paper'"):
        NamedReference("nope").validate()


def test_home_holds_the_home_pose():
    from stewart_drake.references.trajectories import hold_home

    x, v, a = hold_home().evaluate(np.linspace(0.0, 5.0, 11))
    np.testing.assert_array_equal(x, np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.30], (11, 1)))
    np.testing.assert_array_equal(v, 0.0)
    np.testing.assert_array_equal(a, 0.0)


def test_the_helix_is_the_circle_and_the_wobble_its_docstring_gives():
    """A 5 mm circle in X-Y at 2 Hz (X = 5 mm at t = 0, Y = 5 mm an eighth of a second later),
    its speed 2 pi 2 Hz 5 mm and its acceleration toward the centre; Z rising 3 mm at 0.25 Hz
    (at the top at t = 1 s), theta's 20 mrad wobble at 1 Hz (at its top at t = 0.25 s); phi and
    psi still."""
    from stewart_drake.references.trajectories import helix

    x, v, a = helix().evaluate(np.array([0.0, 0.125, 0.25, 1.0]))
    np.testing.assert_allclose(x[:, 3:5], [[5e-3, 0], [0, 5e-3], [-5e-3, 0], [5e-3, 0]], atol=1e-15)
    np.testing.assert_allclose(
        x[:, 5], 0.30 + 0.003 * np.sin(np.pi / 2 * np.array([0, 0.125, 0.25, 1]))
    )
    np.testing.assert_allclose(x[:, 1], [0.0, 0.02 * np.sin(np.pi / 4), 0.02, 0.0], atol=1e-15)
    np.testing.assert_array_equal(x[:, [0, 2]], 0.0)
    w = 2 * np.pi * 2.0
    t = np.linspace(0.0, 2.0, 41)
    x, v, a = helix().evaluate(t)
    np.testing.assert_allclose(np.hypot(x[:, 3], x[:, 4]), 5e-3, rtol=1e-14)
    np.testing.assert_allclose(np.hypot(v[:, 3], v[:, 4]), w * 5e-3, rtol=1e-14)
    np.testing.assert_allclose(a[:, 3:5], -w * w * x[:, 3:5], atol=1e-14)
    # rate and acceleration of the other axes: theta's and Z's by hand
    np.testing.assert_allclose(v[:, 1], 0.02 * 2 * np.pi * np.cos(2 * np.pi * t), atol=1e-15)
    np.testing.assert_allclose(
        a[:, 5], -0.003 * (np.pi / 2) ** 2 * np.sin(np.pi / 2 * t), atol=1e-15
    )
    np.testing.assert_array_equal(v[:, [0, 2]], 0.0)
    np.testing.assert_array_equal(a[:, [0, 2]], 0.0)


def test_a_sine_is_refused_exactly_where_it_would_overflow():
    """check_sine_bounds: with A = 1e300 the acceleration A (2 pi f)^2 is 1e308 at 2 pi f = 1e4
    rad/s, below float64's largest (1.8e308), and overflows at 2e4 rad/s: the first sine is
    accepted and finite everywhere, the second refused naming its axis, amplitude and frequency;
    an offset and an amplitude whose sum overflows are refused too."""
    ok = SineTrajectory(
        amplitude=(0, 0, 0, 0, 1e300, 0), frequency_hz=(0, 0, 0, 0, 1e4 / (2 * np.pi), 0)
    )
    for part in ok.evaluate(np.linspace(0.0, 1e-3, 17)):
        assert np.isfinite(part).all()
    assert ok.evaluate(np.pi / 2 / 1e4)[2][4] == pytest.approx(-1e308, rel=1e-12)
    f = 2e4 / (2 * np.pi)
    assert np.isinf(1e300 * (2 * np.pi * f) ** 2)
    with pytest.raises(
        InvalidConfigError,
        match=r"^wild: axis 4 overflows float64 \(amplitude 1e\+300, frequency 3\.18e\+03 Hz\); "
        r"use SI units$",
    ):
        SineTrajectory(
            amplitude=(0, 0, 0, 0, 1e300, 0), frequency_hz=(0, 0, 0, 0, f, 0), name="wild"
        )
    with pytest.raises(
        InvalidConfigError, match=r"axis 2 overflows float64 \(amplitude 1e\+308, frequency 0 Hz\)"
    ):
        SineTrajectory(amplitude=(0, 0, 1e308, 0, 0, 0), offset=(0, 0, 1e308, 0, 0, 0.3))


def test_a_sine_s_numbers_are_six_each():
    with pytest.raises(InvalidConfigError, match=r"sine: amplitude must have shape \(6,\)"):
        SineTrajectory(amplitude=(0.1, 0.2, 0.3))
    with pytest.raises(InvalidConfigError, match=r"sine: phase must have shape \(6,\)"):
        SineTrajectory(phase=np.zeros((1, 6)))


def test_a_sine_reference_of_a_scenario_is_its_sine():
    """SineReference's fields make the SineTrajectory of the same numbers: the pose at t = 0 is
    offset + A sin(phase), a quarter period on the amplitude is added to the offset."""
    from stewart_drake.references.trajectories import SineReference

    config = SineReference(
        amplitude=[0.0, 0.01, 0.0, 0.002, 0.0, 0.0],
        frequency_hz=[0.0, 0.5, 0.0, 1.0, 0.0, 0.0],
        phase=[0.0, 0.0, 0.0, np.pi / 2, 0.0, 0.0],
        name="mine",
    )
    config.validate()
    sine = config.make(None, 1.0, None)
    assert sine.name == "mine"
    x = sine.evaluate(np.array([0.0, 0.5]))[0]
    np.testing.assert_allclose(x[0], [0, 0, 0, 0.002, 0, 0.30], atol=1e-15)
    np.testing.assert_allclose(x[1], [0, 0.01, 0, -0.002, 0, 0.30], atol=1e-15)
    with pytest.raises(InvalidConfigError, match="must have shape"):
        SineReference(offset=[0.0, 0.3]).validate()


def test_a_step_and_its_sizes():
    """x_d = offset + size on one axis from t_step on (at t_step itself too), no rate and no
    acceleration; step(axis) takes 20 mrad or 5 mm at 0.5 s by name or index."""
    from stewart_drake.references.trajectories import StepTrajectory, step

    offset = [0.0, 0.0, 0.01, 0.0, 0.0, 0.29]
    s = StepTrajectory(axis="psi", size=-0.03, t_step=0.25, offset=offset)
    assert s.axis == 2 and s.offset == (0.0, 0.0, 0.01, 0.0, 0.0, 0.29)
    x, v, a = s.evaluate(np.array([0.0, 0.2499, 0.25, 1.0]))
    np.testing.assert_allclose(x[:, 2], [0.01, 0.01, -0.02, -0.02], rtol=0, atol=1e-17)
    np.testing.assert_array_equal(np.delete(x, 2, axis=1), np.tile(np.delete(offset, 2), (4, 1)))
    np.testing.assert_array_equal(v, 0.0)
    np.testing.assert_array_equal(a, 0.0)
    assert v.shape == a.shape == (4, 6) and s.evaluate(0.3)[0].shape == (6,)
    for axis, index, size in (("phi", 0, 0.02), ("theta", 1, 0.02), (3, 3, 0.005), ("Z", 5, 0.005)):
        made = step(axis)
        assert (made.axis, made.size, made.t_step) == (index, size, 0.5)
        x = made.evaluate(np.array([0.49, 0.5]))[0]
        np.testing.assert_allclose(x[1] - x[0], np.eye(6)[index] * size, rtol=0, atol=1e-17)
        np.testing.assert_array_equal(x[0], [0, 0, 0, 0, 0, 0.30])
    assert step(np.int64(4)).name == "step_Y"


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda S: S(axis="W"), r"unknown axis 'W'; choose one of \('phi'"),
        (lambda S: S(axis=6), r"axis must be 0..5 or one of \('phi'.*got 6"),
        (lambda S: S(axis=-1), r"axis must be 0..5 .*got -1"),
        (lambda S: S(axis=2.0), r"axis must be 0..5 .*got 2.0"),
        (lambda S: S(t_step=-0.1), r"step: t_step must be a finite number in \[0, inf\]"),
        (lambda S: S(size="big"), r"step: size must be a number"),
        (lambda S: S(offset=np.zeros((2, 6))), r"step: offset must be one pose \(6,\).*\(2, 6\)"),
        (lambda S: S(offset=(0, 0, 0, 0, 0, 3e3)), r"step: offset has a position beyond 1000 m"),
    ],
)
def test_a_step_s_bad_numbers_are_refused_naming_them(make, message):
    from stewart_drake.references.trajectories import StepTrajectory

    with pytest.raises(InvalidConfigError, match=message):
        make(StepTrajectory)


def test_a_step_at_zero_is_allowed():
    from stewart_drake.references.trajectories import StepTrajectory

    x = StepTrajectory(axis=0, size=0.1, t_step=0.0).evaluate(0.0)[0]
    assert x[0] == 0.1


def _chirp(**kw):
    from stewart_drake.references.trajectories import ChirpTrajectory

    return ChirpTrajectory(
        **{"axis": 3, "amplitude": 1e-3, "f0_hz": 2.0, "f1_hz": 32.0, "duration_s": 4.0, **kw}
    )


def test_a_sweep_s_frequency_and_phase():
    """f(t) = f0 (f1/f0)^(t/T): f0 at the start, the geometric mean halfway, f1 at T and held
    after; the phase is the integral of 2 pi f (by quadrature), 2 pi f1 a second after T."""
    from scipy.integrate import quad

    chirp = _chirp()
    np.testing.assert_allclose(
        chirp.frequency(np.array([0.0, 2.0, 4.0, 9.0])), [2, 8, 32, 32], rtol=1e-14
    )
    for t in (0.0, 0.7, 2.0, 3.9, 4.0):
        integral = quad(lambda s: 2 * np.pi * 2.0 * 16.0 ** (s / 4.0), 0.0, t, epsabs=1e-12)[0]
        assert chirp.phase(t) == pytest.approx(integral, rel=1e-12, abs=1e-12)
    assert chirp.phase(5.5) - chirp.phase(4.0) == pytest.approx(2 * np.pi * 32.0 * 1.5, rel=1e-12)


def test_a_sweep_s_envelope_is_the_amplitude_up_to_its_corner_then_falls_as_one_over_f_squared():
    """sweep("Z"): 0.2 mm up to the corner, where 0.2 mm at f would need more than the
    acceleration cap (31.6 Hz), then cap / (2 pi f)^2: 0.125 mm at 40 Hz, 0.08 mm at 50 Hz (the
    docstring's figures); its derivatives those of the envelope by central differences."""
    from stewart_drake.references.trajectories import sweep

    z = sweep("Z")
    assert (z.axis, z.name, z.f0_hz, z.f1_hz, z.duration_s) == (5, "sweep_Z", 1.0, 50.0, 8.0)
    at = lambda f: 8.0 * np.log(f) / np.log(50.0)  # noqa: E731 - the time the sweep is at f
    A, A_dot, A_ddot = z.envelope(np.array([at(20.0), at(31.0), at(32.0), at(40.0), 8.0, 12.0]))
    np.testing.assert_allclose(
        A, [2e-4, 2e-4, 2e-4 * (31.62 / 32) ** 2, 1.25e-4, 8e-5, 8e-5], rtol=2e-4
    )
    np.testing.assert_array_equal(A_dot[[0, 1, 5]], 0.0)
    np.testing.assert_array_equal(A_ddot[[0, 1, 5]], 0.0)
    t, h = np.array([at(32.0), at(40.0), at(49.0)]), 1e-5
    ahead, behind, here = z.envelope(t + h), z.envelope(t - h), z.envelope(t)
    np.testing.assert_allclose(A_dot[3], (ahead[0] - behind[0])[1] / (2 * h), rtol=1e-8)
    np.testing.assert_allclose(here[1], (ahead[0] - behind[0]) / (2 * h), rtol=1e-8)
    np.testing.assert_allclose(here[2], (ahead[1] - behind[1]) / (2 * h), rtol=1e-8)
    # an angle: 2 mrad, 0.8 mrad at 50 Hz; a negative amplitude flips the envelope
    phi = sweep("phi")
    assert (phi.axis, phi.name) == (0, "sweep_phi")
    np.testing.assert_allclose(phi.envelope(np.array([0.0, 10.0]))[0], [2e-3, 8e-4], rtol=1e-12)
    flipped = _chirp(amplitude=-1e-3, max_acceleration=5.0)
    for mine, theirs in zip(
        flipped.envelope(np.linspace(0, 6, 13)),
        _chirp(max_acceleration=5.0).envelope(np.linspace(0, 6, 13)),
    ):
        np.testing.assert_array_equal(mine, -theirs)
    A, A_dot, A_ddot = _chirp(amplitude=-1e-3).envelope(np.array([1.0, 3.0]))
    np.testing.assert_array_equal(A, -1e-3)
    np.testing.assert_array_equal(A_dot, 0.0)
    np.testing.assert_array_equal(A_ddot, 0.0)


@pytest.mark.parametrize("max_acceleration", [None, 5.0])
def test_a_sweep_s_rate_and_acceleration_are_the_derivatives_of_its_pose(max_acceleration):
    """On its axis only, from the offset; against central differences (h = 1e-6 s) below and
    above the corner of the cap and after the sweep holds f1."""
    chirp = _chirp(
        amplitude=-1e-3, max_acceleration=max_acceleration, offset=(0, 0, 0, 0.001, 0, 0.3)
    )
    t = np.concatenate([np.linspace(0.01, 3.95, 157), np.linspace(4.05, 5.0, 21)])
    x, v, a = chirp.evaluate(t)
    fd_v, fd_a = _finite_difference(chirp, t, 1e-6)
    scale = np.abs(a[:, 3]).max()
    np.testing.assert_allclose(v, fd_v, rtol=0, atol=1e-7 * np.abs(v[:, 3]).max())
    np.testing.assert_allclose(a, fd_a, rtol=0, atol=1e-6 * scale)
    env = chirp.envelope(t)[0]
    np.testing.assert_allclose(x[:, 3], 0.001 + env * np.sin(chirp.phase(t)), rtol=0, atol=1e-18)
    np.testing.assert_array_equal(np.delete(x, 3, axis=1), np.tile([0, 0, 0, 0, 0.3], (t.size, 1)))
    assert chirp.evaluate(1.0)[0].shape == (6,)
    if max_acceleration:  # the cap holds: |a| at most the cap's and what the envelope's own
        assert np.abs(env).min() < 1e-3  # derivatives add, near it
        assert 4.0 < scale < 5.0 * 1.2


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"f0_hz": 32.0}, r"sweep: need f0_hz < f1_hz, got 32.0, 32.0"),
        ({"f0_hz": 0.0}, r"sweep: f0_hz must be a finite number in \(0, inf\]"),
        ({"f1_hz": -1.0}, r"sweep: f1_hz must be a finite number in \(0"),
        ({"duration_s": 0.0}, r"sweep: duration_s must be a finite number in \(0"),
        ({"amplitude": np.nan}, r"sweep: amplitude must be a finite number in \[-inf, inf\]"),
        ({"max_acceleration": 0.0}, r"sweep: max_acceleration must be a finite number in \(0"),
        ({"axis": "Q"}, r"unknown axis 'Q'"),
        ({"offset": (0, 0, 0, 0, 0)}, r"sweep: offset must have shape \(\.\.\., 6\)"),
    ],
)
def test_a_sweep_s_bad_numbers_are_refused_naming_them(kw, message):
    with pytest.raises(InvalidConfigError, match=message):
        _chirp(**kw)


def test_a_sweep_takes_a_negative_amplitude_and_numbers_of_any_type():
    chirp = _chirp(
        amplitude=-2, f0_hz=np.float32(1), f1_hz=3, duration_s=np.int64(2), max_acceleration=7
    )
    assert (
        chirp.amplitude,
        chirp.f0_hz,
        chirp.f1_hz,
        chirp.duration_s,
        chirp.max_acceleration,
    ) == (
        -2.0,
        1.0,
        3.0,
        2.0,
        7.0,
    )
    assert all(type(v) is float for v in (chirp.amplitude, chirp.f0_hz, chirp.max_acceleration))


def test_a_drake_trajectory_is_read_with_its_derivatives():
    """A cubic Hermite PiecewisePolynomial through a cubic per axis is that cubic: its pose, rate
    and acceleration at any times (any shape) are the cubic's, written by hand."""
    from pydrake.trajectories import PiecewisePolynomial

    from stewart_drake.references.trajectories import DrakeTrajectory

    c = np.array(
        [
            [0.1, -0.2, 0.05, 0.01, 0.0, 0.3],
            [1, 2, 3, 4, 5, 6],
            [0.5, 0, -1, 0, 1, 0],
            [0.1, 0.2, 0, -0.3, 0, 0.01],
        ]
    )
    p = lambda t: c[0] + c[1] * t + c[2] * t**2 + c[3] * t**3  # noqa: E731
    dp = lambda t: c[1] + 2 * c[2] * t + 3 * c[3] * t**2  # noqa: E731
    ddp = lambda t: 2 * c[2] + 6 * c[3] * t  # noqa: E731
    breaks = [0.0, 0.5, 1.2, 2.0]
    poly = PiecewisePolynomial.CubicHermite(
        breaks, np.column_stack([p(b) for b in breaks]), np.column_stack([dp(b) for b in breaks])
    )
    ref = as_trajectory(poly)
    assert isinstance(ref, DrakeTrajectory) and ref.name == "drake_trajectory"
    assert (ref.start_time, ref.end_time) == (0.0, 2.0)
    t = np.array([[0.0, 0.3, 0.5], [1.0, 1.7, 2.0]])
    x, v, a = ref.evaluate(t)
    assert x.shape == v.shape == a.shape == (2, 3, 6)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(x[i, j], p(t[i, j]), rtol=0, atol=1e-13)
            np.testing.assert_allclose(v[i, j], dp(t[i, j]), rtol=0, atol=1e-12)
            np.testing.assert_allclose(a[i, j], ddp(t[i, j]), rtol=0, atol=1e-11)
    assert DrakeTrajectory(poly, name="mine").evaluate(0.3)[0].shape == (6,)
    with pytest.raises(InvalidConfigError, match=r"6 rows and 1 column .*got \(3, 1\)"):
        DrakeTrajectory(PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.zeros((3, 2))))
    with pytest.raises(InvalidConfigError, match=r"6 rows and 1 column .*got \(6, 2\)"):
        DrakeTrajectory(PiecewisePolynomial.ZeroOrderHold([0.0, 1.0], [np.zeros((6, 2))] * 2))
    with pytest.raises(InvalidConfigError, match=r"got list"):
        DrakeTrajectory([1, 2])


def test_a_reference_is_used_as_it_is_when_it_evaluates_arrays(tmp_path):
    """as_trajectory keeps an object whose evaluate takes an array of times and returns three
    (n, 6) arrays; one that answers with one pose whatever the times, or that takes one time
    only, is wrapped and evaluated per time; a CSV path of either case of suffix is read."""
    sine = paper_manoeuvre()
    assert as_trajectory(sine) is sine

    class Fixed:
        name = "fixed"

        def evaluate(self, t):
            return np.full(6, float(np.sum(t))), np.zeros(6), np.zeros(6)

    wrapped = as_trajectory(Fixed())
    assert isinstance(wrapped, ScalarEvaluate)
    x = wrapped.evaluate(np.array([0.5, 2.0, 3.0]))[0]
    np.testing.assert_array_equal(x, np.repeat([[0.5], [2.0], [3.0]], 6, axis=1))

    class ShortRun:
        """Defined over a 0.5 s run only, one time at a time, as a user's table would be."""

        def evaluate(self, t):
            if not 0.0 <= float(t) <= 0.5:
                raise ValueError(f"no sample at {t}")
            return tuple(np.asarray(v)[0] for v in sine.evaluate(np.array([float(t)])))

    short = as_trajectory(ShortRun())
    assert isinstance(short, ScalarEvaluate) and short.name == "custom"
    assert ScalarEvaluate(ShortRun(), name="mine").name == "mine"
    np.testing.assert_allclose(
        short.evaluate(np.array([0.25]))[0], sine.evaluate(np.array([0.25]))[0]
    )

    class FiveNumbers:
        def evaluate(self, t):
            return np.zeros(5), np.zeros(5), np.zeros(5)

    with pytest.raises(
        InvalidConfigError,
        match=r"^FiveNumbers\.evaluate\(t\) must return \(pose, rate, acceleration\)",
    ):
        as_trajectory(FiveNumbers())
    with pytest.raises(InvalidConfigError, match=r"an object with evaluate\(t\); got float$"):
        as_trajectory(3.0)
    for suffix in ("csv", "CSV"):
        f = tmp_path / f"r.{suffix}"
        f.write_text(
            "t,phi,theta,psi,X,Y,Z\n0,0,0,0,0,0,0.3\n0.1,0,0,0,0.001,0,0.3\n0.2,0,0,0,0.002,0,0.3\n"
        )
        for source in (f, str(f)):
            ref = as_trajectory(source)
            assert ref.name == "r"
            np.testing.assert_allclose(ref.evaluate(0.1)[0], [0, 0, 0, 0.001, 0, 0.3], atol=1e-15)


def test_a_step_s_and_a_sweep_s_numbers_are_plain_floats_and_their_axis_an_index():
    """Whatever type the numbers come in (numpy scalars, ints), the trajectory holds floats, as
    a JSON file takes them, and its axis as the index a name gives."""
    import dataclasses
    import json

    from stewart_drake.references.trajectories import ChirpTrajectory, StepTrajectory

    s = StepTrajectory(axis=np.int64(1), size=np.float32(0.25), t_step=np.float32(1.5))
    assert json.loads(json.dumps(dataclasses.asdict(s)))["size"] == 0.25
    assert (s.axis, s.size, s.t_step) == (1, 0.25, 1.5)
    c = ChirpTrajectory(axis="X", amplitude=np.float32(0.5))
    assert json.loads(json.dumps(dataclasses.asdict(c)))["amplitude"] == 0.5
    assert c.axis == 3 and ChirpTrajectory(axis="psi").axis == 2


def test_a_sweep_by_name_takes_the_position_or_the_angle_amplitude():
    """sweep() is on Z; a position (X, Y, Z) takes 0.2 mm, an angle (phi, theta, psi) 2 mrad."""
    from stewart_drake.references.trajectories import sweep

    assert (sweep().axis, sweep().name) == (5, "sweep_Z")
    for axis in ("X", "Y", "Z"):
        assert sweep(axis).amplitude == 2e-4 and sweep(axis).max_acceleration == pytest.approx(
            8e-5 * (2 * np.pi * 50) ** 2
        )
    for axis in ("phi", "theta", "psi"):
        assert sweep(axis).amplitude == 2e-3 and sweep(axis).max_acceleration == pytest.approx(
            8e-4 * (2 * np.pi * 50) ** 2
        )
