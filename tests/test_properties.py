"""Property-based: every public kinematics and controller entry point returns a finite
result or raises a typed StewartError, for any input (NaN, inf, huge, wrong shapes included).

Reproducible (``derandomize=True``); each test checks its own count when its examples are
done (:func:`_settings`): at least two thirds of its examples ran (>= 2000 of the 3000 in
total) and every function it names reached a finite result at least 20 times, whatever
order or subset of the tests runs.
An untyped exception (numpy's ValueError, LinAlgError, TypeError) fails the test that meets it.
"""

import functools
from collections import Counter

import numpy as np
import pytest
import scipy.linalg
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stewart_drake.base.errors import StewartError, UnreachablePoseError
from stewart_drake.control.features import density_features
from stewart_drake.control.lqi.controller import LqiController
from stewart_drake.control.lqi.driver import LqiScales
from stewart_drake.control.lqi.gain import error_model, hautus_checks, input_matrix, lqi_gain
from stewart_drake.control.tuner.ann import TunerModel
from stewart_drake.control.tuner.network import load_tuner
from stewart_drake.references.trajectories import SineTrajectory
from stewart_drake.robot import forward_kinematics, kinematics, limits, statics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import LqiDriver, NamedReference, Scenario
from stewart_drake.station.guard import GuardConfig

GEOMETRY = StewartGeometry()
EXAMPLES = Counter()
RETURNED = Counter()  # calls that returned a finite result, per function


#: Finite results each function named in a test's ``reaches`` must give in that test.
MIN_RETURNED = 20


def _settings(n, reaches=()):
    """Hypothesis settings of n examples, and the test's own count, checked once they are done:
    at least 2 n / 3 examples ran, and each function of ``reaches`` (its ``__qualname__``)
    returned a finite result at least MIN_RETURNED times, not only refusals (a strategy that
    drifts to all-invalid inputs fails here). The counters are reset before the examples, so
    the check needs no other test and no order."""
    hypothesis_settings = settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )

    def decorate(test):
        test = hypothesis_settings(test)

        @functools.wraps(test)
        def counted(*args, **kwargs):
            EXAMPLES.clear()
            RETURNED.clear()
            test(*args, **kwargs)
            assert sum(EXAMPLES.values()) >= 2 * n / 3, (n, EXAMPLES)
            short = {name: RETURNED[name] for name in reaches if RETURNED[name] < MIN_RETURNED}
            assert not short, f"finite results below {MIN_RETURNED}: {short} (all: {RETURNED})"

        return counted

    return decorate


def _finite(out):
    """Assert every number in a (nested) result is finite; returns it."""
    if isinstance(out, dict):
        for v in out.values():
            _finite(v)
    elif isinstance(out, (tuple, list)):
        for v in out:
            _finite(v)
    elif isinstance(out, (np.ndarray, float, int, np.floating, np.integer)):
        assert np.all(np.isfinite(out)), out
    return out


def _call(fn, *args, **kwargs):
    """fn(...) if it returns finite numbers; None if it raised a StewartError."""
    try:
        out = fn(*args, **kwargs)
    except StewartError as err:
        assert str(err), "typed errors must say something"
        return None
    RETURNED[getattr(fn, "__qualname__", str(fn))] += 1
    return _finite(out)


# -- strategies -----------------------------------------------------------------------------------

any_float = st.floats()  # NaN, +-inf, huge, subnormal
scale = np.array([0.4, 0.4, 0.5, 0.1, 0.1, 0.1])


@st.composite
def near_home(draw, spread=1.0):
    """Poses around home, mostly reachable, some past the edge."""
    u = draw(hnp.arrays(np.float64, 6, elements=st.floats(-1.0, 1.0)))
    return X_HOME + spread * u * scale


wild_pose = hnp.arrays(np.float64, 6, elements=any_float)
wrong_shape = hnp.arrays(
    np.float64, hnp.array_shapes(max_dims=3, max_side=7), elements=st.floats(-1.0, 1.0)
).filter(lambda a: a.shape[-1:] != (6,))
batch = (
    st.integers(1, 5).flatmap(lambda n: st.lists(near_home(), min_size=n, max_size=n)).map(np.array)
)
poses = st.one_of(
    near_home(),
    near_home(),
    wild_pose,
    wrong_shape,
    batch,
    st.just(np.array([0, 0, 0, 0, 0, np.nan])),
    st.just(X_HOME * 1e200),
)


# -- kinematics -----------------------------------------------------------------------------------


@_settings(400, reaches=("ik", "limit_margins", "singularity_measures"))
@given(x=poses)
def test_ik_and_reach_ratio(x):
    EXAMPLES["ik"] += 1
    theta = _call(kinematics.ik, GEOMETRY, x)
    try:
        ratio = kinematics.leg_reach_ratio(GEOMETRY, x)
    except StewartError:
        assert theta is None
        return
    assert not np.any(np.isnan(ratio))
    reachable = bool(np.all(np.abs(ratio) <= 1.0))
    assert (theta is not None) == reachable
    if theta is not None:
        assert theta.shape == np.shape(x)
    # typed errors where a leg cannot close, never NaN
    margins = _call(limits.limit_margins, GEOMETRY, x)
    measures = _call(kinematics.singularity_measures, GEOMETRY, x)
    assert (margins is not None) == (measures is not None) == reachable


@_settings(400, reaches=("jacobian", "tau", "wrench_map", "holding_torques"))
@given(x=poses, with_theta=st.booleans())
def test_jacobian_tau_wrench_and_holding_torques(x, with_theta):
    EXAMPLES["jacobian"] += 1
    theta = None
    if with_theta:
        theta = _call(kinematics.ik, GEOMETRY, x)
        if theta is None:
            return
    J = _call(kinematics.jacobian, GEOMETRY, x, theta)
    tau = _call(kinematics.tau, GEOMETRY, x, theta)
    W = _call(kinematics.wrench_map, GEOMETRY, x, theta)
    T = _call(statics.holding_torques, GEOMETRY, x, theta)
    if J is not None:
        np.testing.assert_array_equal(tau, np.swapaxes(J, -1, -2))
        assert W is not None and W.shape == J.shape
        if T is not None:  # J^T T = dV/dx, |T| below 1e3 N m near home
            assert T.shape == np.shape(x)


@_settings(150, reaches=("fk",))
@given(
    theta=st.one_of(
        near_home().map(lambda x: kinematics.ik_unchecked(GEOMETRY, x)[0]),
        hnp.arrays(np.float64, 6, elements=st.floats(-2.0, 2.0)),
        hnp.arrays(np.float64, 6, elements=any_float),
        wrong_shape,
        near_home().map(lambda x: kinematics.ik_unchecked(GEOMETRY, x)[0]),
    ),
    tol=st.one_of(st.just(1e-12), any_float),
    max_iter=st.sampled_from([50, 0, 3]),
)
def test_fk(theta, tol, max_iter):
    EXAMPLES["fk"] += 1
    out = _call(forward_kinematics.fk, GEOMETRY, theta, tol=tol, max_iter=max_iter)
    if out is not None:
        x, status = out
        assert status.converged and status.residual <= tol
        np.testing.assert_allclose(
            kinematics.wrap_angle(kinematics.ik(GEOMETRY, x) - theta), 0.0, atol=max(10 * tol, 1e-9)
        )


@_settings(150)
@given(
    n=st.integers(0, 12),
    base=near_home(spread=0.6),
    step=st.floats(1e-3, 0.2),
    direction=hnp.arrays(np.float64, 6, elements=st.floats(-1, 1)),
    poison=st.sampled_from([None, "nan_x", "inf_t", "unsorted", "shape"]),
    cond_threshold=st.one_of(st.just(200.0), any_float),
    sigma=st.one_of(st.just(0.01), any_float),
)
def test_validate_trajectory(n, base, step, direction, poison, cond_threshold, sigma):
    EXAMPLES["validate_trajectory"] += 1
    t = step * np.arange(n)
    x = base + np.outer(np.linspace(0, 1, n), 0.5 * direction * scale)
    if poison == "nan_x" and n:
        x[-1, 2] = np.nan
    elif poison == "inf_t" and n:
        t[0] = -np.inf
    elif poison == "unsorted" and n > 1:
        t = t[::-1]
    elif poison == "shape":
        x = x[:, :5]
    try:
        report = limits.validate_trajectory(
            GEOMETRY,
            t,
            x,
            cond_threshold=cond_threshold,
            min_sigma_min_inv=sigma,
            raise_refused=True,
        )
    except StewartError:
        return
    assert report.ok and np.isfinite(report.max_cond) and report.max_cond <= cond_threshold
    assert report.min_sigma_min_inv >= sigma and report.summary().startswith("OK")


# -- controller -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def controller():
    return LqiController(GEOMETRY, LqiDriver())


valid_omega = st.floats(1e-3, 1e3)
omegas = st.one_of(
    valid_omega,
    valid_omega,
    valid_omega,
    st.floats(0.1, 10.0),
    any_float,
    st.just("1"),
    st.just(None),
)


@_settings(300, reaches=("LqiController.gain",))
@given(
    x=st.one_of(near_home(0.7), near_home(0.7), near_home(0.7), wild_pose, wrong_shape),
    omega_Q=omegas,
    omega_R=omegas,
)
def test_controller_gain(controller, x, omega_Q, omega_R):
    EXAMPLES["gain"] += 1
    K = _call(controller.gain, x, omega_Q, omega_R)
    if K is not None:
        assert K.shape == (6, 18)
        A, B = error_model(input_matrix(GEOMETRY, x), controller.h)
        assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 1.0


#: B_c = M_x^-1 tau at 40 reachable poses: the input matrices the controller really sees.
B_C_REAL = [
    input_matrix(GEOMETRY, x)
    for x in X_HOME + np.random.default_rng(1).uniform(-0.3, 0.3, (400, 6)) * scale
    if np.all(np.abs(kinematics.leg_reach_ratio(GEOMETRY, x)) < 0.95)
][:40]
matrices = st.one_of(
    st.sampled_from(B_C_REAL),
    st.sampled_from(B_C_REAL),
    st.tuples(st.sampled_from(B_C_REAL), st.floats(-1e3, 1e3)).map(lambda p: p[0] * p[1]),
    hnp.arrays(np.float64, (6, 6), elements=st.floats(-1e3, 1e3)),
    hnp.arrays(np.float64, (6, 6), elements=any_float),
    hnp.arrays(np.float64, hnp.array_shapes(max_dims=2, max_side=7), elements=st.floats(-1, 1)),
    near_home().map(lambda x: np.asarray(x)),
)


# 400 examples: about one in thirteen reaches a finite gain (the rest are refused: bad steps,
# negative R, unreachable inputs), and _settings asks for at least 20 of them.
@_settings(400, reaches=("error_model", "hautus_checks", "lqi_gain"))
@given(
    B_c=matrices,
    h=st.one_of(st.just(1e-3), st.floats(1e-4, 0.1), any_float),
    q=st.floats(1e-3, 1e3),
    r=st.one_of(st.floats(1e-3, 1e3), st.floats(1e-3, 1e3), st.floats(-1.0, 0.0)),
)
def test_error_model_hautus_and_lqi_gain(B_c, h, q, r):
    EXAMPLES["lqi_gain"] += 1
    out = _call(error_model, B_c, h)
    if out is None:
        return
    A, B = out
    assert A.shape == (18, 18) and B.shape == (18, 6)
    checks = _call(hautus_checks, A, B, np.eye(18))
    assert checks is not None and set(checks) >= {"stabilizable", "detectable"}
    K = _call(lqi_gain, A, B, q * np.eye(18), r * np.eye(6))
    if K is not None:
        assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 1.0


@_settings(150)
@given(
    A=hnp.arrays(np.float64, hnp.array_shapes(max_dims=3, max_side=4), elements=any_float),
    B=hnp.arrays(np.float64, hnp.array_shapes(max_dims=2, max_side=4), elements=any_float),
    C=hnp.arrays(np.float64, hnp.array_shapes(max_dims=2, max_side=4), elements=any_float),
)
def test_hautus_and_lqi_gain_on_arbitrary_matrices(A, B, C):
    EXAMPLES["hautus"] += 1
    checks = _call(hautus_checks, A, B, C)
    if checks is not None:  # the verdicts are the ranks' (eqs. 28-29), the ranks at most n
        assert checks["stabilizable"] == (checks["rank_AB"] == checks["n"] == A.shape[0])
        assert checks["detectable"] == (checks["rank_AC"] == checks["n"])
        assert 0 <= checks["rank_AB"] <= checks["n"] and 0 <= checks["rank_AC"] <= checks["n"]
    K = _call(lqi_gain, A, B, C, np.eye(B.shape[-1]) if B.ndim == 2 else B)
    if K is not None:  # a gain returned is (m, n) and stabilizes A - B K (scipy's eigenvalues)
        assert K.shape == (B.shape[1], A.shape[0])
        assert np.max(np.abs(scipy.linalg.eigvals(A - B @ K))) < 1.0


@_settings(150, reaches=("LqiScales",))
@given(
    pose=st.one_of(
        hnp.arrays(np.float64, 6, elements=st.floats(1e-6, 1.0)),
        hnp.arrays(np.float64, hnp.array_shapes(max_dims=1, max_side=7), elements=any_float),
    ),
    torque=st.one_of(st.floats(1e-3, 10.0), any_float, st.just("0.3")),
)
def test_lqi_scales(pose, torque):
    EXAMPLES["LqiScales"] += 1
    scales = _call(LqiScales, pose=tuple(pose), torque=torque)
    if scales is not None:
        _finite(scales.Q_unit())
        _finite(scales.R_unit())


# -- configuration, geometry, trajectories ------------------------------------------------------

periods = st.one_of(st.sampled_from([1e-3, 2e-3, 1e-2, 2e-2, 1.5e-3]), any_float)


@_settings(150)
@given(
    duration=st.one_of(st.floats(1e-3, 100.0), any_float),
    control=periods,
    schedule=periods,
    log=periods,
    omega_Q=omegas,
    omega_R=omegas,
    trajectory=st.sampled_from(["paper", "home", "nope", 3]),
    closure=st.one_of(st.just(1e-3), any_float),
)
def test_scenario(duration, control, schedule, log, omega_Q, omega_R, trajectory, closure):
    EXAMPLES["Scenario"] += 1
    try:
        config = Scenario(
            duration_s=duration,
            control_period_s=control,
            log_period_s=log,
            controller=LqiDriver(omega_Q=omega_Q, omega_R=omega_R, schedule_period_s=schedule),
            reference=NamedReference(trajectory),
            guard=GuardConfig(max_closure_error_m=closure),
        )
    except StewartError:
        return
    assert np.isfinite(config.duration_s) and config.duration_s > 0
    c = config.controller
    assert 1e-3 <= c.omega_Q <= 1e3 and 1e-3 <= c.omega_R <= 1e3
    ratio = c.schedule_period_s / config.control_period_s
    assert abs(ratio - round(ratio)) < 1e-6
    make_plan(config).reference.evaluate(0.0)


geometry_fields = {
    "base_radius": st.floats(0.05, 0.4),
    "platform_radius": st.floats(0.03, 0.3),
    "crank_length": st.floats(0.02, 0.3),
    "rod_length": st.floats(0.1, 0.8),
    "pivot_z": st.floats(-0.3, 0.1),
    "rod_mass": st.floats(-1.0, 1.0),
    "platform_inertia": st.tuples(st.floats(-1e-3, 1e-2), st.floats(0, 1e-2), st.floats(0, 1e-2)),
    "motor_angle_min_deg": st.floats(-200, 0),
    "platform_joint_cone_deg": st.floats(-10, 100),
    "pivot_angles_deg": hnp.arrays(np.float64, st.integers(5, 7), elements=st.floats(-360, 360)),
}


@_settings(250)
@given(
    changes=st.dictionaries(
        st.sampled_from(sorted(geometry_fields)), st.one_of(st.just(None), any_float), max_size=3
    ).flatmap(
        lambda keys: st.fixed_dictionaries(
            {k: (geometry_fields[k] if v is None else st.just(v)) for k, v in keys.items()}
        )
    )
)
def test_geometry_construction(changes):
    EXAMPLES["StewartGeometry"] += 1
    try:
        g = StewartGeometry(**changes)
    except StewartError:
        return
    # A geometry that constructs is usable at home: finite IK, Jacobian and torques there.
    _finite(kinematics.ik(g, X_HOME))
    _finite(statics.holding_torques(g, X_HOME))


@_settings(200, reaches=("SineTrajectory",))
@given(
    amplitude=hnp.arrays(np.float64, st.sampled_from([6, 6, 6, 5]), elements=any_float),
    frequency=hnp.arrays(np.float64, 6, elements=st.one_of(st.floats(0, 10), any_float)),
    t=hnp.arrays(np.float64, st.integers(1, 5), elements=st.floats(0, 1e3)),
)
def test_sine_trajectory(amplitude, frequency, t):
    EXAMPLES["SineTrajectory"] += 1
    trajectory = _call(SineTrajectory, amplitude=tuple(amplitude), frequency_hz=tuple(frequency))
    if trajectory is not None:
        x, v, a = _finite(trajectory.evaluate(t))
        assert x.shape == v.shape == a.shape == (t.size, 6)


# -- features and the tuner -----------------------------------------------------------------------


@_settings(150, reaches=("density_features",))
@given(
    e=hnp.arrays(
        np.float64,
        st.tuples(st.integers(1, 8), st.sampled_from([6, 6, 5])),
        elements=st.one_of(st.floats(-1e300, 1e300), any_float),
    ),
    eps=st.one_of(st.just(1e-9), any_float),
)
def test_density_features(e, eps):
    EXAMPLES["density_features"] += 1
    rho = _call(density_features, e, np.flip(e, axis=0), eps)
    if rho is not None:
        assert rho.shape == (12,) and np.all(rho >= 0) and np.all(rho <= e.shape[0] + 1e-9)


@pytest.fixture(scope="module")
def shipped_tuner():
    return load_tuner(TunerModel)


@_settings(150, reaches=("TunerModel.predict",))
@given(
    rho=st.one_of(
        hnp.arrays(np.float64, 12, elements=st.floats(0, 50)),
        hnp.arrays(np.float64, st.sampled_from([(12,), (3, 12), (11,)]), elements=any_float),
    ),
    weight_scale=st.one_of(st.just(1.0), st.floats(1e100, 1e300)),
)
def test_tuner_inference(shipped_tuner, rho, weight_scale):
    EXAMPLES["AnnTuner"] += 1
    model = shipped_tuner
    if weight_scale != 1.0:
        model = TunerModel(
            model.W1 * weight_scale,
            model.b1,
            model.W2 * weight_scale,
            model.b2,
            model.x_mean,
            model.x_std,
            model.activation,
        )
    omega = _call(model.predict, rho)
    if omega is not None:
        assert omega.shape == np.shape(rho)[:-1] + (2,)
        assert np.all((0.1 <= omega) & (omega <= 10.0))


def test_reachable_examples_are_not_all_refused():
    """The strategies reach the non-error branch: most near-home poses are reachable."""
    rng = np.random.default_rng(0)
    x = X_HOME + rng.uniform(-1, 1, (1000, 6)) * scale
    reachable = np.all(np.abs(kinematics.leg_reach_ratio(GEOMETRY, x)) <= 1, axis=1)
    assert 0.3 < reachable.mean() < 0.99
    with pytest.raises(UnreachablePoseError):
        kinematics.ik(GEOMETRY, x)
