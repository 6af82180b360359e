"""The LQI's compiled code, ready to run: importing this module compiles every function the
controller calls (:mod:`.step`, the control period; :mod:`.reschedule`, the gain's
re-schedule), or loads it from numba's disk cache, so that no control period pays for it.

The first import on a machine (and Python version) compiles for about 40 s
(docs/performance.md); later processes load the machine code in about a second. The cache goes
where numba can write: ``NUMBA_CACHE_DIR`` if set, else ``__pycache__`` beside the kernels'
files, else the user's cache folder; when none of them is writable (a read-only install and
home), a folder in the system's temporary directory
(:func:`~stewart_drake.control.kernel_cache.njit_cached`).
:func:`~stewart_drake.control.kernel_cache.will_compile` tells, without importing this module,
whether importing it will compile.
"""

from __future__ import annotations

import numpy as np

from ...robot.single_pose import LEG_SIZE
from . import reschedule, step
from .layout import LqiLayout, StepConstants


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def warm_up() -> None:
    """Compile (or load from the cache) every entry the controller calls
    (:data:`~stewart_drake.control.kernel_cache.ENTRY_POINTS`), with the argument types it
    passes, so that no control period pays for it: a real-time run must not stall on its first
    step. Called once, when the module is first imported."""
    # Zero constants (the estimator off) with the layout they imply, the constants sized from
    # their fields: numba does not check bounds, so an array shorter than the stages index
    # would be read past its end. The types, not the values, decide what is compiled.
    lay = LqiLayout.build(24, 1, True, False, 50)
    c = _readonly(np.zeros(len(StepConstants.get_fields())))
    legs = _readonly(np.zeros((6, LEG_SIZE)))
    u, state, bounds = np.zeros(lay.u_size), np.zeros(lay.state_size), lay.bounds()
    step.step(c, legs, u, state, bounds)
    step.act(c, u, state, bounds, 0)
    step.filter_rate(1e-3, 0.5, np.zeros(6), np.zeros(12))
    step.newton(legs, 1.0, 1e-5, 1, np.array([0, 0, 0, 0, 0, 0.3]), np.zeros(6), np.zeros(6))
    body, x, K = (
        _readonly(np.ones(len(reschedule.BODY))),
        np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.3]),
        np.zeros((6, 24)),
    )
    try:  # compiled before it runs; zero legs make no pose
        reschedule.warm_gain(legs, body, x, 1e-3, 1, np.eye(24), np.eye(6), K, np.inf, 1, 1e-16)
    except (ZeroDivisionError, ValueError, np.linalg.LinAlgError):  # ValueError: not compiled
        pass


warm_up()
