"""Singularity measure, limits, trajectory validation, workspace sweeps and holding torques."""

import csv

import numpy as np
import pytest
from conftest import random_reachable_poses
from pydrake.multibody.tree import JacobianWrtVariable
from test_plant import _hold

from stewart_drake.analysis import workspace
from stewart_drake.base import errors
from stewart_drake.base.errors import InvalidConfigError, InvalidGeometryError, UnreachablePoseError
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import make_plant
from stewart_drake.references import trajectories
from stewart_drake.robot import kinematics, limits, statics
from stewart_drake.robot.geometry import X_HOME


def _paper(n=4001, duration=10.0, scale=1.0):
    t = np.linspace(0, duration, n)
    x = np.tile(X_HOME, (n, 1))
    x[:, 0] = scale * np.pi / 6 * np.sin(2 * t)
    x[:, 5] = scale * 0.05 * np.sin(2 * t) + 0.30
    return t, x


# --- singularity measure ---------------------------------------------------------------------


def test_singularity_measures_equal_numpy_svd(geometry, random_poses):
    cond, inv = kinematics.singularity_measures(geometry, random_poses)
    J = kinematics.jacobian(geometry, random_poses)
    np.testing.assert_allclose(cond, np.linalg.cond(J), rtol=1e-9)
    np.testing.assert_allclose(inv, 1 / np.linalg.norm(J, 2, axis=(-2, -1)), rtol=1e-12)
    assert kinematics.singularity_measures(geometry, X_HOME)[0] == pytest.approx(43.71, abs=0.01)


def _closure_edge(geometry, direction):
    """Largest s with X_HOME + s * direction closable (bisection to 1e-15)."""
    lo, hi = 0.0, 0.5
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        ok = np.all(np.abs(kinematics.leg_reach_ratio(geometry, X_HOME + mid * direction)) <= 1)
        lo, hi = (mid, hi) if ok else (lo, mid)
    return lo


@pytest.mark.parametrize(
    "direction, cond_blows_up",
    [
        ([0, 0, 0, 0, 1, 0], True),  # sideways: one leg stretches out first
        ([0, 0, 0, 0.3, 0.5, 0.4], True),
        ([0, 0, 0, 0, 0, -1], False),  # pure heave: all six rows of J grow together
    ],
)
def test_singularity_measures_at_the_edge_of_the_workspace(geometry, direction, cond_blows_up):
    """Towards a leg's dead point sigma_min(J^-1) -> 0; cond(J) -> inf unless all legs at once."""
    direction = np.array(direction, dtype=float)
    edge = _closure_edge(geometry, direction)
    x = X_HOME + np.array([0.0, edge - 1e-3, edge - 1e-6, edge - 1e-9])[:, None] * direction
    cond, inv = kinematics.singularity_measures(geometry, x)
    assert np.all(np.diff(inv) < 0) and inv[-1] < 1e-3 * inv[0]
    if cond_blows_up:
        assert np.all(np.diff(cond) > 0) and cond[-1] > 1e4
    else:
        assert cond[-1] < cond[0]
    beyond = X_HOME + (edge + 1e-3) * direction
    unreachable = kinematics.singularity_measures_unchecked(geometry, beyond)
    assert np.isnan(unreachable[0]) and np.isnan(unreachable[1])
    with pytest.raises(UnreachablePoseError, match=r"\|L\|/sqrt\(M\^2\+N\^2\) = 1\.0"):
        kinematics.singularity_measures(geometry, beyond)  # typed, not NaN


# --- limits ----------------------------------------------------------------------------------


def test_home_margins_are_the_documented_angles(geometry):
    report = limits.is_reachable(geometry, X_HOME)
    assert report and report.violations() == []
    m = {k: np.rad2deg(v) for k, v in report.margins.items()}
    theta_home = np.rad2deg(kinematics.ik(geometry, X_HOME))
    np.testing.assert_allclose(m["motor_angle"], 90 - np.abs(theta_home), atol=1e-12)
    np.testing.assert_allclose(m["crank_joint"], 35 - 19.351, atol=1e-3)  # rod end at 19.35 deg
    np.testing.assert_allclose(m["platform_joint"], 40, atol=1e-6)  # socket along home rod


@pytest.mark.parametrize(
    "change, x, limit",
    [
        ({}, [0, 0, 0, 0, 0, 0.60], "closure"),
        (
            {"motor_angle_min_deg": -10, "motor_angle_max_deg": 10},
            [0, 0, 0, 0, 0, 0.36],
            "motor_angle",
        ),
        ({"crank_joint_cone_deg": 20}, [0, 0, 0, 0.05, 0, 0.30], "crank_joint"),
        ({}, [0.7, 0, 0, 0, 0, 0.30], "platform_joint"),
    ],
)
def test_is_reachable_names_leg_limit_and_margin(geometry, change, x, limit):
    g = geometry.replace(**change)
    report = limits.is_reachable(g, x)
    assert not report
    worst = report.violations()[0]
    assert worst.limit == limit and worst.margin < 0
    assert worst.margin == pytest.approx(report.margins[limit][worst.leg])
    assert worst.margin == pytest.approx(report.margins[limit].min())
    assert f"leg {worst.leg} exceeds its {limit} limit" in str(worst)
    if limit == "motor_angle":  # independent: the IK angle itself
        theta = np.rad2deg(kinematics.ik(g, x))
        assert np.rad2deg(worst.margin) == pytest.approx(10 - np.abs(theta).max())


def test_is_reachable_is_vectorized(geometry, random_poses):
    report = limits.is_reachable(geometry, random_poses.reshape(10, 20, 6))
    assert report.reachable.shape == (10, 20)
    for name in limits.LIMITS:
        assert report.margins[name].shape == (10, 20, 6)
        single = limits.limit_margins(geometry, random_poses[57])[name]
        np.testing.assert_allclose(report.margins[name][2, 17], single, rtol=1e-12)


def test_limit_margins_refuse_unreachable_and_nan_poses(geometry):
    """Typed errors at the public entry point, NaN only in the sweeps' variant."""
    far = [0, 0, 0, 0, 0, 0.60]
    with pytest.raises(
        UnreachablePoseError,
        match=r"leg \d cannot reach the pose \(pose .*0\.6\]\)"
        r": \|L\|/sqrt\(M\^2\+N\^2\) = 2\.155 > 1",
    ):
        limits.limit_margins(geometry, np.array([X_HOME, far]))
    assert np.all(limits.limit_margins_unchecked(geometry, far)["closure"] < 0)
    for bad in ([0, 0, np.nan, 0, 0, 0.3], [0, 0, 0, 0, 0, 0.3, 0]):
        for function in (limits.limit_margins, kinematics.singularity_measures):
            with pytest.raises(InvalidConfigError, match="pose x"):
                function(geometry, bad)
    with pytest.raises(InvalidConfigError, match="motor angles theta has a non-finite value"):
        limits.limit_margins(geometry, X_HOME, theta=np.full(6, np.nan), ratio=np.zeros(6))
    margins = limits.limit_margins(geometry, X_HOME)
    assert all(np.all(np.isfinite(v) & (v >= 0)) for v in margins.values())


def test_the_reach_ratio_is_printed_as_its_absolute_value(geometry):
    """A platform too low for its rods gives L < 0: the message prints |L| / sqrt(M^2 + N^2)."""
    x = np.array([0, 0, 0, 0, 0, 0.10])
    ratio = kinematics.leg_reach_ratio(geometry, x)
    assert np.all(ratio < -1)
    err = errors.UnreachablePoseError(0, -1.006, t=0.5)
    assert err.ratio == 1.006 and "|L|/sqrt(M^2+N^2) = 1.006 > 1" in str(err)
    with pytest.raises(UnreachablePoseError) as info:
        kinematics.ik(geometry, x)
    assert info.value.ratio == pytest.approx(np.abs(ratio).max()) and "= -" not in str(info.value)


@pytest.mark.parametrize(
    "make, message",
    [
        (
            lambda: trajectories.StepTrajectory(offset=(0, 0, 0, 0, 0, np.nan)),
            r"step: offset has a non-finite value nan at index \(5,\)",
        ),
        (
            lambda: trajectories.ChirpTrajectory(offset=(0, 0, 0, np.inf, 0, 0.3)),
            r"sweep: offset has a non-finite value inf",
        ),
        (
            lambda: trajectories.SineTrajectory(offset=(np.nan,) * 6),
            r"sine: offset has a non-finite",
        ),
        (lambda: trajectories.StepTrajectory(offset=(0, 0, 0.3)), r"offset must have shape"),
        (lambda: trajectories.StepTrajectory(size=np.nan), r"step: size must be a finite number"),
        (
            lambda: trajectories.ChirpTrajectory(amplitude="big"),
            r"sweep: amplitude must be a number",
        ),
    ],
)
def test_trajectories_refuse_a_nan_offset_by_name(make, message):
    with pytest.raises(InvalidConfigError, match=message):
        make()


@pytest.mark.parametrize(
    "change",
    [
        {"motor_angle_min_deg": 10, "motor_angle_max_deg": -10},
        {"motor_angle_max_deg": 200},
        {"crank_joint_cone_deg": 0},
        {"platform_joint_cone_deg": float("nan")},
        {"crank_joint_cone_deg": 15},  # home itself needs 19.35 deg
    ],
)
def test_invalid_limits_are_refused(geometry, change):
    with pytest.raises(InvalidGeometryError):
        geometry.replace(**change)


# --- trajectory validation -------------------------------------------------------------------


def test_paper_manoeuvre_validates_with_its_margins(geometry):
    t, x = _paper()
    report = limits.validate_trajectory(geometry, t, x)
    assert report.ok and report.first_violation is None and report.first_singular_t is None
    assert report.min_margin["closure"] == pytest.approx(1 - 0.91, abs=0.01)  # reference_geometry
    assert np.rad2deg(report.min_margin["motor_angle"]) == pytest.approx(90 - 74.94, abs=0.05)
    assert np.rad2deg(report.min_margin["crank_joint"]) == pytest.approx(35 - 21.10, abs=0.05)
    assert np.rad2deg(report.min_margin["platform_joint"]) == pytest.approx(40 - 32.19, abs=0.05)
    assert 77 < report.max_cond < 78
    assert "OK" in report.summary()


def test_first_time_closer_to_singularity_than_threshold(geometry):
    t, x = _paper()
    report = limits.validate_trajectory(geometry, t, x, cond_threshold=60.0)
    cond = np.linalg.cond(kinematics.jacobian(geometry, x))
    assert not report.ok
    assert report.first_singular_t == t[np.argmax(cond > 60.0)]
    assert report.max_cond_t == pytest.approx(t[np.argmax(cond)])


def test_unreachable_trajectory_raises_with_time_and_leg(geometry):
    t, x = _paper(scale=2.5)
    with pytest.raises(UnreachablePoseError) as err:
        limits.validate_trajectory(geometry, t, x)
    ratio = kinematics.leg_reach_ratio(geometry, x)
    k = int(np.argmax(np.any(np.abs(ratio) > 1, axis=1)))
    assert err.value.t == t[k] and abs(ratio[k, err.value.leg]) > 1
    report = limits.validate_trajectory(geometry, t, x, raise_unreachable=False)
    assert not report.ok and report.first_violation.t <= t[k]


@pytest.mark.parametrize("name", sorted(trajectories.TRAJECTORIES))
def test_every_named_trajectory_validates(geometry, name):
    """The trajectories the runner uses (paper manoeuvre, data collection) pass before a run."""
    t = np.arange(0, 20.0, 2e-3)
    x = trajectories.make_trajectory(name).evaluate(t)[0]
    report = limits.validate_trajectory(geometry, t, x)
    assert report.ok, report.summary()


# --- workspace -------------------------------------------------------------------------------


def test_classify_matches_pointwise_functions(geometry, random_poses):
    x = np.concatenate([random_poses[:50], [[0, 0, 0, 0, 0, 0.6], [0.7, 0, 0, 0, 0, 0.3]]])
    c = workspace.classify(geometry, x)
    assert c["reachable"][:50].all() and not c["reachable"][50:].any()
    np.testing.assert_allclose(
        c["torques"][:50], statics.holding_torques(geometry, x[:50]), rtol=1e-12
    )
    assert np.isnan(c["torques"][50:]).all() and (c["bottleneck"][50:] == -1).all()
    np.testing.assert_array_equal(c["bottleneck"][:50], np.argmax(np.abs(c["torques"][:50]), 1))


def test_parallel_sweep_equals_serial(geometry):
    x = workspace.translation_grid(workspace.grid_axes(workspace.TRANSLATION_BOX, 15))
    serial = workspace.sweep(geometry, x, jobs=1)
    parallel = workspace.sweep(geometry, x, jobs=2, chunk=1000)
    for key in workspace.FIELDS:
        np.testing.assert_array_equal(serial[key], parallel[key])
    assert serial["reachable"].shape == (15, 15, 15)


def test_boxes_contain_the_whole_workspace(geometry):
    for box, grid in (
        (workspace.TRANSLATION_BOX, workspace.translation_grid),
        (workspace.ORIENTATION_BOX, workspace.orientation_grid),
    ):
        reach = workspace.classify(geometry, grid(workspace.grid_axes(box, 25)))["reachable"]
        assert reach.any()
        for d in range(3):
            assert not reach.take(0, axis=d).any() and not reach.take(-1, axis=d).any()


def test_reachable_volume_agrees_with_monte_carlo(geometry):
    # 25 per axis: 7.639e-3 m^3, as at 41 (the volume is a sum of cells; 31 gives 7.619e-3)
    axes = workspace.grid_axes(workspace.TRANSLATION_BOX, 25)
    grid = workspace.classify(geometry, workspace.translation_grid(axes))["reachable"]
    volume = workspace.reachable_volume(axes, grid)
    rng = np.random.default_rng(0)
    box = np.array(workspace.TRANSLATION_BOX)
    p = box[:, 0] + rng.uniform(size=(200_000, 3)) * (box[:, 1] - box[:, 0])
    x = np.concatenate([np.zeros_like(p), p], axis=1)
    mc = limits.is_reachable(geometry, x).reachable.mean() * np.prod(box[:, 1] - box[:, 0])
    assert volume == pytest.approx(mc, rel=0.03)  # both ~7.6e-3 m^3
    ext = workspace.extents(axes, grid)
    assert ext[2, 0] < X_HOME[5] < ext[2, 1] and ext[1, 0] == pytest.approx(-ext[1, 1])


def test_max_tilt_is_reachable_in_every_direction_and_not_beyond(geometry):
    heights, tilts = np.array([0.26, 0.30, 0.36]), np.deg2rad(np.arange(0, 61, 1.0))
    grid = workspace.tilt_grid(heights, tilts, n_azimuth=36)
    reachable = workspace.classify(geometry, grid)["reachable"]
    every, some = workspace.max_tilt_vs_height(tilts, reachable)
    assert np.all(some >= every) and np.rad2deg(every[1]) == pytest.approx(37.5, abs=1.5)
    for h, alpha in enumerate(every):
        k = int(round(np.rad2deg(alpha)))
        assert limits.is_reachable(geometry, grid[h, : k + 1]).reachable.all()
        assert not limits.is_reachable(geometry, grid[h, k + 1]).reachable.all()
    # a tilt about the X axis is a pure roll
    np.testing.assert_allclose(grid[0, 10, 0], [tilts[10], 0, 0, 0, 0, 0.26], atol=1e-15)


def test_dynamic_torque_summary(geometry):
    t, x = _paper(n=501)
    T = statics.holding_torques(geometry, x)
    T[:, 4] += 0.5 * np.sin(3 * t)
    s = workspace.summarize_dynamic_torques(geometry, t, x, T)
    assert s["bottleneck"] == 4
    assert s["peak"][4] == pytest.approx(np.abs(T[:, 4]).max())
    assert s["peak_t"][4] == t[np.argmax(np.abs(T[:, 4]))]
    np.testing.assert_allclose(s["dynamic_over_static"][[0, 1, 2, 3, 5]], 1.0, rtol=1e-12)


def test_workspace_writes_outputs_atomically(tmp_path):
    rows = workspace.write_workspace(tmp_path / "ws", resolution=9, jobs=1, progress=False)
    assert rows[0][0] == "reachable_volume"
    names = sorted(p.name for p in (tmp_path / "ws").iterdir())
    assert names == [
        "bottleneck_and_orientation.png",
        "summary.csv",
        "tilt_vs_height.csv",
        "workspace.npz",
        "workspace.png",
    ]  # no temporary files left
    data = np.load(tmp_path / "ws" / "workspace.npz")
    assert data["translation_reachable"].shape == (9, 9, 9)
    rows = {
        r["figure"]: float(r["value"])
        for r in csv.DictReader(open(tmp_path / "ws" / "summary.csv"))
    }
    assert 0.004 < rows["reachable_volume"] < 0.012
    assert rows["max_holding_torque"] == pytest.approx(
        np.nanmax(data["translation_max_torque"]), rel=1e-5
    )


# --- holding torques against the Drake plant -------------------------------------------------


def _drake_static_torques(plant, context, handles, x):
    """Motor torques u with gravity + B u + G^T lambda = 0, G the 6 ball constraints' Jacobian."""
    assemble(plant, context, handles, x)
    W = plant.world_frame()
    G = np.vstack(
        [
            plant.CalcJacobianTranslationalVelocity(
                context,
                JacobianWrtVariable.kV,
                handles.rods[i].body_frame(),
                handles.rod_top_in_rod[i],
                W,
                W,
            )
            - plant.CalcJacobianTranslationalVelocity(
                context,
                JacobianWrtVariable.kV,
                handles.platform.body_frame(),
                handles.geometry.p_E[i],
                W,
                W,
            )
            for i in range(6)
        ]
    )
    A = np.hstack([plant.MakeActuationMatrix(), G.T])
    tau_g = plant.CalcGravityGeneralizedForces(context)
    sol = np.linalg.lstsq(A, -tau_g, rcond=None)[0]
    assert np.abs(A @ sol + tau_g).max() < 1e-9  # the plant is in equilibrium
    return sol[:6]


def test_holding_torques_equal_drake_statics_at_12_poses(geometry):
    plant, context, handles, _, _ = make_plant()
    for x in random_reachable_poses(geometry, 12, seed=11):
        T = statics.holding_torques(geometry, x)
        u = _drake_static_torques(plant, context, handles, x)
        assert np.abs(u - T).max() < 0.01 * np.abs(T).max()  # measured: ~6e-12 relative


def test_plant_stays_still_with_holding_torques_and_not_with_one_percent_less(geometry):
    """At 10 random poses, the map is within 1 %: exact torques drift 100x less than 0.99 T."""
    for x in random_reachable_poses(geometry, 10, seed=13):
        T = workspace.classify(geometry, x)["torques"]
        drift = np.abs(_hold(geometry, x, T, duration=0.3)[0] - x).max()
        drift_low = np.abs(_hold(geometry, x, 0.99 * T, duration=0.3)[0] - x).max()
        assert drift < 1e-6 and drift < 0.01 * drift_low


# --- the motors as a limit of the workspace --------------------------------------------------


@pytest.fixture(scope="module")
def hardware_plan():
    from pathlib import Path

    from stewart_drake.run.plan import make_plan
    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario(Path(__file__).parents[1] / "scenarios" / "paper_hardware.yaml")
    plan = make_plan(scenario, with_reference=False)
    assert plan.motor_limits.peak_torque_Nm == pytest.approx(0.702, abs=1e-3)
    return plan


def test_no_pose_counted_usable_needs_more_than_the_motors(hardware_plan):
    """Drake's statics (constraint forces solved on the plant) at the 8 poses counted within the
    motors with the largest holding torques: each within the peak (and the share a reference
    may use where counted admissible); and the torque limit removes poses the old count kept."""
    geometry, motors = hardware_plan.geometry, hardware_plan.motor_limits
    c = workspace.sweep(
        geometry,
        workspace.translation_grid(workspace.grid_axes(workspace.TRANSLATION_BOX, 9)),
        motor_limits=motors,
    )
    assert np.sum(c["usable"] & ~c["within_peak"]) > 0
    assert np.all(c["admissible"] <= c["within_peak"]) and np.all(c["within_peak"] <= c["usable"])
    plant, context, handles, _, _ = make_plant(geometry)
    for key, limit in (
        ("within_peak", motors.peak_torque_Nm),
        ("admissible", motors.margin * motors.peak_torque_Nm),
    ):
        x = workspace.translation_grid(workspace.grid_axes(workspace.TRANSLATION_BOX, 9))[c[key]]
        worst = x[np.argsort(c["max_torque"][c[key]])[-8:]]
        for pose in worst:
            u = _drake_static_torques(plant, context, handles, pose)
            assert np.abs(u).max() <= limit * (1 + 1e-9)


def test_admissible_agrees_with_the_checks_torque_verdict_either_side_of_the_limit(
    hardware_plan,
):
    """Poses along X at home height cross the reference's torque share; classify's verdict
    equals the one the reference check gives a pose held still (motor_effort at rest against
    margin * peak), on both sides of the limit."""
    geometry, motors = hardware_plan.geometry, hardware_plan.motor_limits
    x = np.tile(X_HOME, (41, 1))
    x[:, 3] = np.linspace(-0.08, 0.16, 41)
    c = workspace.classify(geometry, x, motor_limits=motors)
    T, _ = statics.motor_effort(geometry, x, np.zeros_like(x), np.zeros_like(x), motors.servo)
    within = np.abs(T).max(axis=1) <= motors.margin * motors.peak_torque_Nm
    assert np.all(c["usable"])
    assert within.any() and (~within).any()  # both sides of the limit
    np.testing.assert_array_equal(c["admissible"], within)


def test_the_torque_limit_shrinks_the_usable_volume_at_resolution_21(hardware_plan):
    """Before: 0.0073875 m^3 usable ignoring the motors; after: 0.005175 m^3 within the peak
    (30 % fewer) and 0.00425 m^3 within the reference's share (42 % fewer)."""
    s = workspace.workspace_summary(
        hardware_plan.geometry, 21, jobs=1, motor_limits=hardware_plan.motor_limits
    )
    assert s["usable_volume_m3"] == pytest.approx(0.0073875, rel=1e-6)
    assert s["usable_within_peak_volume_m3"] == pytest.approx(0.005175, rel=1e-6)
    assert s["admissible_volume_m3"] == pytest.approx(0.00425, rel=1e-6)
    assert s["orientation_within_peak_share"] / s["orientation_usable_share"] == pytest.approx(
        0.871, abs=0.001
    )


def test_one_admissible_set_for_the_map_teleop_and_check(hardware_plan, random_poses):
    """The map's ``admissible`` flag, teleop's boundary (``admissible_poses``) and ``check``'s
    verdict on a pose held still (the validator's limits and singularity measures, the holding
    torque against the reference's share, the clearance) agree pose by pose."""
    from stewart_drake.plant.clearance import clearance_model
    from stewart_drake.run.reference import admissible_poses

    geometry, motors = hardware_plan.geometry, hardware_plan.motor_limits
    rng = np.random.default_rng(5)
    x = np.concatenate(
        [
            random_poses[:120],
            X_HOME + rng.uniform(-1, 1, (120, 6)) * [0.5, 0.5, 0.5, 0.12, 0.12, 0.1],
        ]
    )
    mapped = workspace.classify(geometry, x, motor_limits=motors)["admissible"]
    teleop = admissible_poses(
        geometry,
        x,
        peak_torque_Nm=motors.peak_torque_Nm,
        torque_fraction=motors.margin,
        clearance=clearance_model(geometry),
    )
    clearance = clearance_model(geometry)
    checked = [
        limits.validate_trajectory(
            geometry,
            np.array([0.0, 1.0]),
            np.stack([pose, pose]),
            raise_unreachable=False,
            x_dot=np.zeros((2, 6)),
            x_ddot=np.zeros((2, 6)),
            clearance=clearance,
            motor_limits=motors,
        ).ok
        for pose in x
    ]
    np.testing.assert_array_equal(mapped, teleop)
    np.testing.assert_array_equal(mapped, np.array(checked))
    assert 20 < mapped.sum() < len(x) - 20  # both verdicts are exercised
