"""Lag matching: the surrogate's command delayed by the platform's own lag behind its reference,
estimated each control period from the crank encoders, so that the internal target and the
external surrogate move on one clock.

Why. On the servo bus (a 10 ms period) the platform follows its reference some milliseconds
late, by an amount its controller, its friction and the motion decide (+26, +12 and -2 ms on
three of IntERAct's LIGHT SABR traces with the shipped controller; docs/robot.md), while the
surrogate's stage, a light carriage on one servo, follows its own within 0.2 ms. What a motion
management system sees is the two motions' **relative** timing: a phantom whose internal target
is 26 ms late on its external surrogate presents a 26 ms phase error the patient never had.
Delaying the carriage's command by the platform's lag makes the pair move as recorded, whatever
the platform's controller. (IntERAct synchronises its two robots by their start only.)

The estimate. Let y(t) be the platform's translation measured along its reference's principal
direction (:func:`~stewart_drake.base.signals.principal_direction`) and c(t) the reference's,
so that y(t) ~ c(t - L) + b (a lag L and an offset b). Linearised about the estimate L_k in
use at period k,

    r_k = y_k - c(t_k - L_k) ~ -(L - L_k) g_k + b,   g_k = c'(t_k - L_k),

so u_k = r_k - L_k g_k ~ -L g_k + b: a straight line in g whose slope is -L whatever L_k was. The
slope is the exponentially weighted least-squares fit over the last ``memory_s`` (a time constant
longer than a breathing cycle; the offset is the line's intercept); it is what the RMSE alignment of
the relative latency (:func:`stewart_drake.base.pair_figures.relative_latency`) minimises, to first
order in L - L_k. The delay in use moves towards it by at most ``max_rate`` s per s (0.5 %: the
carriage's speed changes by at most that), stays within +-``max_delay_s``, and holds until the fit
has seen :data:`MIN_HISTORY_S` of readings and a reference moving at ``min_speed_m_s`` RMS.

Nothing here is fitted to the verdict: the delay acts on the carriage's command as the run goes,
from the encoders' past readings; the relative latency judged at the end compares each motion
with its own reference (the carriage's before any delay), so a matching that did not match is
seen there.
"""

import math

import numpy as np

from ...base.errors import InvalidConfigError

#: The fit's time constant, s (longer than a breathing cycle).
MEMORY_S = 6.0
#: The fastest the delay in use changes, s per s (the carriage's speed changes by at most this).
MAX_RATE = 0.005
#: The largest delay applied either way, s (IntERAct's claimed synchronisation is 0.1 s).
MAX_DELAY_S = 0.2
#: The reference's RMS speed along its axis below which the fit holds the delay, m/s.
MIN_SPEED_M_S = 2e-4
#: The fewest seconds of readings the fit holds before it moves the delay (a quarter of a
#: breath: a line fitted to less cannot tell a lag from an offset).
MIN_HISTORY_S = 1.0


class PlatformLagMatch:
    """The platform's lag behind its reference, estimated each period (module docstring), as the
    delay to give the surrogate's command.

    Its whole state is one (6,) vector (the fit's five weighted sums and the delay in use),
    :attr:`state`, advanced by :meth:`step`: a Drake system holds it in its context
    (:class:`~stewart_drake.station.surrogate.lag_matched_goal.LagMatchedGoal`).

    Args:
        period_s: the control period, s (the reference's samples' step).
        reference: (n,) the platform's reference along ``axis`` at t0, t0 + h, t0 + 2h, ... s, m.
        reference_rate: (n,) its rate there, m/s.
        axis: a pose coordinate (3, 4 or 5: X, Y, Z), or a (3,) unit direction of the
            translation (the principal direction of its motion): the platform's coordinate is
            its translation along it.
        memory_s, max_rate, max_delay_s, min_speed_m_s: the module's constants by default.
        t0: the time of the reference's first sample, s.
    Attributes:
        state: (6,) [weight, sum g, sum u, sum g^2, sum g u, the delay in use s].
        estimate_s: the fit's lag at the last :meth:`update`, s (NaN until the reference has
            moved enough).
    Raises:
        InvalidConfigError: tables not (n,) alike or not finite, an axis not a translation
            nor a unit direction,
            a setting out of range.
    """

    def __init__(
        self,
        period_s: float,
        reference,
        reference_rate,
        axis,
        memory_s: float = MEMORY_S,
        max_rate: float = MAX_RATE,
        max_delay_s: float = MAX_DELAY_S,
        min_speed_m_s: float = MIN_SPEED_M_S,
        t0: float = 0.0,
    ):
        c, g = np.asarray(reference, dtype=float), np.asarray(reference_rate, dtype=float)
        if c.ndim != 1 or c.shape != g.shape or c.size < 2:
            raise InvalidConfigError(
                f"the reference and its rate must be (n,) alike with n >= 2, got {c.shape} "
                f"and {g.shape}"
            )
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(g))):
            raise InvalidConfigError("the platform's reference for lag matching is not finite")
        direction = _direction(axis)
        for name, value in (("period_s", period_s), ("memory_s", memory_s)):
            if not 0 < value < math.inf:
                raise InvalidConfigError(f"{name} must be > 0 s, got {value}")
        if not (0 <= max_rate < 1 and 0 <= max_delay_s < math.inf and min_speed_m_s > 0):
            raise InvalidConfigError(
                f"lag matching's limits out of range: max_rate {max_rate} (0..1), max_delay_s "
                f"{max_delay_s} (>= 0), min_speed_m_s {min_speed_m_s} (> 0)"
            )
        if not math.isfinite(t0):
            raise InvalidConfigError(f"t0 must be finite, got {t0}")
        self.period_s, self.direction, self.t0 = float(period_s), direction, float(t0)
        self._c, self._g, self._last = c, g, c.size - 1
        self._forget = math.exp(-self.period_s / memory_s)
        n = max(1, round(MIN_HISTORY_S / self.period_s))
        #: The fit's weight after MIN_HISTORY_S of readings (its weights' sum).
        self._min_weight = (1 - self._forget**n) / (1 - self._forget) - 1e-9
        self._step = max_rate * self.period_s
        self.max_delay_s, self._min_var = float(max_delay_s), float(min_speed_m_s) ** 2
        self.estimate_s = math.nan
        self.state = np.zeros(6)

    @property
    def delay_s(self) -> float:
        """The delay in use, s (> 0: the platform is late, the carriage's command delayed)."""
        return float(self.state[5])

    def _at(self, t: float) -> tuple[float, float]:
        """(c, c') at run time ``t`` (linear between samples; the ends held)."""
        x = (t - self.t0) / self.period_s
        k = min(max(int(math.floor(x)), 0), self._last)
        w = min(max(x - k, 0.0), 1.0) if k < self._last else 0.0
        c, g = self._c, self._g
        k1 = min(k + 1, self._last)
        return c[k] + w * (c[k1] - c[k]), g[k] + w * (g[k1] - g[k])

    def update(self, t: float, pose) -> float:
        """Take the platform's pose measured for run time ``t`` (s; (6,) rad and m) into
        :attr:`state` and return the delay to use from now on, s."""
        self.estimate_s = self.step(self.state, t, self.coordinate(pose))
        return self.delay_s

    def coordinate(self, pose) -> float:
        """The platform's coordinate the lag is measured on, m, from a pose ((6,) or more:
        rad and m, the translation in 3..5)."""
        p = np.asarray(pose, dtype=float)[3:6]
        return float(p @ self.direction)

    def step(self, state: np.ndarray, t: float, y: float) -> float:
        """Advance ``state`` ((6,), as :attr:`state`; in place) by the platform's coordinate
        ``y`` (m) measured for run time ``t`` (s). Returns the fit's lag, s (NaN: the
        reference has not moved enough yet, or ``y`` is NaN: nothing learnt)."""
        if y != y:  # a reading with no pose: nothing learnt
            return math.nan
        d = float(state[5])
        c, g = self._at(t - d)
        u = (y - c) - d * g
        lam = self._forget
        state[0] = lam * state[0] + 1.0
        state[1] = lam * state[1] + g
        state[2] = lam * state[2] + u
        state[3] = lam * state[3] + g * g
        state[4] = lam * state[4] + g * u
        if state[0] < self._min_weight:
            return math.nan
        mean_g = state[1] / state[0]
        var_g = state[3] / state[0] - mean_g * mean_g
        if var_g < self._min_var:
            return math.nan
        estimate = -(state[4] / state[0] - mean_g * state[2] / state[0]) / var_g
        target = min(max(estimate, -self.max_delay_s), self.max_delay_s)
        state[5] = d + min(max(target - d, -self._step), self._step)
        return float(estimate)


def _direction(axis) -> np.ndarray:
    """(3,) the unit direction of ``axis``: a pose coordinate 3..5, or a (3,) unit vector.

    Raises:
        InvalidConfigError: neither.
    """
    if isinstance(axis, (int, np.integer)) and not isinstance(axis, bool):
        if axis not in (3, 4, 5):
            raise InvalidConfigError(f"the matched axis must be a translation (3..5), got {axis}")
        return np.eye(3)[int(axis) - 3]
    u = np.asarray(axis, dtype=float)
    if u.shape != (3,) or not np.all(np.isfinite(u)) or abs(np.linalg.norm(u) - 1) > 1e-6:
        raise InvalidConfigError(
            f"the matched axis must be a translation (3..5) or a (3,) unit direction, got {axis}"
        )
    return u
