"""The reference a run on the robot follows: a homing lead-in from where the robot rests to the
reference's start, then the reference itself, started and ended at rest (:class:`HomingReference`,
which :func:`~stewart_drake.live.session.run_on_robot` checks whole before anything is powered)."""

import numpy as np

from ..base.errors import InvalidConfigError
from ..references.smoothstep import smooth_ramp

#: Default duration of the homing lead-in, s.
HOME_S = 3.0


class HomingReference:
    """The run's reference on the robot: a homing lead-in from where the robot rests, then the
    reference started and ended at rest.

    - For t in [0, home_s]: each coordinate follows the quintic from ``x_start`` to the
      reference's start x_d(0), at rest at both ends (scipy's ``BPoly.from_derivatives``).
    - Then the reference along its own path, on a warped clock tau(t): tau' (the speed along
      the path) rises from 0 to 1 over ``ramp_s`` by the quintic smoothstep S(u) =
      10 u^3 - 15 u^4 + 6 u^5, is 1 (the reference's own rate) in between, and falls back to 0
      over the last ``ramp_s`` before tau reaches ``t_end``; pose x_d(tau), rate x_d'(tau) tau',
      acceleration x_d''(tau) tau'^2 + x_d'(tau) tau'': continuous everywhere, so a reference
      that starts or ends moving (the paper's manoeuvre starts at phi_dot = 2 pi / 6 rad/s)
      asks no step of rate of the motors. The path is the reference's, every pose of it
      checked as ``check`` checks the reference; the rates are at most the reference's.
    - After it, x_d(t_end) held at rest.

    The warp lasts ``t_end + ramp_s`` s (each ramp lags half of itself): ``duration_s`` is
    the whole run, lead-in included.

    Args:
        reference: an object with ``evaluate(t)`` (``as_trajectory``'s).
        x_start: (6,) pose the robot rests at, rad and m.
        home_s: duration of the lead-in, s (> 0).
        t_end: the reference's time at which it ends, s (> 0).
        ramp_s: duration of each ramp of the warp, s (at most ``t_end``; shortened to it).
    Raises:
        InvalidConfigError: home_s, t_end or ramp_s not > 0.
    """

    def __init__(
        self, reference, x_start, home_s: float = HOME_S, t_end: float = 10.0, ramp_s: float = 1.0
    ):
        from scipy.interpolate import BPoly

        if not (home_s > 0 and t_end > 0 and ramp_s > 0):
            raise InvalidConfigError(
                f"the homing time, the reference's end and the ramp must be > 0 s, got "
                f"{home_s}, {t_end}, {ramp_s}"
            )
        self.reference, self.home_s, self.t_end = reference, float(home_s), float(t_end)
        self.ramp_s = min(float(ramp_s), self.t_end)
        #: The run's length, s: the lead-in, then the reference on its warped clock.
        self.duration_s = self.home_s + self.t_end + self.ramp_s
        self.name = f"{getattr(reference, 'name', 'reference')}_homed"
        x0 = np.asarray(reference.evaluate(0.0)[0], dtype=float).reshape(6)
        x_start = np.asarray(x_start, dtype=float).reshape(6)
        self._lead = [
            BPoly.from_derivatives([0.0, self.home_s], [[x_start[i], 0, 0], [x0[i], 0, 0]])
            for i in range(6)
        ]

    def _warp(self, s):
        """(tau, tau', tau'') at s s after the lead-in (s >= 0)."""
        R, T = self.ramp_s, self.t_end + self.ramp_s

        def up(s):  # the rising ramp, s in [0, R]: tau = R * integral of S
            tau, S, dS = smooth_ramp(s / R, scale=R)
            return tau, S, dS / R

        tau, d1, d2 = s - R / 2, np.ones_like(s), np.zeros_like(s)
        rising, falling = s < R, s > T - R
        if np.any(rising):
            tau[rising], d1[rising], d2[rising] = up(s[rising])
        if np.any(falling):
            tau_f, d1_f, d2_f = up(np.clip(T - s[falling], 0.0, R))
            tau[falling], d1[falling], d2[falling] = self.t_end - tau_f, d1_f, -d2_f
        return tau, d1, d2

    def reference_time(self, t) -> np.ndarray:
        """The time on the reference's own clock (tau, a planned path's ``t [s]``) at run
        times t (s, any shape); NaN during the lead-in."""
        t = np.asarray(t, dtype=float)
        tau = np.full(t.shape, np.nan)
        rest = t >= self.home_s
        tau[rest] = self._warp(t[rest] - self.home_s)[0]
        return tau

    def evaluate(self, t):
        t = np.asarray(t, dtype=float)
        shape = t.shape
        flat = t.reshape(-1)
        out = [np.zeros((flat.size, 6)) for _ in range(3)]
        lead = flat < self.home_s
        if np.any(lead):
            s = np.clip(flat[lead], 0.0, None)
            for i, poly in enumerate(self._lead):
                for k in range(3):
                    out[k][lead, i] = poly(s, k)
        rest = ~lead
        if np.any(rest):
            tau, d1, d2 = self._warp(flat[rest] - self.home_s)
            x, v, a = (
                np.asarray(p, dtype=float).reshape(-1, 6) for p in self.reference.evaluate(tau)
            )
            out[0][rest] = x
            out[1][rest] = v * d1[:, None]
            out[2][rest] = a * (d1 * d1)[:, None] + v * d2[:, None]
        return tuple(o.reshape(shape + (6,)) for o in out)


__all__ = ["HOME_S", "HomingReference"]
