"""The LQI's compiled building blocks (:mod:`~stewart_drake.control.lqi.step`,
:mod:`~stewart_drake.control.lqi.reschedule`) against numpy and against their uncompiled
``py_func`` (:data:`~stewart_drake.control.lqi.step.reference`) on random inputs. (Whole steps,
the gain pipeline and the cache: test_lqi_step.py.)"""

import numpy as np
import pytest
from conftest import HANG_S

from stewart_drake.control.lqi import reschedule, step
from stewart_drake.control.lqi.step import reference
from stewart_drake.robot import kinematics, single_pose
from stewart_drake.robot.geometry import X_HOME


def test_the_reference_is_each_kernel_s_own_py_func():
    """Equal by construction: the uncompiled step runs the code numba compiles, each compiled
    function's ``py_func``, and nothing else."""
    kernels = {name: f for name, f in vars(step).items() if hasattr(f, "py_func")}
    assert set(vars(reference)) == set(kernels)
    for name, f in vars(reference).items():
        assert f.__code__ is kernels[name].py_func.__code__, name
        assert not hasattr(f, "py_func")  # plain Python, calling plain Python


def test_the_compiled_ik_equals_the_batched_ik_and_nan_where_unreachable(geometry, random_poses):
    constants = single_pose.leg_constants(geometry)
    compiled = np.array(constants)  # as the LQI's estimate passes them
    for x in random_poses[:50]:
        theta = np.asarray(step.ik_compiled(compiled, x))
        np.testing.assert_allclose(theta, kinematics.ik(geometry, x), rtol=0, atol=1e-12)
        np.testing.assert_array_equal(theta, single_pose.ik_scalar(constants, x.tolist()))
    far = X_HOME + np.array([0, 0, 0, 0, 0, 0.5])
    assert np.isnan(np.asarray(step.ik_compiled(compiled, far))).all()


def test_solve6_and_matvec_give_the_reference_s_bits_and_numpy_s_numbers():
    rng = np.random.default_rng(11)
    for _ in range(200):
        A = rng.normal(size=(6, 6))
        b = rng.normal(size=6)
        x, ok = step.solve6(A, b)
        x_ref, ok_ref = reference.solve6(A, b)
        assert ok and ok_ref
        np.testing.assert_array_equal(x, x_ref)  # the same bits
        np.testing.assert_allclose(A @ x, b, atol=1e-10 * np.linalg.cond(A))
        np.testing.assert_array_equal(step.matvec(A, b), reference.matvec(A, b))
        np.testing.assert_allclose(step.matvec(A, b), A @ b, rtol=1e-13, atol=1e-14)
    singular = np.ones((6, 6))
    singular[0] = 0.0  # a zero pivot, as dgesv would report
    assert not step.solve6(singular, b)[1] and not reference.solve6(singular, b)[1]


def test_lu_solve_agrees_with_lapack_and_flags_an_exactly_singular_matrix():
    rng = np.random.default_rng(12)
    for m, k in ((6, 6), (6, 1), (3, 4), (12, 6)):
        A = rng.normal(size=(m, m)) + m * np.eye(m)
        B = rng.normal(size=(m, k))
        X, ok = reschedule.lu_solve(A, B)
        assert ok
        np.testing.assert_allclose(X, np.linalg.solve(A, B), rtol=1e-12, atol=1e-13)
    A = rng.normal(size=(6, 6))
    A[:, 3] = 0.0
    assert not reschedule.lu_solve(A, np.eye(6))[1]


def test_push_window_writes_the_ring_buffer_like_the_reference():
    rng = np.random.default_rng(13)
    w = 4
    compiled, interpreted = np.zeros(12 * w + 2), np.zeros(12 * w + 2)
    for _ in range(7):  # wraps around the ring
        e, T = rng.normal(size=6), rng.normal(size=6)
        assert step.push_window(compiled, e, T) and reference.push_window(interpreted, e, T)
        np.testing.assert_array_equal(compiled, interpreted)
    assert compiled[-2] == w and compiled[-1] == 7 % w
    np.testing.assert_array_equal(compiled[12 * 2 : 12 * 2 + 6], e)  # the 7th row at head 2
    e[1] = np.nan
    before = compiled.copy()
    assert not step.push_window(compiled, e, T)  # a NaN is not buffered
    np.testing.assert_array_equal(compiled, before)


@pytest.mark.system
def test_the_warm_up_reads_no_array_past_its_end():
    """numba does not check bounds: the warm-up, run as plain Python (NUMBA_DISABLE_JIT=1), must
    index only what its arrays hold (the constants sized from their fields, the layout theirs)."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    done = subprocess.run(
        [sys.executable, "-c", "import stewart_drake.control.lqi.kernels"],
        env=env,
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    assert done.returncode == 0, done.stderr[-2000:]
