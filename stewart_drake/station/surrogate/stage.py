"""The external surrogate's stage: a 1-DoF linear axis (a servo driving a toothed belt) with its own
controller, as Drake systems in the platform's Diagram and on its clock.

:class:`SurrogateStage` is the scenario's section: the part, one definition with the servo bus's
(:class:`~stewart_drake.station.surrogate.linear_stage.LinearStage`: by default a ROBOTIS Dynamixel
XM430-W350-T on a GT2 belt over a 40-tooth pulley, 80 mm of travel a turn of the horn, its speed,
force and resolution derived from the motor catalogue), and its position loop.
:func:`add_surrogate_stage` adds the axis to a ``DiagramBuilder`` from Drake's own systems only (no
Python on the per-step path):

    goal table (TrajectorySource, zero-order hold of the goals, each rounded to one count)
      -> PD + feed-forward (MatrixGain on [p_d, v_d, a_d, p, v])
      -> Saturation (+- the part's continuous force)
      -> ZeroOrderHold (the control period, at the platform controller's sample offset)
      -> carriage (discrete LinearSystem at the plant's time step: moving mass and viscous
         friction, exact zero-order-hold discretisation)

Not modelled: the servo's Coulomb friction and its torque-speed line (the speed is checked
before the run instead, :meth:`SurrogateStage.check_signal`); docs/surrogate.md says why.
"""

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.geometry import Box, Rgba
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.systems.primitives import (
    LinearSystem,
    MatrixGain,
    Multiplexer,
    Saturation,
    TrajectorySource,
    ZeroOrderHold,
)
from pydrake.trajectories import PiecewisePolynomial

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from .linear_stage import LinearStage


@dataclass
class SurrogateStage(LinearStage):
    """The surrogate's linear stage in the Diagram, a scenario section (``surrogate.stage``): the
    part (:class:`~stewart_drake.station.surrogate.linear_stage.LinearStage`, the same as the servo
    bus's ``bus.surrogate.stage``: its fields, defaults and sources) and its position loop; SI
    units.

    From the part: the speed the carriage may be asked for is the servo's no-load speed at the
    carriage (61.3 mm/s for the default belt), the force the controller may command its
    continuous force (58 N, saturated there), the goals' step one encoder count (19.5 um).

    Attributes:
        bandwidth_hz: the position loop's natural frequency, Hz.
        damping_ratio: the position loop's damping ratio.
    """

    bandwidth_hz: float = 8.0
    damping_ratio: float = 1.0

    def validate(self, control_period_s: float | None = None) -> "SurrogateStage":
        """Check every field; with ``control_period_s`` (s), that the sampled loop is stable.

        Raises:
            InvalidConfigError: a field out of range (named ``surrogate.stage.<field>``), an
                unknown motor, or a loop that the control period makes unstable (its spectral
                radius named, with the bandwidth to lower).
        """
        p = "surrogate.stage."
        self.check(p)
        as_number(p + "bandwidth_hz", self.bandwidth_hz, 0.0, 200.0, lo_open=True)
        as_number(p + "damping_ratio", self.damping_ratio, 0.1, 5.0)
        if control_period_s is not None:
            rho = self.spectral_radius(control_period_s)
            if rho >= 0.999:
                raise InvalidConfigError(
                    f"surrogate.stage.bandwidth_hz: {self.bandwidth_hz:g} Hz sampled every "
                    f"{control_period_s * 1e3:g} ms gives a loop of spectral radius {rho:.3f} "
                    "(unstable): lower the bandwidth"
                )
        return self

    # -- the loop --------------------------------------------------------------------------
    def gains(self) -> tuple[float, float]:
        """(K_p N/m, K_d N s/m) of the PD: m w^2 and 2 zeta m w less the viscous friction
        (never below 0), w = 2 pi bandwidth_hz."""
        m, w = self.moving_mass_kg(), 2 * math.pi * self.bandwidth_hz
        return m * w * w, max(2 * self.damping_ratio * m * w - self.viscous_N_s_per_m(), 0.0)

    def carriage_matrices(self, time_step_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(A (2, 2), B (2, 1)): the carriage's state [p m, v m/s] one ``time_step_s`` on under a
        force held constant (N), exact: the matrix exponential of the mass-damper."""
        from scipy.linalg import expm

        m, b = self.moving_mass_kg(), self.viscous_N_s_per_m()
        M = np.zeros((3, 3))
        M[0, 1] = 1.0
        M[1, 1] = -b / m
        M[1, 2] = 1.0 / m
        E = expm(M * time_step_s)
        return E[:2, :2], E[:2, 2:]

    def feedback_gain(self) -> np.ndarray:
        """(1, 5) the force's row on [p_d, v_d, a_d, p, v]: feed-forward m a_d + b v_d and the
        PD K_p (p_d - p) + K_d (v_d - v), N."""
        kp, kd = self.gains()
        m, b = self.moving_mass_kg(), self.viscous_N_s_per_m()
        return np.array([[kp, kd + b, m, -kp, -kd]])

    def spectral_radius(self, control_period_s: float) -> float:
        """Largest |eigenvalue| of the sampled loop (the PD held for ``control_period_s``, no
        saturation): below 1 is stable."""
        A, B = self.carriage_matrices(control_period_s)
        K = self.feedback_gain()[:, 3:]
        return float(max(abs(np.linalg.eigvals(A + B @ K))))

    def check_signal(self, t: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
        """Refuse a signal the stage cannot follow, before any run.

        Args:
            t: (n,) s. p, v, a: (n,) the surrogate's position about the stroke's middle [m],
                velocity [m/s] and acceleration [m/s^2].
        Raises:
            InvalidConfigError: beyond the travel, the no-load speed, or the force the motion
                needs (m a + b v) beyond the continuous force: the first time, the value and
                the limit named, with the fields it comes from.
        """
        part = "surrogate.stage.motor and lead_m_per_rev"
        limits = (
            ("travel", np.abs(p), self.travel_m / 2, "m", "surrogate.stage.travel_m / 2"),
            ("speed", np.abs(v), self.no_load_speed_m_s, "m/s", "no-load speed: " + part),
            (
                "force",
                np.abs(self.moving_mass_kg() * a + self.viscous_N_s_per_m() * v),
                self.continuous_force_N,
                "N",
                "continuous force: " + part,
            ),
        )
        for what, value, limit, unit, field in limits:
            over = np.flatnonzero(value > limit * (1 + 1e-9))
            if over.size:
                k = over[0]
                raise InvalidConfigError(
                    f"the surrogate's signal needs a {what} of {value[k]:.4g} {unit} at t = "
                    f"{t[k]:.3f} s, beyond the stage's {limit:.4g} {unit} ({field}): a larger "
                    "stage, or scale the signal"
                )


# -- the stage in a Diagram --------------------------------------------------------------------


@dataclass
class SurrogatePorts:
    """The stage's systems in a Diagram (:func:`add_surrogate_stage`).

    Attributes:
        state: output port (2,) [p m, v m/s], the carriage about the stroke's middle.
        goal: output port (3,) [p_d m, v_d m/s, a_d m/s^2], the goal the controller holds.
        carriage: the carriage's ``LinearSystem`` (its discrete state is [p, v]).
        x0: (2,) where the carriage starts, [m, m/s] (:meth:`initialize`).
        goal_system: the system giving ``goal`` (a ``TrajectorySource``, or with lag
            matching the :class:`~.lag_matched_goal.LagMatchedGoal`).
    """

    state: Any  # OutputPort
    goal: Any  # OutputPort
    carriage: Any  # LinearSystem
    x0: np.ndarray
    goal_system: Any = None

    def initialize(self, root_context) -> None:
        """Start the carriage at its first goal, moving with it."""
        ctx = self.carriage.GetMyMutableContextFromRoot(root_context)
        ctx.SetDiscreteState(self.x0)


def goal_table(
    stage: SurrogateStage, t: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray
) -> np.ndarray:
    """(3, n) the goals [p_d rounded to one count of the servo (``metres_per_count``), v_d,
    a_d] at the sample times ``t``."""
    q = stage.metres_per_count
    p_q = np.round(p / q) * q if q > 0 else np.asarray(p, float)
    return np.vstack([p_q, v, a])


def add_surrogate_stage(
    builder,
    stage: SurrogateStage,
    samples: tuple,
    period_s: float,
    offset_s: float,
    time_step_s: float,
    meshcat=None,
    lag_match=None,
    platform_state=None,
) -> SurrogatePorts:
    """Add the stage and its controller to ``builder`` (module docstring: Drake's systems only;
    with lag matching, the goal from one Python system a period instead of the table).

    Args:
        builder: the ``DiagramBuilder`` of the run.
        stage: the validated :class:`SurrogateStage`.
        samples: (t (n,), p (n,), v (n,), a (n,)) the signal at the controller's sample instants
            [s, m, m/s, m/s^2], checked (:meth:`SurrogateStage.check_signal`).
        period_s: the control period, s (the platform's). offset_s: its sample offset, s.
        time_step_s: the plant's time step, s (the carriage's discrete step).
        meshcat: optional Meshcat: a box drawn at the carriage (:class:`SurrogateBox`).
        lag_match: optional :class:`~.lag_matching.PlatformLagMatch` (its reference sampled at
            ``samples``' times): the goal is then the signal as late as the platform is
            measured to be (:class:`~.lag_matched_goal.LagMatchedGoal`), read from
            ``platform_state`` (an output port (12,): the pose the controller measures).
    Returns:
        :class:`SurrogatePorts`.
    """
    t, p, v, a = (np.asarray(s, float) for s in samples)
    goals = goal_table(stage, t, p, v, a)
    if lag_match is not None:
        from .lag_matched_goal import LagMatchedGoal

        count = stage.metres_per_count
        matched = LagMatchedGoal(lag_match, (t, p, v, a), period_s, offset_s, count)
        goal = builder.AddNamedSystem("surrogate_goal", matched)
        builder.Connect(platform_state, goal.get_input_port())
    else:
        breaks = t.copy()
        breaks[0] = min(breaks[0], 0.0)  # the table holds its first goal from t = 0
        table = PiecewisePolynomial.ZeroOrderHold(breaks, goals)  # type: ignore[call-overload]  # stub shapes
        goal = builder.AddNamedSystem("surrogate_goal", TrajectorySource(table))
    A, B = stage.carriage_matrices(time_step_s)
    carriage = builder.AddNamedSystem(
        "surrogate_carriage", LinearSystem(A, B, np.eye(2), np.zeros((2, 1)), time_step_s)
    )
    mux = builder.AddNamedSystem("surrogate_mux", Multiplexer([3, 2]))
    law = builder.AddNamedSystem("surrogate_pd", MatrixGain(stage.feedback_gain()))
    force = np.array([stage.continuous_force_N])
    sat = builder.AddNamedSystem("surrogate_force_limit", Saturation(-force, force))
    hold = builder.AddNamedSystem("surrogate_hold", ZeroOrderHold(period_s, 1, offset_s))
    builder.Connect(goal.get_output_port(), mux.get_input_port(0))
    builder.Connect(carriage.get_output_port(), mux.get_input_port(1))
    builder.Connect(mux.get_output_port(), law.get_input_port())
    builder.Connect(law.get_output_port(), sat.get_input_port())
    builder.Connect(sat.get_output_port(), hold.get_input_port())
    builder.Connect(hold.get_output_port(), carriage.get_input_port())
    if meshcat is not None:
        box = builder.AddNamedSystem("surrogate_box", SurrogateBox(meshcat, stage))
        builder.Connect(carriage.get_output_port(), box.get_input_port())
    return SurrogatePorts(
        state=carriage.get_output_port(),
        goal=goal.get_output_port(),
        carriage=carriage,
        x0=np.array([goals[0, 0], v[0]]),
        goal_system=goal,
    )


#: Where the stroke's middle is drawn, m in the world: beside the platform, at its height.
BOX_ORIGIN_M = (0.0, 0.3, 0.15)


class SurrogateBox(LeafSystem):
    """The surrogate in Meshcat: a box at the carriage, moving along the world's z (the chest's
    rise) about :data:`BOX_ORIGIN_M`, its stroke drawn as a thin rail; 30 frames a second.

    Input port: ``state`` (2,) [p m, v m/s].
    """

    def __init__(self, meshcat, stage: SurrogateStage, period_s: float = 1 / 30):
        super().__init__()
        self._meshcat = meshcat
        self.DeclareVectorInputPort("state", 2)
        meshcat.SetObject("surrogate/box", Box(0.06, 0.06, 0.03), Rgba(0.9, 0.5, 0.1, 1))
        meshcat.SetObject(
            "surrogate/rail", Box(0.01, 0.01, stage.travel_m), Rgba(0.5, 0.5, 0.5, 0.6)
        )
        self._origin = np.array(BOX_ORIGIN_M)
        self._SetAt("surrogate/rail", 0.0)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._Draw)

    def _SetAt(self, path: str, z: float) -> None:
        self._meshcat.SetTransform(path, RigidTransform(self._origin + [0.0, 0.0, z]))

    def _Draw(self, context) -> None:
        state = np.asarray(self.get_input_port().Eval(context))
        self._SetAt("surrogate/box", float(state[0]))
