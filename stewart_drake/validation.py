"""Checks of user input, shared by every public entry point: typed errors, never NaN out.

The rule (issue 8): a public function given a NaN, an inf, a wrong shape or a non-number raises a
:class:`~stewart_drake.errors.StewartError` that names the argument and says what to change; it
never returns NaN and never lets numpy's own ``ValueError``/``TypeError`` escape. The checks are
one ``np.isfinite(...).all()`` per array, so vectorized paths stay fast.

:func:`check_config` validates a :class:`~stewart_drake.diagram.StewartConfig` beyond its own
``__post_init__``: types, the periods against the plant step, the trajectory name, the tuner
weights file and the guard settings (:class:`~stewart_drake.guard.GuardConfig`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InvalidConfigError, MissingFileError

#: Largest |position| accepted in a pose, m: a kilometre is far outside any Stewart platform and
#: keeps squared lengths (|l|^2 in the closed-form IK) far from overflow.
MAX_POSITION_M = 1e3


def as_array(name: str, value, shape: tuple | None = None, last: int | None = None,
             error=InvalidConfigError) -> np.ndarray:
    """``value`` as a finite float64 array, or a typed error naming ``name``.

    Args:
        name: what the caller calls the argument (used in the message).
        value: anything ``np.asarray(value, dtype=float)`` accepts.
        shape: exact shape required, or None.
        last: size of the last axis required (batches ``(..., last)``), or None.
        error: the :class:`~stewart_drake.errors.StewartError` subclass to raise.
    Returns:
        the array (a view when ``value`` already is a float64 array).
    Raises:
        error: not numbers, a wrong shape, or a NaN/inf (first bad index named).
    """
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise error(f"{name} must be numbers, got {value!r:.80} ({err})") from None
    if shape is not None and a.shape != tuple(shape):
        raise error(f"{name} must have shape {tuple(shape)}, got {a.shape}")
    if last is not None and (a.ndim < 1 or a.shape[-1] != last):
        raise error(f"{name} must have shape (..., {last}), got {a.shape}")
    if not np.isfinite(a).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise error(f"{name} has a non-finite value {a[bad] if bad else a} at index {bad}; "
                    f"give finite numbers")
    return a


def as_poses(name: str, x) -> np.ndarray:
    """Poses (6,) or (..., 6) [phi, theta, psi, X, Y, Z] in rad and m, finite, |X|,|Y|,|Z| <= 1 km.

    Raises:
        InvalidConfigError: not (..., 6), non-finite, or a position beyond MAX_POSITION_M.
    """
    a = as_array(name, x, last=6)
    if a.size and np.abs(a[..., 3:]).max() > MAX_POSITION_M:
        raise InvalidConfigError(f"{name} has a position beyond {MAX_POSITION_M:g} m "
                                 f"(max |X|, |Y|, |Z| = {np.abs(a[..., 3:]).max():.3g} m); "
                                 f"poses are in m, not mm")
    return a


def as_number(name: str, value, lo: float | None = None, hi: float | None = None,
              lo_open: bool = False, error=InvalidConfigError) -> float:
    """``value`` as a finite float in [lo, hi] ((lo, hi] with ``lo_open``), or a typed error.

    Raises:
        error: not a real number (bool is refused too), not finite, or out of range.
    """
    if isinstance(value, (bool, np.bool_)) or not np.isscalar(value) and np.ndim(value) != 0:
        raise error(f"{name} must be one number, got {value!r:.80}")
    if isinstance(value, (str, bytes)):
        raise error(f"{name} must be a number, got {value!r:.80} (a string)")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise error(f"{name} must be a number, got {value!r:.80}") from None
    below = lo is not None and (v <= lo if lo_open else v < lo)
    if not np.isfinite(v) or below or (hi is not None and v > hi):
        lo_text = "-inf" if lo is None else f"{lo:g}"
        hi_text = "inf" if hi is None else f"{hi:g}"
        raise error(f"{name} must be a finite number in {'(' if lo_open else '['}{lo_text}, "
                    f"{hi_text}], got {value!r:.80}")
    return v


def check_multiple(name: str, period_s: float, base_name: str, base_s: float) -> int:
    """How many ``base_s`` steps make ``period_s``; a typed error if it is not a whole number.

    Returns:
        the integer ratio, >= 1.
    Raises:
        InvalidConfigError: the period is not a whole multiple of the base (1e-6 relative slack),
            with the nearest valid value in the message.
    """
    ratio = period_s / base_s
    n = int(round(ratio)) if 0 < ratio < 1e12 else 0       # 1e12 steps: far past any run
    if n < 1 or abs(ratio - n) > 1e-6 * max(1.0, ratio):
        nearest = max(n, 1) * base_s
        raise InvalidConfigError(f"{name} ({period_s:g} s) must be a whole multiple of {base_name} "
                                 f"({base_s:g} s); the nearest valid value is {nearest:g} s")
    return n


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
        raise InvalidConfigError(f"{trajectory.name}: axis {axis} overflows float64 (amplitude "
                                 f"{A[axis]:.3g}, frequency {f[axis]:.3g} Hz); use SI units")


def check_config(config) -> None:
    """Validate a StewartConfig before anything is built or simulated.

    Checks (each raising :class:`InvalidConfigError` that names the field):
        - every period and the duration are finite numbers > 0 (also refuses strings, bools);
        - control_period_s is a whole multiple of plant_time_step_s, schedule_period_s and
          tuner_period_s of control_period_s (the controller and the tuner run on its clock),
          log_period_s and the guard's check_period_s of plant_time_step_s (a log between plant
          steps would compare a held state with a later reference);
        - omega_Q, omega_R in [1e-3, 1e3]; feedforward, tuner names; feature_window >= 1;
        - a trajectory name that exists, or an object with ``evaluate``;
        - tuner_weights, when given, names an existing file (:class:`MissingFileError`);
        - the guard settings (:class:`~stewart_drake.guard.GuardConfig`).
    """
    from .controller import OMEGA_MAX, OMEGA_MIN
    from .guard import GuardConfig

    for name in ("duration_s", "plant_time_step_s", "control_period_s", "schedule_period_s",
                 "tuner_period_s", "log_period_s"):
        as_number(name, getattr(config, name), lo=0.0, lo_open=True)
    for name in ("omega_Q", "omega_R"):
        as_number(name, getattr(config, name), OMEGA_MIN, OMEGA_MAX)
    h = config.plant_time_step_s
    check_multiple("control_period_s", config.control_period_s, "plant_time_step_s", h)
    check_multiple("schedule_period_s", config.schedule_period_s, "control_period_s",
                   config.control_period_s)
    if config.tuner is not None:
        check_multiple("tuner_period_s", config.tuner_period_s, "control_period_s",
                       config.control_period_s)
    check_multiple("log_period_s", config.log_period_s, "plant_time_step_s", h)
    from .diagram import CONTROLLERS
    from .reference import FEEDFORWARD_MODES

    if config.feedforward not in FEEDFORWARD_MODES:
        raise InvalidConfigError(f"feedforward must be 'gravity', 'inverse_dynamics' or 'none', "
                                 f"got {config.feedforward!r}")
    if config.tuner not in (None, "ann"):
        raise InvalidConfigError(f"tuner must be None or 'ann', got {config.tuner!r}")
    if config.controller not in CONTROLLERS:
        raise InvalidConfigError(f"controller must be 'lqi' or 'pd', got {config.controller!r}")
    if config.tuner and config.controller != "lqi":
        raise InvalidConfigError("the ANN tuner drives the LQI's weights: use controller='lqi' "
                                 "with tuner='ann'")
    if config.riccati not in ("warm", "cold"):
        raise InvalidConfigError(f"riccati must be 'warm' or 'cold', got {config.riccati!r}")
    as_number("pd_bandwidth_hz", config.pd_bandwidth_hz, lo=0.0, lo_open=True)
    as_number("payload_scale", config.payload_scale, 0.1, 10.0)
    if config.torque_limit_Nm is not None:
        as_number("torque_limit_Nm", config.torque_limit_Nm, lo=0.0, lo_open=True)
    if config.sensor_noise_std is not None:
        try:
            std = np.broadcast_to(np.asarray(config.sensor_noise_std, dtype=float), (12,))
        except (TypeError, ValueError):
            std = np.array([np.nan])
        if not (np.all(np.isfinite(std)) and np.all(std >= 0)):
            raise InvalidConfigError(f"sensor_noise_std needs 12 finite values >= 0 (rad, m, "
                                     f"rad/s, m/s), got {config.sensor_noise_std}")
    seed = config.noise_seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidConfigError(f"noise_seed must be an integer >= 0, got {seed!r}")
    window = config.feature_window
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise InvalidConfigError(f"feature_window must be an integer >= 1, got {window!r}")
    if isinstance(config.trajectory, str):
        from .trajectories import make_trajectory

        make_trajectory(config.trajectory)          # unknown name: lists the known ones
    elif not callable(getattr(config.trajectory, "evaluate", None)):
        raise InvalidConfigError(f"trajectory must be a name or an object with evaluate(t), got "
                                 f"{type(config.trajectory).__name__}")
    if config.tuner_weights is not None and not Path(config.tuner_weights).is_file():
        raise MissingFileError(f"no ANN tuner weights at {config.tuner_weights}: check the path, "
                               f"or leave tuner_weights unset for the shipped weights")
    guard = getattr(config, "guard", None)
    if guard is not None:
        if not isinstance(guard, GuardConfig):
            raise InvalidConfigError(f"guard must be a GuardConfig, got {type(guard).__name__}")
        check_multiple("guard.check_period_s", guard.check_period_s, "plant_time_step_s", h)
