"""The LQI of paper section III as a Drake system: :class:`LqiController` computes (one
compiled step per control period, the gain re-scheduled online), :class:`LqiDiagram` gives it the
controller contract's named ports. The gain design is :mod:`.gain`, the options
:class:`~.driver.LqiDriver`, the step :mod:`.step`.
"""

from __future__ import annotations

import typing
import warnings

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer, Multiplexer

from ...base.checks import as_array, as_number
from ...base.errors import (
    InvalidConfigError,
    NotStabilizableError,
    RiccatiSolveError,
    SimulationDivergedError,
    SingularPoseError,
    UnreachablePoseError,
)
from ...robot import kinematics, statics
from ...robot.geometry import X_HOME, StewartGeometry
from ...robot.single_pose import LEG_SIZE, ik_jacobian
from ..contract import LQI_STATUS_NAMES
from . import layout
from .gain import (
    GOVERNOR_MARGIN,
    LQI_OMEGA_MAX,
    LQI_OMEGA_MIN,
    N_E,
    STEIN_TOL,
    body_constants,
    error_model,
    hautus_checks,
    input_matrix,
    lqi_gain,
    project_onto_torque_bound,
)
from .layout import LqiStatus


class LqiController(LeafSystem):
    """LQI torque controller of the platform pose, re-scheduled online (paper section III): the
    system that computes. :class:`LqiDiagram` gives it the controller contract's named ports
    (:mod:`~stewart_drake.control.contract`); the Diagram uses that.

    Input port ``u`` (:class:`~.layout.LqiLayout`, ``layout``): [``x`` (12,) pose and rate
    [phi, theta, psi, X, Y, Z, rates] in rad, m, /s, or with an estimator ``motor_angle`` (6,)
    rad; ``x_d`` (18,) reference pose, rate, acceleration (/s^2); ``T_ff`` (6,) feed-forward
    torques, N m; ``omega`` (2,) [omega_Q, omega_R] > 0; with ``feature_window``,
    ``motor_torque_applied`` (6,) N m]. Output port ``state``: the whole state, whose first parts
    :class:`LqiDiagram` exports as ``T`` (6,) torques, N m, held (within +-torque_limit_Nm when
    known); ``integral`` (6,) z of eq. 23 [rad s, m s]; ``status`` (7,)
    :data:`~.contract.LQI_STATUS_NAMES`; ``e_bar`` (6,) the error x - x_d acted on; ``x_hat``
    (12,) with an estimator; ``feature_window`` (12 w + 2,) for
    :class:`~.features.DensityFeatures`. The rest (gains: :meth:`gain_in_use`) and the one
    callback per period that runs :mod:`.step`: docs/performance.md, "The control step".

    Args:
        geometry: the robot (for B(x)).
        driver: the options (:class:`~.driver.LqiDriver`; its weights are the Diagram's, on
            ``omega``), checked here by the driver's own ``validate``.
        period_s: control period h, s (paper: 1 ms). offset_s: time of the sample within the
            period, s (the Diagram: half a plant step, the contract's "Sampling").
        x_initial, x_dot_initial: pose of the first gain and its rate (default home, at rest).
        torque_limit_Nm: the motors' torque limit, N m, or None: commands are clipped to it (the
            driver's anti-windup and reference governor act only with a limit).
        delay_periods: control periods between a sample and its torque acting; with
            ``driver.delay_compensation`` the error model carries the pending torques
            (:func:`~.gain.error_model`).
        estimator: None to read ``x``; or a
            :class:`~stewart_drake.control.estimator.PoseEstimator` that tracks the pose from
            ``motor_angle`` (:meth:`~.estimator.PoseEstimator.track`), exported as ``x_hat``.
        feature_window: None, or the samples w of the density features' window (eqs. 35-36).
        compiled: run the compiled stages (:mod:`.kernels`); False runs their ``py_func``
            (:data:`~.step.reference`), the same numbers, many times slower.
    Raises:
        InvalidConfigError: a bad period, offset, limit, delay or window, or a bad option of the
            driver (named ``driver.<option>``).
        RiccatiSolveError: no gain at the start pose. NotStabilizableError: the error model
            fails the Hautus test at the start pose (eqs. 28-29).
    """

    def __init__(
        self,
        geometry: StewartGeometry,
        driver,
        *,
        period_s: float = 1e-3,
        offset_s: float = 0.0,
        x_initial=None,
        x_dot_initial=None,
        torque_limit_Nm: float | None = None,
        delay_periods: int = 0,
        estimator=None,
        feature_window: int | None = None,
        compiled: bool = True,
    ):
        super().__init__()
        self.status_names = LQI_STATUS_NAMES
        self.geometry = geometry
        self.estimator = estimator
        self._configure(
            driver,
            period_s,
            offset_s,
            torque_limit_Nm,
            delay_periods,
            feature_window,
        )
        x0 = X_HOME if x_initial is None else np.asarray(x_initial, dtype=float)
        self.x_initial = x0.copy()
        K0 = self._initial_gain(x0)
        #: Newton iterations and cold solves so far (diagnostics, not state: a benchmark reads
        #: them after a run; they do not affect the simulation).
        self.solve_stats = {"warm": 0, "warm_iterations": 0, "cold": 0}
        T0 = statics.holding_torques(geometry, x0)
        self.layout = layout.LqiLayout.build(
            self.n, self.delay, self.governor, estimator is not None, feature_window
        )
        self.feature_window = feature_window
        self._u = self.DeclareVectorInputPort("u", self.layout.u_size)
        self._state_index = self.DeclareDiscreteState(
            self._initial_state(
                x0,
                np.zeros(6) if x_dot_initial is None else np.asarray(x_dot_initial, dtype=float),
                T0,
                K0,
            )
        )
        self.DeclareStateOutputPort("state", self._state_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.h, offset_sec=float(offset_s), update=self._Update
        )
        self._load_constants(compiled)

    def _configure(
        self, driver, period_s, offset_s, torque_limit_Nm, delay_periods, feature_window
    ) -> None:
        """Check the settings and keep what the stages read: the period, the driver's options,
        the limit, the delay and the unit weights Q_1, R_1."""
        if not (np.isfinite(period_s) and period_s > 0):
            raise InvalidConfigError(f"control period must be > 0 s, got {period_s}")
        if not (0 <= offset_s < period_s):
            raise InvalidConfigError(f"offset_s must be in [0, period_s), got {offset_s}")
        if feature_window is not None and (
            isinstance(feature_window, bool)
            or not isinstance(feature_window, (int, np.integer))
            or feature_window < 1
        ):
            raise InvalidConfigError(
                f"feature_window must be None or an integer >= 1, got {feature_window!r}"
            )
        self.driver = driver.validate(
            period_s, delay_periods, prefix="driver.", delay_name="delay_periods"
        )
        self.h = float(period_s)
        self.steps_per_schedule = int(round(driver.schedule_period_s / period_s))
        self.scales = driver.scales.build()
        self.riccati = driver.riccati
        self.torque_limit = (
            None
            if torque_limit_Nm is None
            else as_number("torque_limit_Nm", torque_limit_Nm, 0.0, lo_open=True)
        )
        self.anti_windup = driver.anti_windup
        self.governor = driver.reference_governor and self.torque_limit is not None
        error_model(np.eye(6), self.h, delay_periods)  # checks delay_periods
        self.delay = int(delay_periods) if driver.delay_compensation else 0
        self.n = N_E + 6 * self.delay
        self._governor_bound = (
            GOVERNOR_MARGIN * self.torque_limit
            if self.governor and self.torque_limit is not None
            else np.inf
        )
        self._Q1, self._R1 = self.scales.Q_unit(self.delay), self.scales.R_unit()
        self.schedule_pose = driver.schedule_pose
        self.gain_transfer = driver.gain_transfer
        self.friction = float(driver.friction_compensation_Nm)
        if self.friction > 0.0 and self.estimator is None:
            raise InvalidConfigError(
                "driver.friction_compensation_Nm needs the encoders' estimator (crank rates from "
                "its Jacobian): set it to 0 on the ideal robot, or give the robot hardware"
            )

    def _initial_gain(self, x0) -> np.ndarray:
        """K at the start pose and unit weights, after the Hautus test of the error model there
        (eqs. 28-29)."""
        A, B = error_model(input_matrix(self.geometry, x0), self.h, self.delay)
        self.hautus = hautus_checks(A, B, np.sqrt(self._Q1))
        if not (self.hautus["stabilizable"] and self.hautus["detectable"]):
            raise NotStabilizableError(self.hautus, x0)
        K0 = lqi_gain(A, B, self._Q1, self._R1)
        self.K_initial = K0
        return K0

    def _load_constants(self, compiled: bool) -> None:
        """What the stages need and never change (configuration, not state), read-only as the
        compiled stages were compiled for (:func:`~.kernels.warm_up`)."""
        self.compiled = bool(compiled)
        self._stages = _kernels().step if self.compiled else _uncompiled_step()
        self._constants = self._step_constants()
        self._bounds = self.layout.bounds()
        self._legs = (
            np.zeros((6, LEG_SIZE)) if self.estimator is None else self.estimator.legs.copy()
        )
        self._legs.setflags(write=False)
        self._newton_x = np.zeros(6)
        self._gain_legs = statics.kernel_constants(self.geometry)[0].copy()
        self._body = body_constants(self.geometry)
        for constant in (self._gain_legs, self._body):
            constant.setflags(write=False)

    def _initial_state(self, x0, v0, T0, K0) -> np.ndarray:
        """The state at t = 0: holding torques, weights 1 and one solve (K_initial) so far, the
        estimate at x0 moving at v0, K = K_old = K0, and a counter that makes the first update
        re-solve at the measured pose."""
        lay = self.layout
        state = np.zeros(lay.state_size)
        state[lay.T] = T0
        status = LqiStatus(state[lay.status])
        status.omega_Q = status.omega_R = status.gain_solves = 1.0
        state[lay.counter] = self.steps_per_schedule
        state[lay.K] = state[lay.K_old] = K0.reshape(-1)
        if self.governor:
            state[lay.hold] = np.concatenate([x0, np.zeros(12), T0])
        if self.estimator is not None:
            state[lay.x_hat] = np.concatenate([x0, v0])
            state[lay.J_inv] = np.linalg.inv(ik_jacobian(self.geometry, x0)[1]).reshape(-1)
        return state

    def _step_constants(self) -> np.ndarray:
        """The constants of the stages (``layout.StepConstants``) as the array they read."""
        c = layout.StepConstants(np.zeros(len(layout.StepConstants.get_fields())))
        c.h = self.h
        c.torque_limit = np.inf if self.torque_limit is None else self.torque_limit
        c.governor_bound = self._governor_bound
        c.steps_per_schedule = self.steps_per_schedule
        c.schedule_pose = float(self.schedule_pose)
        c.anti_windup = float(self.anti_windup)
        c.transfer = layout.TRANSFER_CODES[self.gain_transfer]
        if self.estimator is not None:
            c.estimator = 1.0
            c.alpha = self.estimator.alpha
            c.fk_jump = self.estimator.chord_step_max
            c.friction = self.friction
            c.friction_rate = self.driver.friction_rate_rad_s
        constants = c[:]
        constants.setflags(write=False)
        return constants

    # -- gain ----------------------------------------------------------------------------------
    def _check_weights(self, omega_Q: float, omega_R: float) -> tuple[float, float]:
        return (
            as_number("omega_Q", omega_Q, LQI_OMEGA_MIN, LQI_OMEGA_MAX),
            as_number("omega_R", omega_R, LQI_OMEGA_MIN, LQI_OMEGA_MAX),
        )

    def gain(self, x, omega_Q: float = 1.0, omega_R: float = 1.0, K_start=None) -> np.ndarray:
        """(6, n) LQI gain K = [K_p | K_I (| K_u)] at pose x for weights omega_Q, omega_R (eq. 33);
        n = 18, + 6 per period of delay (the gain on the pending torques).

        Args:
            K_start: optional (6, 18) nearby stabilizing gain: the gain is then refined from it
                by Newton's method (:func:`~.reschedule.newton_gain`; same K to < 1e-8
                relative), with the cold DARE as the fallback.
        Raises:
            InvalidConfigError: weights not in [1e-3, 1e3]; RiccatiSolveError: see lqi_gain.
        """
        x = as_array("pose x", x, shape=(6,))
        kinematics.ik(self.geometry, x)  # a typed error for a bad or unreachable pose
        return self._gain(x, omega_Q, omega_R, K_start)[0]

    def _gain(self, x, omega_Q, omega_R, K_start):
        """(K, J^-1): the gain of :meth:`gain` and the inverse Jacobian at x it used.

        From a start gain, one compiled call (:func:`~.reschedule.warm_gain`: B(x), the error
        model and Newton's method, the same numbers as :func:`~.gain.input_matrix`,
        :func:`~.gain.error_model` and the Newton iteration on Drake's Stein solver), about a
        fifth of their cost in numpy (benchmarks/realtime.py --riccati); the cold DARE is the
        fallback, on the same compiled B(x) (:func:`~.reschedule.input_matrix`).
        """
        omega_Q, omega_R = self._check_weights(omega_Q, omega_R)
        x = np.ascontiguousarray(x, dtype=float)
        Q, R = omega_Q * self._Q1, omega_R * self._R1
        if K_start is not None:
            one_step = self.riccati == "track"
            K, J_inv, iterations = _kernels().reschedule.warm_gain(
                self._gain_legs,
                self._body,
                x,
                self.h,
                self.delay,
                Q,
                R,
                np.ascontiguousarray(K_start, dtype=float),
                np.inf if one_step else 1e-4,
                1 if one_step else 8,
                STEIN_TOL,
            )
            if iterations > 0:
                self.solve_stats["warm"] += 1
                self.solve_stats["warm_iterations"] += iterations
                return K, J_inv
            # a singular pose is named below; a failed Newton iteration falls back to the cold
            # solve
        B_c, J, ok = _kernels().reschedule.input_matrix(self._gain_legs, self._body, x)
        if not ok:
            raise SingularPoseError("B_c", np.inf, np.inf, pose=np.ravel(x))
        A, B = error_model(B_c, self.h, self.delay)
        self.solve_stats["cold"] += 1
        return lqi_gain(A, B, Q, R), np.linalg.inv(J)

    def govern(self, hold, ref) -> np.ndarray:
        """The reference the governor follows when ``ref`` is out of reach: the pose nearest to
        ``ref[:6]`` (Euclidean in rad and m) whose holding torques are within
        :data:`GOVERNOR_MARGIN` of the limit, moving with the part of the reference's rate that
        keeps them there.

        One step of sequential quadratic programming per control period, from the last governed
        pose ``hold[:6]`` (so the governed reference moves continuously: started from ``ref``
        each time, the set of motors at the bound can switch and the reference jump by
        centimetres): the step towards ``ref`` projected exactly onto the motors' bound
        linearized at that pose by finite differences (one batched statics call;
        :func:`project_onto_torque_bound`). The reference moves little in a period, so one step
        is within 6 um | 2 urad and 3e-7 N m of three along the paper manoeuvre, at 0.6 ms
        instead of 1.1 ms.

        The projection is exact, onto every motor's bound at once: a step projected only onto
        the motors the full step would overload can push another one to the limit itself, and a
        motor at the limit keeps no headroom for feedback (docs/hardware.md). The rate and
        acceleration are those of the reference projected onto the tangent of the active bounds
        (the derivative of the projection, curvature neglected), so the pose and the rate the
        LQI tracks agree. On the paper manoeuvre's extreme with a 0.35 N m limit the nearest
        such pose shifts Y and Z by up to 19 and 13 mm rather than giving up a fifth of a radian
        of roll. Ours: the paper has no torque limit.

        Args:
            hold: (24,) the last governed reference (followed at rest if no pose is found).
            ref: (18,) the reference out of reach.
        Returns:
            (24,) [pose (6), rate (6), acceleration (6), the pose's holding torques (6)].
        """
        bound, eps = GOVERNOR_MARGIN * self.torque_limit, 1e-6  # type: ignore[operator]
        x = hold[:6] if np.any(hold[18:]) else ref[:6]
        try:
            T = statics.holding_torques(
                self.geometry, x + np.vstack([np.zeros(6), eps * np.eye(6)])
            )
            G = ((T[1:] - T[0]) / eps).T  # d T / d x, (6, 6)
            step, C = project_onto_torque_bound(ref[:6] - x, T[0], G, bound)
            x = x + step
            T0 = statics.holding_torques(self.geometry, x)
            tangent = np.eye(6) - C.T @ np.linalg.solve(C @ C.T, C) if len(C) else np.eye(6)
        except (UnreachablePoseError, SingularPoseError, InvalidConfigError, np.linalg.LinAlgError):
            T0 = np.full(6, np.inf)
        if not np.abs(T0).max() <= self.torque_limit:
            return np.concatenate([hold[:6], np.zeros(12), hold[18:]])
        return np.concatenate([x, tangent @ ref[6:12], tangent @ ref[12:18], T0])

    def inputs(self, context) -> np.ndarray:
        """The input vector ``u`` of this period (``layout``), read once: the one place the
        controller reads its ports, so a test can inject a fault there."""
        return typing.cast(np.ndarray, self._u.Eval(context))

    # -- update --------------------------------------------------------------------------------
    def gain_in_use(self, context) -> np.ndarray:
        """(6, n) the gain K the controller's state holds in ``context`` (its own context)."""
        state = context.get_discrete_state(self._state_index).get_value()
        return state[self.layout.K].reshape(6, self.n).copy()

    def state_part(self, context, name: str) -> np.ndarray:
        """A copy of the named part of the state (:class:`~.layout.LqiLayout`, e.g. "z",
        "status") in ``context`` (the controller's own)."""
        state = context.get_discrete_state(self._state_index).get_value()
        return state[getattr(self.layout, name)].copy()

    def _Update(self, context, discrete_state):
        # One port in, the stages (compiled) on the state Drake owns (discrete_state holds the
        # current values, updated in place), and Python only for the rare stages.
        u = self.inputs(context)
        state = discrete_state.get_mutable_value(self._state_index)
        need, flags = self._stages.step(self._constants, self._legs, u, state, self._bounds)
        if need:
            flags = self._stages.act(
                self._constants,
                u,
                state,
                self._bounds,
                self._python_stages(context, need, u, state),
            )
        if flags & layout.NONFINITE_SAMPLE:
            lay = self.layout
            sample = np.concatenate([state[lay.e_bar], u[lay.T_applied]])
            raise SimulationDivergedError(
                f"non-finite {'e_bar' if not np.all(np.isfinite(sample[:6])) else 'T'} = "
                f"{np.array2string(sample, precision=4)} ([e_bar, T]) at the density features' "
                f"window (features are not computed from diverged signals)",
                t=context.get_time(),
            )

    # -- the stages that run in Python -------------------------------------------------------
    def _python_stages(self, context, need: int, u, state) -> int:
        """Estimate by full Newton, re-schedule, govern, as ``need`` says; returns the mode
        flags :func:`~.step.act` needs (GAIN_CHANGED, GOVERNED)."""
        lay, mode = self.layout, 0
        if need & layout.NEED_NEWTON:
            self._estimate_by_newton(u[lay.pose_in], state[lay.x_hat])
        x = u[lay.pose_in] if self.estimator is None else state[lay.x_hat]
        if need & layout.NEED_SCHEDULE and self._reschedule(context, x, u[lay.omega], state):
            mode |= layout.GAIN_CHANGED
        if need & layout.NEED_GOVERNOR:
            state[lay.hold] = self.govern(state[lay.hold], u[lay.x_d])
            mode |= layout.GOVERNED
        return mode

    def _estimate_by_newton(self, theta, x_hat) -> None:
        """Estimate: the full Newton solve when the chord step is refused (a jump, a stale
        Jacobian; the compiled stage :func:`~.step.newton`, the estimator's steps), then the
        rate filter."""
        estimator, x = self.estimator, self._newton_x
        x0 = x_hat[:6] + self.h * x_hat[6:]
        self._stages.newton(
            self._legs, estimator.mode, estimator.tol, estimator.max_iterations, x0, theta, x
        )
        self._stages.filter_rate(self.h, estimator.alpha, x, x_hat)

    def _reschedule(self, context, x, omega, state) -> bool:
        """Re-schedule: re-solve the gain at the estimated pose for the weights on the port
        (eqs. 31-33, :meth:`_gain`), keeping the previous gain for the gain transfer and the
        Jacobian's inverse for the estimator. A failed solve keeps the last good gain (with a
        warning, then every hundredth). True if the gain changed."""
        lay = self.layout
        status, K = LqiStatus(state[lay.status]), state[lay.K].reshape(6, self.n)
        try:
            K_new, J_inv = self._gain(
                np.array(x[:6]) if self.schedule_pose else self.x_initial,
                omega[0],
                omega[1],
                K_start=K if self.riccati != "cold" else None,
            )
        except (
            RiccatiSolveError,
            InvalidConfigError,
            UnreachablePoseError,
            SingularPoseError,
            np.linalg.LinAlgError,
        ) as err:
            status.gain_failures += 1
            if status.gain_failures == 1 or status.gain_failures % 100 == 0:
                warnings.warn(
                    f"t = {context.get_time():.4f} s: gain re-schedule failed ({err}); "
                    f"keeping the last good gain ({int(status.gain_failures)} failures "
                    f"so far)",
                    RuntimeWarning,
                    stacklevel=1,
                )
            return False
        status.omega_Q, status.omega_R = omega
        status.gain_solves += 1
        state[lay.K_old] = state[lay.K]
        K[:] = K_new
        if self.estimator is not None:
            state[lay.J_inv] = J_inv.reshape(-1)
        return True


class LqiDiagram(Diagram):
    """:class:`LqiController` with the controller contract's named ports: a ``Multiplexer``
    gathers them into its input vector and a ``Demultiplexer`` splits its state into outputs
    (C++ systems: the controller's Python update reads one port and writes one vector).

    Input ports: ``x`` (12,) or with an estimator ``motor_angle`` (6,); ``x_d`` (18,); ``T_ff``
    (6,); ``omega`` (2,); with a feature window ``motor_torque_applied`` (6,).
    Output ports: ``T`` (6,), ``integral`` (6,), ``status`` (7,), ``e_bar`` (6,), with an
    estimator ``x_hat`` (12,), with a feature window ``feature_window`` (12 w + 2,).
    Units and meanings: :class:`LqiController`.

    Args:
        as :class:`LqiController` (geometry, the :class:`~.driver.LqiDriver`, then keywords).
    Attributes:
        lqi: the :class:`LqiController` inside (gains, governor, settings).
        status_names: :data:`~.contract.LQI_STATUS_NAMES`.
    """

    def __init__(self, geometry: StewartGeometry, driver, **settings):
        super().__init__()
        builder = DiagramBuilder()
        self.lqi = LqiController(geometry, driver, **settings)
        builder.AddNamedSystem("lqi", self.lqi)
        self.status_names = LQI_STATUS_NAMES
        lay = self.lqi.layout
        names = (
            "x" if self.lqi.estimator is None else "motor_angle",
            "x_d",
            "T_ff",
            "omega",
            "motor_torque_applied",
        )
        sizes = [getattr(lay, p).stop - getattr(lay, p).start for p in layout.PARTS[:5]]
        inputs = [(name, size) for name, size in zip(names, sizes) if size]
        mux = builder.AddNamedSystem("inputs", Multiplexer([size for _, size in inputs]))
        for k, (name, _) in enumerate(inputs):
            builder.ExportInput(mux.get_input_port(k), name)
        builder.Connect(mux.get_output_port(), self.lqi.get_input_port())
        parts = [
            (port, getattr(lay, p))
            for p, port in layout.EXPORTED.items()
            if getattr(lay, p).stop > getattr(lay, p).start
        ]
        exported = parts[-1][1].stop
        sizes = [sl.stop - sl.start for _, sl in parts] + [lay.state_size - exported]
        demux = builder.AddNamedSystem("outputs", Demultiplexer(sizes))
        builder.Connect(self.lqi.get_output_port(), demux.get_input_port())
        for k, (port, _) in enumerate(parts):
            builder.ExportOutput(demux.get_output_port(k), port)
        builder.BuildInto(self)

    @property
    def n(self) -> int:
        """Columns of the gain, 18 + 6 d."""
        return self.lqi.n

    @property
    def geometry(self) -> StewartGeometry:
        """The robot the controller believes in."""
        return self.lqi.geometry

    def lqi_context(self, context):
        """The :class:`LqiController`'s context inside this Diagram's ``context``."""
        return self.GetSubsystemContext(self.lqi, context)

    def gain_in_use(self, context) -> np.ndarray:
        """(6, n) the gain in use in this Diagram's ``context``
        (:meth:`LqiController.gain_in_use`)."""
        return self.lqi.gain_in_use(self.lqi_context(context))

    def get_x_input_port(self):
        return self.GetInputPort("x")

    def get_x_d_input_port(self):
        return self.GetInputPort("x_d")

    def get_T_ff_input_port(self):
        return self.GetInputPort("T_ff")

    def get_omega_input_port(self):
        return self.GetInputPort("omega")


def _kernels():
    """The compiled code (:mod:`.kernels`: :mod:`.step` and :mod:`.reschedule`), imported when a
    controller first needs it (numba's import and the first compilation are paid by runs, not
    by importing the controller)."""
    from . import kernels

    return kernels


def _uncompiled_step():
    """:data:`~.step.reference`, the step as the Python numba compiles (imports numba, compiles
    nothing)."""
    from . import step

    return step.reference
