"""Pose and rate of the platform from the motor encoders: what a controller of the robot as built
can know (controller side of the station's ``motor_angle`` port).

Forward kinematics by Newton's method on the closed-form IK (the Jacobian is analytic), warm
started from the previous estimate advanced by the previous rate, with the branch guard of
:func:`~stewart_drake.robot.forward_kinematics.fk_unchecked` (a step may not change the sign of
det J: it would land in another assembly mode with the same motor angles). The rate is the backward
difference of the estimates, low-passed at ``rate_cutoff_hz``.

Why this and not Drake's ``DiscreteDerivative`` + a low-pass filter (measured in
docs/hardware.md): those primitives update at their own instants (offset 0), half a plant step
before the controller samples, so the rate they give is one control period old; here the pose and
the rate are an output computed from the encoders *when the controller reads them* (direct
feedthrough), and the state only keeps the last estimate for the next warm start. Why not an
observer on the error model: the LQI's model is a double integrator in the pose error with an
input matrix re-scheduled from the pose; a Kalman filter on it would need the applied torques
(which the delay and the current loop change) and a noise model the quantization does not have
(a bounded, correlated error); the difference does the same job at the encoder resolutions we
study (rate noise well below the LQI's 1 rad/s | 0.1 m/s scale, docs/hardware.md).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_array, as_number
from ..robot.kinematics import X_HOME
from ..robot.single_pose import ik_jacobian, ik_single, jacobian_single, leg_constants

#: Largest Newton chord-step correction the estimate accepts per period (rad or m); a larger
#: one (a jump, a stale Jacobian) is solved by full Newton (:meth:`PoseEstimator.track`).
CHORD_STEP_MAX = 1e-3


class PoseEstimator:
    """The estimation step, shared by :class:`FkEstimator` and controllers that estimate in their
    own update (the LQI does, to save a Python callback per control period).

    The encoders read theta_i + o_i (o_i their zero errors, ``geometry.encoder_offsets``):
    every reading is taken back to the motor angle by the offsets the controller believes.

    Args:
        geometry: the robot the controller believes in (its encoders' zero errors included).
        period_s: control period h, s.
        quantum_rad: one encoder count, rad; Newton stops when every motor angle of the estimate
            is within ``tolerance_counts`` of a count of the measurement.
        x_reference: (6,) a pose of the assembly mode to stay in (the start pose).
        rate_cutoff_hz: first-order low-pass on the differentiated pose, Hz.
        tolerance_counts: see quantum_rad. max_iterations: Newton steps at most per update.
    Raises:
        InvalidConfigError: a non-finite or non-positive setting.
    """

    def __init__(
        self,
        geometry,
        period_s: float,
        quantum_rad: float,
        x_reference=X_HOME,
        rate_cutoff_hz: float = 100.0,
        tolerance_counts: float = 0.01,
        max_iterations: int = 4,
    ):
        self.geometry = geometry
        self.h = as_number("period_s", period_s, 0.0, lo_open=True)
        self.quantum = as_number("quantum_rad", quantum_rad, 0.0, lo_open=True)
        self.tol = as_number("tolerance_counts", tolerance_counts, 0.0, lo_open=True) * self.quantum
        cutoff = as_number("rate_cutoff_hz", rate_cutoff_hz, 0.0, lo_open=True)
        #: Weight of the new difference in the rate's low-pass: 1 - exp(-2 pi f_c h).
        self.alpha = 1.0 - math.exp(-2 * math.pi * cutoff * self.h)
        self.max_iterations = int(max_iterations)
        #: (6, LEG_SIZE) leg constants of :func:`~stewart_drake.robot.single_pose.ik_scalar`, as
        #: the compiled step reads them (the encoders' zero errors in the last column).
        self.legs = np.array(leg_constants(geometry))
        self.legs.setflags(write=False)
        #: (6,) the encoders' zero errors the controller believes, rad.
        self.offsets = np.array(geometry.encoder_offsets)
        #: Largest chord-step correction accepted (rad or m), else a full Newton solve.
        self.chord_step_max = CHORD_STEP_MAX
        _, J0 = ik_jacobian(geometry, as_array("x_reference", x_reference, shape=(6,)))
        #: sign det J of the assembly mode the estimate stays in (that of the start pose).
        self.mode = float(np.sign(np.linalg.det(J0)))

    def estimate(self, theta, x_start) -> tuple[np.ndarray, int, bool]:
        """FK of the encoders' reading theta (6,) (the motor angles plus their zero errors) by
        Newton from x_start (6,).

        Returns:
            (x (6,), Newton steps, converged). A step that would change the sign of det J or
            leave the workspace is halved (up to 20 times); the sign is checked only after steps
            above 1e-3 (rad or m): a shorter step from a pose of the right mode cannot cross a
            singularity the guard of the reference (1/sigma_max(J) >= 0.01) keeps away. Warm
            started near the answer, as every control period is, the usual cost is the IK and
            the Jacobian at the start and the IK alone at the end (the convergence check).
        """
        x = np.array(x_start, dtype=float)
        theta = np.asarray(theta, dtype=float) - self.offsets  # exact for zero offsets
        th, cache = ik_single(self.geometry, x)
        for step in range(self.max_iterations + 1):
            r = (th - theta + np.pi) % (2 * np.pi) - np.pi
            if np.abs(r).max() <= self.tol:
                return x, step, True
            J = jacobian_single(self.geometry, cache)
            if step == self.max_iterations or not np.isfinite(J).all():
                break
            dx = np.linalg.solve(J, r)
            for _ in range(20):  # branch guard and workspace: halve the step
                candidate = x - dx
                th_c, cache_c = ik_single(self.geometry, candidate)
                if np.isfinite(th_c).all() and (
                    np.abs(dx).max() < 1e-3
                    or np.sign(np.linalg.det(jacobian_single(self.geometry, cache_c))) == self.mode
                ):
                    break
                dx = 0.5 * dx
            else:
                break
            x, th, cache = candidate, th_c, cache_c
        return x, step, False

    def track(self, theta, x_prev, v_prev, J_inv) -> tuple[np.ndarray, np.ndarray]:
        """The next estimate by one Newton *chord* step: J^-1 from the last re-schedule (a few
        ms old) instead of a new Jacobian, so one IK evaluation per control period.

        From x_0 = x_prev + h v_prev the step is x = x_0 - J_inv wrap(ik(x_0) - theta). Its error
        is the chord's (I - J_inv J) times the correction plus the IK's curvature times the
        correction squared. Along the paper manoeuvre at 2^17 counts, with the Jacobian 10 ms
        old, the corrections are 4e-5 (median) to 1.7e-4 (rad or m) and the chord step differs
        from the full Newton of :meth:`estimate` by 1e-7 (median) to 1e-6, where the
        quantization itself moves the estimate by up to 8e-5 (a test holds these). A correction
        above :data:`CHORD_STEP_MAX` (a jump, a stale Jacobian) falls back to :meth:`estimate`.
        This is the LQI's own stage (:func:`~.lqi.step.estimate`), run uncompiled
        (:data:`~.lqi.step.reference`: no compilation for an estimate outside the controller).

        Args:
            theta (6,) the encoders' reading, rad; x_prev, v_prev (6,) the last estimate;
            J_inv (6, 6) or (36,) row-major, the inverse Jacobian.
        Returns:
            (x (6,), v (6,)) [rad, m; rad/s, m/s].
        """
        from .lqi.step import reference  # imports numba, compiles nothing

        theta = np.asarray(theta, dtype=float)
        x_hat = np.concatenate([np.asarray(x_prev, dtype=float), np.asarray(v_prev, dtype=float)])
        if not reference.estimate(
            self.legs,
            self.h,
            self.alpha,
            self.chord_step_max,
            theta,
            x_hat,
            np.asarray(J_inv, dtype=float).reshape(6, 6),
        ):
            reference.filter_rate(
                self.h, self.alpha, self.estimate(theta, x_hat[:6] + self.h * x_hat[6:])[0], x_hat
            )
        return x_hat[:6], x_hat[6:]

    def update(self, theta, x_prev, v_prev) -> tuple[np.ndarray, np.ndarray]:
        """The next estimate from the encoders theta (6,) and the last estimate x_prev, v_prev:
        FK warm started at x_prev + h v_prev, then the rate low-passed from the difference.

        Returns:
            (x (6,), v (6,)) [rad, m; rad/s, m/s].
        """
        x, _, _ = self.estimate(theta, x_prev + self.h * v_prev)
        return x, v_prev + self.alpha * ((x - x_prev) / self.h - v_prev)


class FkEstimator(LeafSystem):
    """Pose and rate estimate from the six motor angles, for controllers with an ``x`` input.

    Input port:  ``motor_angle`` (6,) measured crank angles, rad (the encoders).
    Output port: ``x`` (12,) [phi, theta, psi, X, Y, Z] (rad, m) and their rates (rad/s, m/s):
        the controller's ``x`` (controller contract). Computed from the input and the state
        when read (cached until either changes).
    Discrete state (12,): the last estimate and rate, updated every ``period_s`` at ``offset_s``
    (the controller's instants) to the output's value.

    Args:
        estimator: the :class:`PoseEstimator` (geometry, period, quantum, filter).
        offset_s: sample offset within the period, s.
        x_initial, x_dot_initial: (6,) start pose and rate [rad, m; rad/s, m/s].
    Source: FK by Newton on paper eq. 6 (ours: the paper reads the pose from its ADAMS model).
    """

    def __init__(
        self, estimator: PoseEstimator, offset_s: float, x_initial=X_HOME, x_dot_initial=None
    ):
        super().__init__()
        self.estimator = estimator
        x0 = as_array("x_initial", x_initial, shape=(6,))
        v0 = (
            np.zeros(6)
            if x_dot_initial is None
            else as_array("x_dot_initial", x_dot_initial, shape=(6,))
        )
        self._theta = self.DeclareVectorInputPort("motor_angle", 6)
        self.DeclareDiscreteState(np.concatenate([x0, v0]))
        self._x = self.DeclareVectorOutputPort(
            "x",
            12,
            self._CalcX,
            prerequisites_of_calc={self.all_input_ports_ticket(), self.xd_ticket()},
        )
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=estimator.h, offset_sec=float(offset_s), update=self._Update
        )

    def _CalcX(self, context, output):
        state = context.get_discrete_state_vector().get_value()
        x, v = self.estimator.update(self._theta.Eval(context), state[:6], state[6:])
        output.SetFromVector(np.concatenate([x, v]))

    def _Update(self, context, discrete_state):
        discrete_state.set_value(self._x.Eval(context))  # computed once: the output's cache
