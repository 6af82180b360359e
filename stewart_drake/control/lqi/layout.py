"""Names for the LQI's numbers: every part of its input vector and state, its status, the
constants of its step, and the flags its stages exchange.

Named state, no bare indices. :class:`LqiLayout` names every part of ``u`` and ``state``
(index slices); the status part is named by :data:`~stewart_drake.control.contract.LQI_STATUS_NAMES`
(``LqiStatus``, a Drake ``namedview``), the constants by ``StepConstants`` (a ``namedview``). The
compiled stages (:mod:`.step`) cannot take Python objects: they receive the constants as one
float array and the layout as an int array of (start, stop) rows, :meth:`LqiLayout.bounds`, read
through :func:`~.step.part` with the index constants below. numba freezes these constants into
the machine code: a change here is a change of the compiled step
(:data:`~stewart_drake.control.kernel_cache.DEPENDENCIES_DIGEST`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.containers import namedview

from ..contract import LQI_STATUS_NAMES

#: The status group, by name (``status.gain_solves += 1``).
LqiStatus = namedview("LqiStatus", LQI_STATUS_NAMES)
OMEGA_Q, OMEGA_R, GAIN_SOLVES, GAIN_FAILURES, INTEGRAL_NORM, SATURATED_STEPS, GOVERNED_STEPS = (
    range(len(LQI_STATUS_NAMES))
)

#: The constants of the step, by name; ``governor_bound`` and ``torque_limit`` are inf when
#: there is none, ``transfer`` a code of :data:`TRANSFER_CODES`, the flags 0.0 or 1.0;
#: ``friction`` (N m, 0: none) and ``friction_rate`` (rad/s) the Coulomb feed-forward's.
StepConstants = namedview(
    "StepConstants",
    (
        "h",
        "alpha",
        "torque_limit",
        "governor_bound",
        "steps_per_schedule",
        "schedule_pose",
        "anti_windup",
        "transfer",
        "estimator",
        "fk_jump",
        "friction",
        "friction_rate",
    ),
)
(
    H,
    ALPHA,
    TORQUE_LIMIT,
    GOVERNOR_BOUND,
    STEPS_PER_SCHEDULE,
    SCHEDULE_POSE,
    ANTI_WINDUP,
    TRANSFER,
    ESTIMATOR,
    FK_JUMP,
    FRICTION,
    FRICTION_RATE,
) = range(len(StepConstants.get_fields()))
#: gain_transfer modes (see LqiController) as the codes the compiled stages compare.
TRANSFER_CODES = {"none": 0.0, "integral": 1.0, "feedback": 2.0}
TRANSFER_NONE, TRANSFER_INTEGRAL, TRANSFER_FEEDBACK = 0.0, 1.0, 2.0

#: observe() says which stages need Python this period (bit flags).
NEED_NEWTON, NEED_SCHEDULE, NEED_GOVERNOR = 1, 2, 4
#: act() is told what Python did (bit flags) ...
GAIN_CHANGED, GOVERNED = 1, 2
#: ... and answers with this flag when the features' sample was not finite.
NONFINITE_SAMPLE = 1

#: The named parts of the input vector ``u`` and of the state, in order (:class:`LqiLayout`).
PARTS = (
    "pose_in",
    "x_d",
    "T_ff",
    "omega",
    "T_applied",
    "T",
    "z",
    "status",
    "e_bar",
    "x_hat",
    "window",
    "counter",
    "K",
    "K_old",
    "pending",
    "hold",
    "J_inv",
)
(
    POSE_IN,
    X_D,
    T_FF,
    OMEGA,
    T_APPLIED,
    T_PART,
    Z,
    STATUS,
    E_BAR,
    X_HAT,
    WINDOW,
    COUNTER,
    K_PART,
    K_OLD,
    PENDING,
    HOLD,
    J_INV,
) = range(len(PARTS))
#: The parts of the state the controller's Diagram exports, in order: state output ports.
EXPORTED = {
    "T": "T",
    "z": "integral",
    "status": "status",
    "e_bar": "e_bar",
    "x_hat": "x_hat",
    "window": "feature_window",
}
#: Columns of a window row: [e_bar (6), T (6)].
WINDOW_ROW = 12


@dataclass(frozen=True)
class LqiLayout:
    """Where each named part of the LQI's input vector ``u`` and of its state lies: index slices,
    no bare numbers. An absent part (no estimator, no delay, ...) is an empty slice.

    Input vector ``u``:
        pose_in: (12,) the ``x`` input [pose, rate], or with an estimator (6,) ``motor_angle``.
        x_d (18,): the reference [pose, rate, acceleration]. T_ff (6,): feed-forward, N m.
        omega (2,): [omega_Q, omega_R] on the port.
        T_applied (6,): with a feature window, the torques the motors apply, N m.
    State (the exported parts first, in :data:`EXPORTED` order):
        T (6,): the torque command, N m. z (6,): the integral states (eq. 23).
        status (7,): ``LqiStatus``. e_bar (6,): the pose error the last update acted on.
        x_hat (12,): with an estimator, its estimate. window (12 w + 2,): with a feature window,
            the ring buffer [rows [e_bar, T], n_valid, head].
        counter (1,): control periods since the last gain re-solve.
        K, K_old (6 n,): the gain in use and the one before the last re-solve, row-major (6, n),
            n = 18 + 6 d. pending (6 d,): feedback torques commanded but not yet acting, newest
            first. hold (24,): with a governor, its last reference within reach [pose, rate,
            acc, T_ff]. J_inv (36,): with an estimator, its inverse Jacobian, row-major.
    """

    pose_in: slice
    x_d: slice
    T_ff: slice
    omega: slice
    T_applied: slice
    T: slice
    z: slice
    status: slice
    e_bar: slice
    x_hat: slice
    window: slice
    counter: slice
    K: slice
    K_old: slice
    pending: slice
    hold: slice
    J_inv: slice

    @classmethod
    def build(
        cls, n: int, delay_periods: int, governor: bool, estimator: bool, window: int | None
    ) -> LqiLayout:
        """The layout for n gain columns, d periods of delay, with or without a governor, an
        estimator and a feature window of ``window`` samples."""
        inputs = (6 if estimator else 12, 18, 6, 2, 6 if window else 0)
        state = (
            6,
            6,
            len(LQI_STATUS_NAMES),
            6,
            12 if estimator else 0,
            WINDOW_ROW * window + 2 if window else 0,
            1,
            6 * n,
            6 * n,
            6 * delay_periods,
            24 if governor else 0,
            36 if estimator else 0,
        )
        slices = []
        for sizes in (inputs, state):
            stops = np.cumsum(sizes)
            slices += [slice(int(stop - size), int(stop)) for size, stop in zip(sizes, stops)]
        return cls(*slices)

    @property
    def u_size(self) -> int:
        return self.T_applied.stop

    @property
    def state_size(self) -> int:
        return self.J_inv.stop

    def bounds(self) -> np.ndarray:
        """(17, 2) int64 [start, stop) of each part in :data:`PARTS` order, for the compiled
        stages (which cannot read a dataclass)."""
        return np.array(
            [[getattr(self, p).start, getattr(self, p).stop] for p in PARTS], dtype=np.int64
        )
