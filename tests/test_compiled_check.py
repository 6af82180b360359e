"""The reference check compiled (robot/path_kernels.py) against its numpy form, on real
references: the paper manoeuvre, a breathing motion, references the check refuses (the same
error, time, leg or motor), a path that leaves the workspace, and a pose whose forward
difference cannot be taken; and the compiled kernels against their own Python source.

Every field of the report is the numpy form's to the last bit but the motors' torques. The
torques take the velocity-product forces by forward differences of the task inertia (step
1e-7), which divide the rounding of M_x by the step: the two forms sum M_x in different orders
(numpy's through BLAS), and their torques differ by up to 5e-10 of the peak torque (a heave at
0.6 m/s near the top of the workspace; 2e-10 on the paper manoeuvre, 4e-12 on breathing), while
each is 2e-8 of the peak from the same forward difference evaluated in 80-bit arithmetic there.
The torques are held to 1e-8 of the peak; the peaks of the paper manoeuvre and breathing agree
to 1e-13.
"""

import dataclasses
import functools

import numpy as np
import pytest

from stewart_drake.base.errors import (
    JointLimitError,
    MotorLimitError,
    SingularPoseError,
    StewartError,
    UnreachablePoseError,
)
from stewart_drake.references.organ.library import OrganMotionReference
from stewart_drake.references.trajectories import SineTrajectory, StepTrajectory
from stewart_drake.robot import kinematics, limits, path_kernels
from stewart_drake.robot.geometry import X_HOME
from stewart_drake.robot.statics import kernel_constants
from stewart_drake.run import plan as run_plan
from stewart_drake.run.scenario_io import load_scenario

#: Torques agree to this share of the peak torque (module docstring).
TORQUE_RTOL = 1e-8
#: The report's fields computed from the torques.
TORQUE_FIELDS = {"peak_torque", "peak_torque_motor", "peak_torque_t", "first_effort_violation"}


def _plan(overrides=(), reference=None):
    """(the plan of paper_hardware with ``overrides``, the reference object to check: None for
    the plan's own, which is ``reference`` when it is a scenario's reference)."""
    scenario = load_scenario("paper_hardware", list(overrides))
    if isinstance(reference, OrganMotionReference):
        scenario.reference, reference = reference, None
        scenario.validate()
    return run_plan.make_plan(scenario), reference


def _both(monkeypatch, check, *args, **kwargs):
    """``check(*args, **kwargs)`` with the compiled check, then with the numpy form: each
    outcome a report or the error raised."""
    outcomes = []
    for compiled in (True, False):
        validator = functools.partial(limits.validate_trajectory, compiled=compiled)
        monkeypatch.setattr(run_plan, "validate_trajectory", validator)
        try:
            outcomes.append(check(*args, **kwargs))
        except StewartError as error:
            outcomes.append(error)
    return outcomes


def _same_error(compiled: StewartError, numpy_form: StewartError):
    """The same type and arguments (time, leg or motor, measure, pose); the torque a motor
    would need to :data:`TORQUE_RTOL`."""
    assert type(compiled) is type(numpy_form), (compiled, numpy_form)
    args_a, args_b = list(compiled._init_args()), list(numpy_form._init_args())
    if isinstance(compiled, MotorLimitError) and compiled.quantity == "torque":
        np.testing.assert_allclose(compiled.required, numpy_form.required, rtol=TORQUE_RTOL)
        args_a.remove(compiled.required)
        args_b.remove(numpy_form.required)
    for a, b in zip(args_a, args_b, strict=True):
        np.testing.assert_array_equal(a, b)


def _same_report(compiled, numpy_form):
    """Every field equal (NaN to NaN), the torques' to :data:`TORQUE_RTOL` of their peak; the
    series sample by sample, to the last bit but the torque."""
    for f in dataclasses.fields(compiled):
        a, b = getattr(compiled, f.name), getattr(numpy_form, f.name)
        if f.name in TORQUE_FIELDS or f.name == "series":
            continue
        if f.name == "clearance_profile":  # (t, clearance, resolution): the same measures
            assert len(a) == len(b) and all(np.array_equal(u, v) for u, v in zip(a, b))
            continue
        assert a == b or (a != a and b != b), (f.name, a, b)  # NaN equals NaN here
    series_a, series_b = compiled.series, numpy_form.series
    assert series_a.keys() == series_b.keys()
    for key in series_a:
        if key == "margins":
            for name in limits.LIMITS:
                np.testing.assert_array_equal(series_a[key][name], series_b[key][name])
        elif key != "torque":
            np.testing.assert_array_equal(series_a[key], series_b[key], err_msg=key)
    if "torque" not in series_b:
        return
    peak = numpy_form.peak_torque
    np.testing.assert_allclose(compiled.peak_torque, peak, rtol=TORQUE_RTOL)
    np.testing.assert_allclose(series_a["torque"], series_b["torque"], atol=TORQUE_RTOL * peak)
    # The same sample and motor, or another within the tolerance of the peak (a tie).
    k = int(np.searchsorted(series_b["t"], compiled.peak_torque_t))
    assert abs(series_b["torque"][k, compiled.peak_torque_motor]) >= peak * (1 - TORQUE_RTOL)
    first_a, first_b = compiled.first_effort_violation, numpy_form.first_effort_violation
    assert (first_a is None) == (first_b is None)
    if first_b is not None:
        _same_error(first_a, first_b)


@pytest.mark.parametrize(
    "name, overrides, reference",
    [
        ("paper manoeuvre", ["duration_s=10"], None),
        ("breathing", ["duration_s=30"], OrganMotionReference(motion="breathing_heartbeat")),
        # Refused: a platform socket's cone at 0.27 s, and the motors' torque.
        (
            "roll past a joint limit",
            ["duration_s=4"],
            SineTrajectory((0.9,) + (0.0,) * 5, (0.5,) * 6),
        ),
        ("torque over the limit", ["duration_s=4", "torque_limit_Nm=0.3"], None),
        ("near a singularity", ["duration_s=4", "guard.cond_threshold=50"], None),
    ],
)
def test_the_compiled_check_reports_what_the_numpy_check_reports(
    monkeypatch, name, overrides, reference
):
    """check_reference of the plan's reference, refusals reported and not raised: every field
    and every sample of the series the same (the clearance's included)."""
    plan, trajectory = _plan(overrides, reference)
    check = run_plan.check_reference
    compiled, numpy_form = _both(monkeypatch, check, plan, trajectory, raise_refused=False)
    assert not isinstance(numpy_form, Exception), numpy_form
    _same_report(compiled, numpy_form)
    assert numpy_form.ok == (name in ("paper manoeuvre", "breathing")), numpy_form.summary()
    assert np.isfinite(numpy_form.peak_torque) and np.isfinite(numpy_form.min_clearance)


@pytest.mark.parametrize(
    "overrides, reference, error",
    [
        (["duration_s=4"], SineTrajectory((0.9,) + (0.0,) * 5, (0.5,) * 6), JointLimitError),
        (["duration_s=4", "torque_limit_Nm=0.3"], None, MotorLimitError),
        (["duration_s=4", "guard.cond_threshold=50"], None, SingularPoseError),
        # Up 0.2 m at 0.6 m/s: the motors' torque near the top of the workspace refuses it first.
        (["duration_s=4"], SineTrajectory((0.0,) * 5 + (0.2,), (0.5,) * 6), MotorLimitError),
        # Slowly up 0.2 m: the cranks reach their dead points (1/sigma_max(J) too small) first.
        (["duration_s=10"], SineTrajectory((0.0,) * 5 + (0.2,), (0.05,) * 6), SingularPoseError),
        # A step out of the workspace: no sample on the way.
        (["duration_s=1"], StepTrajectory(5, 0.3, 0.5), UnreachablePoseError),
    ],
)
def test_a_refused_reference_is_refused_with_the_same_error(
    monkeypatch, overrides, reference, error
):
    """The run's check (refusals raised): the same error type, time, leg or motor, measure and
    pose, the need of a motor over its limit to TORQUE_RTOL."""
    plan, trajectory = _plan(overrides, reference)
    compiled, numpy_form = _both(monkeypatch, run_plan.check_reference, plan, trajectory)
    assert isinstance(numpy_form, error), numpy_form
    _same_error(compiled, numpy_form)


def test_a_path_out_of_the_workspace_gives_the_same_report_and_nan(monkeypatch, geometry):
    """Reported and not raised (raise_unreachable=False): the poses whose legs cannot close have
    the same NaN margins, measures and effort series in both forms; with raise_unreachable, the
    same UnreachablePoseError (time, leg, ratio)."""
    plan, _ = _plan(["duration_s=10"])
    reference = SineTrajectory((0.0,) * 5 + (0.25,), (0.05,) * 6)
    t = np.arange(0.0, 10.0, 2e-3)
    x, x_dot, x_ddot = reference.evaluate(t)
    closed = np.all(np.abs(kinematics.leg_reach_ratio(plan.plant_geometry, x)) <= 1.0, axis=1)
    assert 0 < closed.sum() < t.size  # out of the workspace and back in
    check = functools.partial(
        limits.validate_trajectory,
        plan.plant_geometry,
        t,
        x,
        x_dot=x_dot,
        x_ddot=x_ddot,
        motor_limits=plan.motor_limits,
    )
    reports = [check(raise_unreachable=False, compiled=c) for c in (True, False)]
    _same_report(*reports)
    assert np.isnan(reports[0].series["margins"]["crank_joint"]).any()
    assert np.isnan(reports[0].series["torque"][~closed]).all()
    errors = []
    for compiled in (True, False):
        with pytest.raises(UnreachablePoseError) as info:
            check(compiled=compiled)
        errors.append(info.value)
    _same_error(*errors)


def test_a_pose_whose_forward_difference_step_is_unreachable_raises_the_same_error(geometry):
    """A heave to within 1e-7 m of the top of the workspace: the compiled inverse dynamics
    cannot take the step up and leaves the pose to the numpy form, which raises its error."""
    lo, hi = X_HOME[5], X_HOME[5] + 0.5  # reachable, unreachable

    def reaches(z):
        pose = np.array([0.0, 0.0, 0.0, 0.0, 0.0, z])
        return np.all(np.abs(kinematics.leg_reach_ratio(geometry, pose)) <= 1.0)

    while hi - lo > 5e-8:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if reaches(mid) else (lo, mid)
    assert reaches(lo) and not reaches(lo + 1e-7)
    x = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, lo]])
    motors = limits.MotorLimits(peak_torque_Nm=1.0, max_speed_rad_s=10.0)
    errors = []
    for compiled in (True, False):
        with pytest.raises(UnreachablePoseError) as info:
            limits.validate_trajectory(
                geometry,
                [0.0],
                x,
                x_dot=np.zeros((1, 6)),
                x_ddot=np.zeros((1, 6)),
                motor_limits=motors,
                compiled=compiled,
            )
        errors.append(info.value)
    _same_error(*errors)
    step = errors[0].pose - x[0]  # the pose a step away is named
    assert errors[0].t is None and np.count_nonzero(step) == 1 and step.max() == pytest.approx(1e-7)


def test_the_compiled_kernels_compute_what_their_python_source_computes(geometry, random_poses):
    """Each kernel against its numba py_func (path_kernels.reference): numba's arithmetic is
    Python's, but for CPython's own hypot (last bits) and the forward differences (which divide
    those by their step)."""
    x = np.ascontiguousarray(np.vstack([random_poses[:6], X_HOME + [0, 0, 0, 0, 0, 0.5]]))
    legs, body = kernel_constants(geometry)
    out = {}
    for name, kernels in (("compiled", path_kernels), ("python", path_kernels.reference)):
        ratio, M, N = np.empty(x.shape), np.empty(x.shape), np.empty(x.shape)
        kernels.closure(x, legs, body, ratio, M, N)
        with np.errstate(invalid="ignore"):
            theta = np.where(np.abs(ratio) <= 1, np.arcsin(np.clip(ratio, -1, 1)), np.nan)
        theta = theta - np.arctan2(N, M)
        J, crank, cos_p = np.empty(x.shape + (6,)), np.empty(x.shape), np.empty(x.shape)
        axes = limits._joint_axes(geometry)
        kernels.pose_terms(x, theta, legs, body, axes, J, crank, cos_p)
        T, status = np.empty((6, 6)), np.empty(6, dtype=np.int64)
        rates = np.full((6, 6), 0.1), np.full((6, 6), 0.5)
        bad = kernels.effort(x[:6], *rates, np.ascontiguousarray(theta[:6]), legs, body, T, status)
        out[name] = (ratio, M, N, J, crank, cos_p, T, bad)
    for k, (a, b) in enumerate(zip(out["compiled"], out["python"], strict=True)):
        rtol = TORQUE_RTOL if k == 6 else 1e-14
        np.testing.assert_allclose(a, b, rtol=rtol, atol=0, equal_nan=True)
    assert out["compiled"][-1] == 0 and np.isnan(out["compiled"][3][-1]).any()  # last: too high
