"""One source, two speeds: the LQI's compiled step against its uncompiled reference.

The controller runs the stages of :mod:`~stewart_drake.control.lqi.step` compiled (numba); their
``py_func`` (:data:`~stewart_drake.control.lqi.step.reference`) is the same code run by Python.
They must agree to 1e-12 relative on every case the controller meets (they give the same bits:
the sums that feed back are loops in one order), and so must closed-loop runs with either.
"""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from conftest import HANG_S

from stewart_drake.control import kernel_cache
from stewart_drake.control.estimator import PoseEstimator
from stewart_drake.control.lqi import layout, reschedule, step
from stewart_drake.control.lqi.controller import LqiController
from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.control.lqi.gain import (
    balance,
    body_constants,
    error_model,
    input_matrix,
    lqi_gain,
)
from stewart_drake.control.tuning import AnnTunerDriver
from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment

RTOL = 1e-12
GEOMETRY = StewartGeometry()


def _controller(
    estimator: bool,
    delay: int,
    limit,
    window,
    transfer="integral",
    governor=True,
    friction=0.0,
    friction_rate=3e-4,
):
    est = PoseEstimator(GEOMETRY, 1e-3, 2 * np.pi / 2**17) if estimator else None
    driver = LqiDriver(
        schedule_period_s=2e-2,
        gain_transfer=transfer,
        reference_governor=governor,
        riccati="track",
        friction_compensation_Nm=friction,
        friction_rate_rad_s=friction_rate,
    )
    return LqiController(
        GEOMETRY,
        driver,
        period_s=1e-3,
        torque_limit_Nm=limit,
        delay_periods=delay,
        estimator=est,
        feature_window=window,
    )


def _random_case(c: LqiController, rng):
    """(u, state) of ``c``'s layout: a pose near home, a reference near it, torques, an
    integral, pending torques, a window, gains, with the counter due or not."""
    lay = c.layout
    x = X_HOME + rng.uniform(-1, 1, 6) * [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]
    u, state = np.zeros(lay.u_size), c._initial_state(x, np.zeros(6), np.zeros(6), c.K_initial)
    if c.estimator is not None:
        u[lay.pose_in] = kinematics.ik(GEOMETRY, x) + rng.normal(0, 2e-5, 6)
        state[lay.x_hat] = np.concatenate([x + rng.normal(0, 1e-5, 6), rng.normal(0, 0.02, 6)])
        state[lay.J_inv] = np.linalg.inv(kinematics.jacobian(GEOMETRY, x)).reshape(-1)
    else:
        u[lay.pose_in] = np.concatenate([x, rng.normal(0, 0.05, 6)])
    u[lay.x_d] = np.concatenate([x + rng.normal(0, 2e-3, 6), rng.normal(0, 0.05, 12)])
    u[lay.T_ff] = rng.normal(0, 0.2, 6)
    u[lay.omega] = rng.choice([1.0, 2.0]), 1.0  # sometimes new weights
    u[lay.T_applied] = rng.normal(0, 0.2, lay.T_applied.stop - lay.T_applied.start)
    state[lay.z] = rng.normal(0, 1e-4, 6)
    state[lay.e_bar] = rng.normal(0, 1e-3, 6)
    state[lay.counter] = rng.integers(0, 25)
    state[lay.K] = (c.K_initial * (1 + 0.1 * rng.normal(size=c.K_initial.shape))).reshape(-1)
    state[lay.K_old] = c.K_initial.reshape(-1)
    state[lay.pending] = rng.normal(0, 0.05, lay.pending.stop - lay.pending.start)
    if lay.window.stop > lay.window.start:
        w = (lay.window.stop - lay.window.start - 2) // 12
        window = state[lay.window]
        window[:-2] = rng.normal(0, 0.1, 12 * w)
        window[-2], window[-1] = rng.integers(1, w + 1), rng.integers(0, w)
    return u, state


def _agree(a, b):
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=RTOL * max(1.0, np.abs(b).max()))


CASES = [
    dict(estimator=e, delay=d, limit=lim, window=w, transfer=t)
    for e in (False, True)
    for d in (0, 1, 2)
    for lim in (None, 0.05, 0.7)
    for w, t in ((None, "integral"), (5, "feedback"), (None, "none"))
] + [  # the Coulomb friction feed-forward, which needs the estimator's Jacobian
    dict(estimator=True, delay=d, limit=lim, window=None, transfer="integral", friction=0.02)
    for d in (0, 1)
    for lim in (None, 0.05, 0.7)
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(f"{k}={v}" for k, v in c.items()))
def test_the_compiled_step_equals_its_uncompiled_reference(case):
    """observe, act (every mode) and step on random poses, weights, saturation, delays."""
    c = _controller(**case)
    rng = np.random.default_rng(abs(hash(tuple(case.values()))) % 2**32)
    saturated = 0
    for _ in range(12):
        u, state = _random_case(c, rng)
        args = (c._constants, c._legs, u, None, c._bounds)
        results = []
        for stages in (step.reference, step):
            s = state.copy()
            need, flags = stages.step(args[0], args[1], u, s, args[4])
            acts = []
            for mode in (layout.GAIN_CHANGED, layout.GOVERNED, 0):
                a = s.copy()
                acts.append((stages.act(c._constants, u, a, c._bounds, mode), a))
            results.append((need, flags, s, acts))
        (n0, f0, s0, a0), (n1, f1, s1, a1) = results
        assert (n0, f0) == (n1, f1)
        _agree(s1, s0)
        for (fa, sa), (fb, sb) in zip(a0, a1):
            assert fa == fb
            _agree(sb, sa)
        saturated += sum(
            int(a[c.layout.status][layout.SATURATED_STEPS] > 0) for _, a in a0 + [(f0, s0)]
        )
    if case["limit"] == 0.05:
        assert saturated > 0  # the clipping path was taken


def test_a_non_finite_sample_is_flagged_by_both():
    c = _controller(False, 0, None, 5)
    u, state = _random_case(c, np.random.default_rng(3))
    u[c.layout.T_applied][2] = np.nan
    for stages in (step.reference, step):
        s = state.copy()
        assert stages.act(c._constants, u, s, c._bounds, 0) == layout.NONFINITE_SAMPLE


def test_the_estimate_equals_the_reference_and_the_full_newton():
    est = PoseEstimator(GEOMETRY, 1e-3, 2 * np.pi / 2**17)
    rng = np.random.default_rng(4)
    for _ in range(50):
        x = X_HOME + rng.uniform(-1, 1, 6) * [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]
        theta = kinematics.ik(GEOMETRY, x)
        x_hat = np.concatenate([x + rng.normal(0, 2e-5, 6), np.zeros(6)])
        J_inv = np.linalg.inv(kinematics.jacobian(GEOMETRY, x))
        out = []
        for stages in (step.reference, step):
            h = x_hat.copy()
            assert stages.estimate(
                est.legs,
                est.h,
                est.alpha,
                est.chord_step_max,
                theta,
                h,
                J_inv,
            )
            out.append(h)
        _agree(out[1], out[0])
        assert np.abs(out[0][:6] - x).max() < 1e-7  # a chord step lands near the pose


def test_the_compiled_gain_pipeline_equals_numpy():
    """B(x), the error model and a Newton step: compiled against the numpy functions."""
    c = _controller(False, 1, None, None)
    legs, body = c._gain_legs, c._body  # the read-only arrays the controller passes
    np.testing.assert_array_equal(body, body_constants(GEOMETRY))
    rng = np.random.default_rng(5)
    for _ in range(20):
        x = X_HOME + rng.uniform(-1, 1, 6) * [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]
        B_ref, J_ref = input_matrix(GEOMETRY, x), kinematics.jacobian(GEOMETRY, x)
        B_c, J, ok = reschedule.input_matrix(legs, body, x)
        assert ok
        np.testing.assert_allclose(B_c, B_ref, rtol=1e-12, atol=1e-12 * np.abs(B_ref).max())
        np.testing.assert_allclose(J, J_ref, rtol=1e-12, atol=1e-12 * np.abs(J_ref).max())
        A, B = error_model(B_ref, 1e-3, 1)
        A_c, B_c2 = reschedule.zoh_model(B_ref, 1e-3, 1)
        assert np.array_equal(A, A_c) and np.array_equal(B, B_c2)
        Q, R = 2.0 * c._Q1, c._R1
        K, J_inv, n = reschedule.warm_gain(
            legs, body, x, 1e-3, 1, Q, R, c.K_initial, 1e-10, 8, 1e-16
        )
        assert n > 0
        K_cold = lqi_gain(A, B, Q, R)
        assert np.abs(K - K_cold).max() / np.abs(K_cold).max() < 1e-8
        np.testing.assert_allclose(J_inv, np.linalg.inv(J_ref), rtol=1e-10, atol=1e-12)


def test_the_compiled_stein_solve_equals_drakes():
    from pydrake.math import RealDiscreteLyapunovEquation

    c = _controller(False, 1, None, None)
    A, B = error_model(input_matrix(GEOMETRY, X_HOME), 1e-3, 1)
    Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, c._Q1, c._R1)
    K = c.K_initial * d_x[None, :] / d_u[:, None]
    A_c, W = np.ascontiguousarray(Ab - Bb @ K), Qb + K.T @ Rb @ K
    P, steps = reschedule.stein(A_c, W, 1e-16, 64)
    P_ref = RealDiscreteLyapunovEquation(A_c, 0.5 * (W + W.T))
    assert 0 < steps < 30
    assert np.abs(P - P_ref).max() / np.abs(P_ref).max() < 1e-10
    assert reschedule.stein(1.01 * np.eye(3), np.eye(3), 1e-16, 64)[1] == -1  # unstable: no


def _metrics(scenario, compiled):
    m = run_experiment(
        scenario, controller=lambda context: scenario.controller.make(context, compiled)
    ).metrics
    return {
        k: np.asarray(m[k], dtype=float)
        for k in ("rms_error", "peak_error", "peak_torque", "sum_T2_dt", "max_closure_m")
    }


def test_closed_loop_runs_give_the_same_metrics_with_either_step():
    """The ideal robot to 1e-9; the robot as built (encoder quantization turns a last-bit
    difference into another count) within 1 %; with the ANN tuner too."""
    for name, tuner, rtol in (("paper_ideal", False, 1e-9), ("paper_hardware", True, 1e-2)):
        scenario = load_scenario(name, ["duration_s=1.0"])
        if tuner:
            scenario.tuner = AnnTunerDriver()
        reference, compiled = _metrics(scenario, False), _metrics(scenario, True)
        for key, value in reference.items():
            np.testing.assert_allclose(compiled[key], value, rtol=rtol, err_msg=f"{name} {key}")


def test_the_compiled_code_is_cached_against_the_sources_it_inlines():
    """numba's cache sees this file only: the digest of what it inlines from other files must
    be the one recorded, else the cache is bypassed (update DEPENDENCIES_DIGEST)."""
    assert kernel_cache.sources_digest() == kernel_cache.DEPENDENCIES_DIGEST, (
        f"set DEPENDENCIES_DIGEST = {kernel_cache.sources_digest()!r} in kernel_cache.py"
    )
    assert step._CACHE and reschedule._CACHE


@pytest.mark.system
def test_the_cache_falls_back_to_a_writable_folder(tmp_path):
    """With no writable __pycache__ and no writable user cache (a read-only install and home),
    compiled functions cache in the temporary directory instead of failing to import."""
    module_dir = tmp_path / "readonly"
    module_dir.mkdir()
    (module_dir / "__pycache__").write_text("a file where numba wants a folder")
    (module_dir / "tiny.py").write_text("def double(x):\n    return 2 * x\n")
    blocked = tmp_path / "home_file"
    blocked.write_text("")
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(module_dir)!r})
        from stewart_drake.control.kernel_cache import fallback_cache_dir, njit_cached
        import tiny
        f = njit_cached(tiny.double)
        assert f(21) == 42
        print(fallback_cache_dir())
    """)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(
        XDG_CACHE_HOME=str(blocked / "cache"), HOME=str(blocked), TMPDIR=str(tmp_path / "tmp")
    )
    (tmp_path / "tmp").mkdir()
    out = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=HANG_S
    )
    assert out.returncode == 0, out.stderr[-2000:]
    cache = out.stdout.strip().splitlines()[-1]
    assert cache.startswith(str(tmp_path / "tmp"))
    assert any(name.endswith(".nbi") for _, _, files in os.walk(cache) for name in files)


def test_the_friction_feed_forward_adds_coulomb_friction_at_the_reference_s_crank_rates():
    """T with the feed-forward minus T without it is 0.02 tanh(J x_dot_d / 0.5) per motor; the
    pending torques (the feedback's share) are the same, interpreted and compiled."""
    plain = _controller(True, 1, None, None)
    comp = _controller(True, 1, None, None, friction=0.02, friction_rate=0.5)
    u, state = _random_case(comp, np.random.default_rng(5))
    lay = comp.layout
    theta_dot = np.linalg.solve(state[lay.J_inv].reshape(6, 6), u[lay.x_d][6:12])
    expected = 0.02 * np.tanh(theta_dot / 0.5)
    assert 1e-4 < np.abs(expected).min() and np.abs(expected).max() < 0.015  # not a bare sign
    for stages in (step.reference, step):
        a, b = state.copy(), state.copy()
        stages.act(plain._constants, u, a, plain._bounds, 0)
        stages.act(comp._constants, u, b, comp._bounds, 0)
        _agree(b[lay.T] - a[lay.T], expected)
        _agree(b[lay.pending], a[lay.pending])
