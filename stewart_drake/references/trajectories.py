"""Reference trajectories x_d(t) of the platform pose.

A trajectory is any object with ``evaluate(t)`` mapping times t (s) to pose, rate and
acceleration, each ``t.shape + (6,)`` in [rad, rad, rad, m, m, m] (and /s, /s^2).
:func:`as_trajectory` accepts more and adapts it: an ``evaluate`` that takes one time only, a Drake
``Trajectory`` (e.g. a ``PiecewisePolynomial``), a CSV file of ``t, phi, theta, psi, X, Y, Z``
or a registered name. :func:`~stewart_drake.run.plan.validate_reference` checks one before a
run; :mod:`~stewart_drake.run.reference` puts one into a Diagram. What a reference is:
:class:`~.motion.Reference`.

The reference CSV and the spline through samples are in :mod:`~.samples`, the tuner's
data-collection excitation in :mod:`~.data_collection`. A scenario chooses these references by
:class:`NamedReference`, :class:`~.samples.CsvReference`, :class:`SineReference` and
:class:`~.data_collection.DataCollectionReference`, whose field types Drake's YAML loader reads:
this module must not use ``from __future__ import annotations``.
"""

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.trajectories import Trajectory

from ..base.checks import as_array, as_number, as_poses
from ..base.errors import InvalidConfigError
from ..robot.geometry import X_HOME, StewartGeometry
from ..robot.kinematics import AXIS_NAMES
from .motion import Reference, ReferenceConfig
from .samples import load_csv_trajectory


def check_sine_bounds(trajectory) -> None:
    """Refuse a sine whose pose, rate or acceleration would overflow float64.

    Args:
        trajectory: a SineTrajectory (amplitude, frequency_hz, offset: 6 finite floats each).
    Raises:
        InvalidConfigError: |offset| + |A|, |A| 2 pi f or |A| (2 pi f)^2 not finite, naming the
            axis, so that ``evaluate`` is finite at every finite time.
    """
    A, f = np.abs(trajectory.amplitude), np.abs(trajectory.frequency_hz)
    with np.errstate(over="ignore", invalid="ignore"):
        w = 2 * np.pi * f
        peaks = np.stack([np.abs(trajectory.offset) + A, A * w, A * w * w])
    if not np.isfinite(peaks).all():
        axis = int(np.argwhere(~np.isfinite(peaks))[0][1])
        raise InvalidConfigError(
            f"{trajectory.name}: axis {axis} overflows float64 (amplitude "
            f"{A[axis]:.3g}, frequency {f[axis]:.3g} Hz); use SI units"
        )


def _check_offset(trajectory) -> None:
    """Set ``trajectory.offset`` to a tuple of 6 floats, or refuse it (NaN, inf, wrong size,
    a position beyond 1 km) naming the trajectory."""
    offset = as_poses(f"{trajectory.name}: offset", trajectory.offset)
    if offset.shape != (6,):
        raise InvalidConfigError(
            f"{trajectory.name}: offset must be one pose (6,) [phi, theta, "
            f"psi, X, Y, Z], got shape {offset.shape}"
        )
    object.__setattr__(trajectory, "offset", tuple(float(v) for v in offset))


@dataclass(frozen=True)
class SineTrajectory:
    """x_d(t) = offset + amplitude * sin(2 pi f t + phase), axis by axis.

    Attributes:
        amplitude: (6,) in rad and m.  frequency_hz: (6,) in Hz.  phase: (6,) in rad.
        offset: (6,) centre pose (default home).  name: label used in result files.
    """

    amplitude: tuple = (0.0,) * 6
    frequency_hz: tuple = (0.0,) * 6
    phase: tuple = (0.0,) * 6
    offset: tuple = tuple(X_HOME)
    name: str = "sine"

    def __post_init__(self):
        for attr in ("amplitude", "frequency_hz", "phase", "offset"):
            v = as_array(f"{self.name}: {attr}", getattr(self, attr), shape=(6,))
            object.__setattr__(self, attr, tuple(float(c) for c in v))
        check_sine_bounds(self)

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)[..., None]
        A, w = np.asarray(self.amplitude), 2 * np.pi * np.asarray(self.frequency_hz)
        arg = w * t + np.asarray(self.phase)
        s, c = np.sin(arg), np.cos(arg)
        return np.asarray(self.offset) + A * s, A * w * c, -A * w * w * s


def paper_manoeuvre() -> SineTrajectory:
    """Paper eqs. 37-38: phi = (pi/6) sin 2t rad, Z = 0.05 sin 2t + 0.30 m, others 0."""
    f = 2.0 / (2 * np.pi)
    return SineTrajectory(
        amplitude=(np.pi / 6, 0, 0, 0, 0, 0.05), frequency_hz=(f, 0, 0, 0, 0, f), name="paper"
    )


def hold_home() -> SineTrajectory:
    """Stay at the home pose."""
    return SineTrajectory(name="home")


#: Step sizes of :func:`step` by default: 20 mrad for angles, 5 mm for positions.
STEP_SIZE = (0.02, 0.02, 0.02, 0.005, 0.005, 0.005)


def _axis_index(axis) -> int:
    if isinstance(axis, str):
        if axis not in AXIS_NAMES:
            raise InvalidConfigError(f"unknown axis {axis!r}; choose one of {AXIS_NAMES}")
        return AXIS_NAMES.index(axis)
    if not (isinstance(axis, (int, np.integer)) and 0 <= axis < 6):
        raise InvalidConfigError(f"axis must be 0..5 or one of {AXIS_NAMES}, got {axis!r}")
    return int(axis)


@dataclass(frozen=True)
class StepTrajectory:
    """A step of ``size`` on one axis at ``t_step``: x_d = offset + size e_axis H(t - t_step).

    Rate and acceleration are zero (the step is a reference, not a motion plan: its response
    gives the settling time). Attributes: axis 0..5, size in rad or m, t_step in s, offset (6,).
    """

    axis: int = 5
    size: float = 0.005
    t_step: float = 0.5
    offset: tuple = tuple(X_HOME)
    name: str = "step"

    def __post_init__(self):
        object.__setattr__(self, "axis", _axis_index(self.axis))
        object.__setattr__(self, "size", as_number(f"{self.name}: size", self.size))
        object.__setattr__(self, "t_step", as_number(f"{self.name}: t_step", self.t_step, 0.0))
        _check_offset(self)

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)[..., None]
        e = np.zeros(6)
        e[self.axis] = self.size
        x = np.asarray(self.offset) + e * (t >= self.t_step)
        return x, np.zeros_like(x), np.zeros_like(x)


@dataclass(frozen=True)
class ChirpTrajectory:
    """Exponential sine sweep on one axis, for the closed loop's frequency response.

    x_d = offset + A(t) sin(phase(t)) e_axis, instantaneous frequency
    f(t) = f0 (f1/f0)^(t/duration_s) Hz, phase(t) = 2 pi f0 T (k^(t/T) - 1) / ln k, k = f1/f0;
    after ``duration_s`` the sweep holds f1. The envelope A(t) = min(amplitude,
    max_acceleration / (2 pi f(t))^2) is the shaker test's constant-displacement,
    constant-acceleration profile: the full amplitude where the motors can give it, an amplitude
    falling as 1/f^2 above the corner where its acceleration would exceed what they give.

    Attributes: axis, amplitude (rad or m), f0_hz, f1_hz (> f0_hz), duration_s, offset (6,),
    max_acceleration (rad/s^2 or m/s^2; None: the amplitude at every frequency).
    """

    axis: int = 5
    amplitude: float = 2e-4
    f0_hz: float = 1.0
    f1_hz: float = 50.0
    duration_s: float = 8.0
    offset: tuple = tuple(X_HOME)
    name: str = "sweep"
    max_acceleration: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "axis", _axis_index(self.axis))
        for name, lo in (("amplitude", None), ("f0_hz", 0.0), ("f1_hz", 0.0), ("duration_s", 0.0)):
            object.__setattr__(
                self,
                name,
                as_number(f"{self.name}: {name}", getattr(self, name), lo, lo_open=lo is not None),
            )
        if self.max_acceleration is not None:
            object.__setattr__(
                self,
                "max_acceleration",
                as_number(
                    f"{self.name}: max_acceleration", self.max_acceleration, 0.0, lo_open=True
                ),
            )
        if not self.f0_hz < self.f1_hz:
            raise InvalidConfigError(
                f"{self.name}: need f0_hz < f1_hz, got {self.f0_hz}, {self.f1_hz}"
            )
        _check_offset(self)

    def frequency(self, t) -> np.ndarray:
        """Instantaneous frequency f(t) in Hz."""
        t = np.minimum(np.asarray(t, dtype=float), self.duration_s)
        return self.f0_hz * (self.f1_hz / self.f0_hz) ** (t / self.duration_s)

    def phase(self, t) -> np.ndarray:
        """phase(t) in rad (continuous; linear in t after duration_s)."""
        t = np.asarray(t, dtype=float)
        T, k = self.duration_s, self.f1_hz / self.f0_hz
        tc = np.minimum(t, T)
        ph = 2 * np.pi * self.f0_hz * T * (k ** (tc / T) - 1) / np.log(k)
        return ph + 2 * np.pi * self.f1_hz * np.maximum(t - T, 0.0)

    def envelope(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The envelope A(t) and its first two time derivatives (rad or m, per s, per s^2)."""
        t = np.asarray(t, dtype=float)
        A = np.full(t.shape, float(abs(self.amplitude)))
        A_dot, A_ddot = np.zeros(t.shape), np.zeros(t.shape)
        if self.max_acceleration is not None:
            w = 2 * np.pi * self.frequency(t)
            limited = self.max_acceleration / (w * w)
            over = limited < A
            # A = a_max / w^2 with w = w0 k^(t/T): A' = -2 A ln k / T, A'' = (2 ln k / T)^2 A
            # while the sweep runs, constant once it holds f1.
            rate = np.where(
                t < self.duration_s, -2 * np.log(self.f1_hz / self.f0_hz) / self.duration_s, 0.0
            )
            A = np.where(over, limited, A)
            A_dot = np.where(over, rate * limited, 0.0)
            A_ddot = np.where(over, rate * rate * limited, 0.0)
        sign = 1.0 if self.amplitude >= 0 else -1.0
        return sign * A, sign * A_dot, sign * A_ddot

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays (t scalar gives (6,))."""
        t = np.asarray(t, dtype=float)
        ph = self.phase(t)[..., None]
        w = 2 * np.pi * self.frequency(t)[..., None]
        T, k = self.duration_s, self.f1_hz / self.f0_hz
        w_dot = np.where(t[..., None] < T, w * np.log(k) / T, 0.0)
        A, A_dot, A_ddot = (v[..., None] for v in self.envelope(t))
        e = np.zeros(6)
        e[self.axis] = 1.0
        s, c = np.sin(ph), np.cos(ph)
        x = np.asarray(self.offset) + e * A * s
        x_dot = e * (A_dot * s + A * w * c)
        x_ddot = e * (A_ddot * s + 2 * A_dot * w * c + A * (w_dot * c - w * w * s))
        return x, x_dot, x_ddot


def step(axis) -> StepTrajectory:
    """A step of :data:`STEP_SIZE` on ``axis`` (name or index) at t = 0.5 s from home."""
    k = _axis_index(axis)
    return StepTrajectory(axis=k, size=STEP_SIZE[k], name=f"step_{AXIS_NAMES[k]}")


#: Amplitudes of :func:`sweep`: (rad on an angle, m on a position), where the motors follow it.
SWEEP_AMPLITUDE = (2e-3, 2e-4)
#: Accelerations that cap the sweep's amplitude at high frequency (rad/s^2, m/s^2): the largest
#: the motors follow at 50 Hz within the pre-run check's margin (90 % of the peak torque) with a
#: 20 % payload (0.8 mrad and 0.08 mm at 50 Hz); the corner, where the cap takes over, is 31.6 Hz.
SWEEP_MAX_ACCELERATION = (8e-4 * (2 * np.pi * 50.0) ** 2, 8e-5 * (2 * np.pi * 50.0) ** 2)


def sweep(axis="Z") -> ChirpTrajectory:
    """A 1 -> 50 Hz sweep over 8 s on ``axis``, then held at 50 Hz: :data:`SWEEP_AMPLITUDE`
    (0.2 mm on a position, 2 mrad on an angle) up to the corner where its acceleration reaches
    :data:`SWEEP_MAX_ACCELERATION`, then falling as 1/f^2 (0.08 mm, 0.8 mrad at 50 Hz)."""
    k = _axis_index(axis)
    i = 1 if k >= 3 else 0
    return ChirpTrajectory(
        axis=k,
        amplitude=SWEEP_AMPLITUDE[i],
        max_acceleration=SWEEP_MAX_ACCELERATION[i],
        name=f"sweep_{AXIS_NAMES[k]}",
    )


def helix() -> SineTrajectory:
    """Surgical-style path: a 5 mm circle in X-Y at 2 Hz while Z rises and falls 3 mm at
    0.25 Hz, with a 20 mrad wobble of the tool axis (theta) at 1 Hz; well inside the workspace."""
    return SineTrajectory(
        amplitude=(0, 0.02, 0, 0.005, 0.005, 0.003),
        frequency_hz=(0, 1.0, 0, 2.0, 2.0, 0.25),
        phase=(0, 0, 0, np.pi / 2, 0, 0),
        name="helix",
    )


TRAJECTORIES: dict[str, Callable[[], Any]] = {
    "paper": paper_manoeuvre,
    "home": hold_home,
    "helix": helix,
    **{f"step_{a}": functools.partial(step, a) for a in AXIS_NAMES},
    **{f"sweep_{a}": functools.partial(sweep, a) for a in AXIS_NAMES},
}


def make_trajectory(name: str):
    """A trajectory by name: "paper", "home", "helix", "step_<axis>", "sweep_<axis>" with axis
    one of phi, theta, psi, X, Y, Z.

    Raises:
        InvalidConfigError: unknown name (the message lists the known ones).
    """
    try:
        return TRAJECTORIES[name]()
    except KeyError:
        raise InvalidConfigError(
            f"unknown trajectory {name!r}; choose one of {sorted(TRAJECTORIES)}"
        ) from None


class ScalarEvaluate:
    """Adapter for an ``evaluate(t)`` that takes one time at a time: evaluates it per sample.

    Args:
        source: object whose ``evaluate(t: float)`` returns (pose, rate, acceleration), each (6,).
        name: label used in result files (default ``source.name`` or "custom").
    """

    def __init__(self, source, name: str | None = None):
        self.source = source
        self.name: str = name or str(getattr(source, "name", "custom"))

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three ``t.shape + (6,)`` arrays."""
        t = np.asarray(t, dtype=float)
        rows = [self.source.evaluate(float(tk)) for tk in t.reshape(-1)]
        return tuple(
            np.array([np.reshape(r[k], 6) for r in rows], dtype=float).reshape(t.shape + (6,))
            for k in range(3)
        )


class DrakeTrajectory:
    """A Drake ``Trajectory`` of the pose (6 rows, 1 column) as a reference: pose from
    ``value``, rate and acceleration from ``MakeDerivative(1)`` and ``MakeDerivative(2)``.

    Args:
        trajectory: a ``pydrake.trajectories.Trajectory`` with rows() == 6, cols() == 1, twice
            differentiable (e.g. ``PiecewisePolynomial.CubicWithContinuousSecondDerivatives``).
        name: label used in result files.
    Attributes:
        end_time: the trajectory's last time, s; a run may not last longer.
    Raises:
        InvalidConfigError: not a 6 x 1 trajectory.
    """

    def __init__(self, trajectory, name: str = "drake_trajectory"):
        if not isinstance(trajectory, Trajectory) or (trajectory.rows(), trajectory.cols()) != (
            6,
            1,
        ):
            shape = (
                (trajectory.rows(), trajectory.cols())
                if isinstance(trajectory, Trajectory)
                else type(trajectory).__name__
            )
            raise InvalidConfigError(
                f"a Drake reference must be a Trajectory of 6 rows and 1 "
                f"column ([phi, theta, psi, X, Y, Z]), got {shape}"
            )
        self.trajectory = trajectory
        self._derivatives = (trajectory, trajectory.MakeDerivative(1), trajectory.MakeDerivative(2))
        self.start_time, self.end_time = trajectory.start_time(), trajectory.end_time()
        self.name = name

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three ``t.shape + (6,)`` arrays."""
        t = np.asarray(t, dtype=float)
        flat = t.reshape(-1).tolist()
        return tuple(
            np.asarray(d.vector_values(flat)).T.reshape(t.shape + (6,)) for d in self._derivatives
        )


def as_trajectory(source) -> Reference:
    """A reference object with a vectorized ``evaluate`` from whatever the user gives.

    Args:
        source: a registered name (:data:`TRAJECTORIES`), a path to a ``.csv`` file
            (:func:`load_csv_trajectory`), a Drake ``Trajectory`` (:class:`DrakeTrajectory`),
            or an object with ``evaluate(t)``: used as is when it accepts an array of times and
            returns three ``(n, 6)`` arrays, else wrapped in :class:`ScalarEvaluate`.
    Returns:
        an object with ``evaluate(t)`` -> (pose, rate, acceleration), each ``t.shape + (6,)``,
        and a ``name``.
    Raises:
        InvalidConfigError: none of the above, or an ``evaluate`` whose output does not have
            three (6,) parts; MissingFileError: a CSV path that does not exist.
    """
    if isinstance(source, (str, Path)):
        if str(source).lower().endswith(".csv"):
            return load_csv_trajectory(source)
        return make_trajectory(str(source))
    if isinstance(source, Trajectory):
        return DrakeTrajectory(source)
    if not callable(getattr(source, "evaluate", None)):
        raise InvalidConfigError(
            f"a reference must be a name, a .csv path, a Drake Trajectory or "
            f"an object with evaluate(t); got {type(source).__name__}"
        )
    probe = np.array([0.0, 1e-3])
    try:
        out = source.evaluate(probe)
        if len(out) == 3 and all(np.shape(part) == (2, 6) for part in out):
            return source
    except Exception:  # noqa: BLE001 - an evaluate that takes one time only fails here
        pass
    wrapped = ScalarEvaluate(source)
    try:
        wrapped.evaluate(probe)
    except Exception as err:  # noqa: BLE001 - say what is wrong with the user's object
        raise InvalidConfigError(
            f"{type(source).__name__}.evaluate(t) must return (pose, rate, acceleration), each 6 "
            f"numbers [rad, m, /s, /s^2] for one t (or (n, 6) for n times): {err}"
        ) from None
    return wrapped


# -- a scenario's choices of these references ------------------------------------------------------


@dataclass
class NamedReference(ReferenceConfig):
    """A reference of :data:`TRAJECTORIES`: "paper" (eqs. 37-38), "home", "helix",
    "step_<axis>", "sweep_<axis>"."""

    name: str = "paper"

    def validate(self) -> None:
        make_trajectory(self.name)  # unknown name: lists the known ones

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return make_trajectory(self.name)


@dataclass
class SineReference(ReferenceConfig):
    """x_d(t) = offset + amplitude sin(2 pi f t + phase), axis by axis (6 values each: rad, m,
    Hz, rad); see :class:`SineTrajectory`."""

    amplitude: list[float] = field(default_factory=lambda: [0.0] * 6)
    frequency_hz: list[float] = field(default_factory=lambda: [0.0] * 6)
    phase: list[float] = field(default_factory=lambda: [0.0] * 6)
    offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0, 0.0, 0.30])
    name: str = "sine"

    def validate(self) -> None:
        self._sine()  # checks shapes and overflow

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return self._sine()

    def _sine(self) -> SineTrajectory:
        return SineTrajectory(
            amplitude=tuple(self.amplitude),
            frequency_hz=tuple(self.frequency_hz),
            phase=tuple(self.phase),
            offset=tuple(self.offset),
            name=self.name,
        )
