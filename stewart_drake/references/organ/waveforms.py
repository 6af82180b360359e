"""The motion phantoms' periodic waveforms with rounded corners: :class:`Sawtooth` and
:class:`Sharkfin`.

The waveforms of the commercial motion phantoms (CIRS Motion Control for the Dynamic Thorax,
Dynamic Pelvis and Dynamic Platform: sin, cos^4, cos^6, sawtooth, sharkfin) have corners, which a
reference with rate and acceleration feed-forward cannot have: every corner here is a C2 blend of
the two sides over a stated time (:func:`~.smoothstep.smoothstep`).
"""

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.geometry import X_HOME
from ..smoothstep import smoothstep
from .core import LibraryMotion, along, check_centre, unit_direction

#: Gauss-Legendre nodes and weights on [-1, 1] of :func:`_round_corner`'s integral (16 nodes
#: integrate its smooth integrand to round-off over a corner's few tenths of a second).
_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)


def _round_corner(t, corner: float, width: float, first, second):
    """(y, y', y'') at times ``t`` within ``width`` s centred on ``corner``, where the branch
    ``first`` hands over to ``second`` (each a function of time to (y, y', y''), meeting at the
    corner), the corner rounded by blending the branches' *rates*:
    y' = (1 - S) first' + S second', S = :func:`smoothstep` across the window, integrated from
    the window's start (Gauss-Legendre), plus delta S, where delta (zero for straight branches)
    makes y meet ``second`` at the window's end. At both ends y, y' and y'' are those of the
    branch there: C2. Blending rates rather than positions cuts the corner on its inside (for
    straight branches exactly; curved ones add delta S, 0.8 % of the stroke at the shark fin's
    base with its defaults): the rounded path does not pass beyond the corner, and between two
    branches moving the same way it does not turn back (blending positions would overshoot, a
    hook at the shark fin's base)."""
    a = corner - 0.5 * width
    f, g = first(t), second(t)
    S, dS, ddS = smoothstep((t - a) / width)
    dS, ddS = dS / width, ddS / width**2

    def integral(upper):
        half = 0.5 * (upper - a)
        u = a + half[:, None] * (1.0 + _GAUSS_NODES)
        gap = second(u)[1] - first(u)[1]
        return half * ((smoothstep((u - a) / width)[0] * gap) @ _GAUSS_WEIGHTS)

    end = np.array([a + width])
    delta = float((second(end)[0] - first(end)[0] - integral(end))[0])
    gap, dgap = g[1] - f[1], g[2] - f[2]
    return (
        f[0] + integral(t) + delta * S,
        f[1] + S * gap + delta * dS,
        f[2] + S * dgap + dS * gap + delta * ddS,
    )


def _rounded_cycle(tau, period: float, t_in: float, rounding: float, inhale, exhale):
    """(y, y', y'') of a cycle made of an inhale branch on [0, t_in] and an exhale branch on
    [t_in, period] at times ``tau`` in [0, period), s, its two corners (at t_in, and at 0 =
    period) rounded by :func:`_round_corner` over ``rounding`` s centred on each. ``inhale`` and
    ``exhale`` give (y, y', y'') at any time (each is extended past its side)."""
    h = 0.5 * rounding
    out = [np.where(tau < t_in, a, b) for a, b in zip(inhale(tau), exhale(tau))]
    tip = np.abs(tau - t_in) < h
    if tip.any():
        rounded = _round_corner(tau[tip], t_in, rounding, inhale, exhale)
        for y, b in zip(out, rounded):
            y[tip] = b
    base = (tau < h) | (tau > period - h)
    if base.any():
        s = np.where(tau < h, tau, tau - period)[base]  # in [-h, h)
        rounded = _round_corner(s, 0.0, rounding, lambda u: exhale(u + period), inhale)
        for y, b in zip(out, rounded):
            y[base] = b
    return tuple(out)


class _Waveform(LibraryMotion):
    """A periodic waveform of the phantoms' library from its cycle's two branches
    (:meth:`_branches`) with rounded corners: the displacement is b (1/2 - u(t)) along
    ``direction``, u the rounded cycle scaled to [0, 1], from +b/2 at end-exhale to -b/2 at
    end-inhale about the centre as :class:`~.breathing.Breathing`'s; cycles start at t = k
    period, in the middle of the rounded corner between exhale and inhale."""

    if TYPE_CHECKING:  # set by _check_waveform, not fields
        amplitude_m: float
        period_s: float
        inhale_fraction: float
        rounding_s: float
        direction: tuple | str
        _range: tuple

    def _check_waveform(self) -> None:
        _set = object.__setattr__
        _set(self, "amplitude_m", as_number(f"{self.name}: amplitude_m", self.amplitude_m, 0.0))
        _set(self, "period_s", as_number(f"{self.name}: period_s", self.period_s, 0.05, 3600.0))
        _set(
            self,
            "inhale_fraction",
            as_number(f"{self.name}: inhale_fraction", self.inhale_fraction, 0.05, 0.95),
        )
        shortest = self.period_s * min(self.inhale_fraction, 1.0 - self.inhale_fraction)
        rounding = as_number(f"{self.name}: rounding_s", self.rounding_s, 0.0, lo_open=True)
        if rounding > shortest:
            raise InvalidConfigError(
                f"{self.name}: rounding_s must be at most the shorter of inhale and exhale "
                f"({shortest:.4g} s) so the rounded corners do not overlap, got {rounding:g}"
            )
        _set(self, "rounding_s", rounding)
        _set(self, "direction", unit_direction(f"{self.name}: direction", self.direction))
        _set(self, "centre", check_centre(self.name, self.centre))

    def _set_range(self) -> None:
        """The rounded cycle's lowest value and peak to peak (u is scaled by them)."""
        y = self._raw(np.linspace(0.0, self.period_s, 20001))[0]
        object.__setattr__(self, "_range", (float(y.min()), float(np.ptp(y))))

    def _branches(self):  # pragma: no cover - every waveform defines it
        """(inhale, exhale): functions of the time in the cycle, s, to (y, y', y'')."""
        raise NotImplementedError

    def _raw(self, t):
        tau = np.mod(np.asarray(t, dtype=float), self.period_s)
        t_in = self.inhale_fraction * self.period_s
        return _rounded_cycle(tau, self.period_s, t_in, self.rounding_s, *self._branches())

    def shape(self, t):
        """(s, ds/dt, d2s/dt2) of s(t) = 1/2 - u(t), dimensionless: +1/2 at end-exhale, -1/2 at
        end-inhale."""
        low, span = self._range
        y, dy, ddy = self._raw(t)
        return 0.5 - (y - low) / span, -dy / span, -ddy / span

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        s, ds, dds = self.shape(t)
        return along(np.asarray(self.direction) * self.amplitude_m, s, ds, dds)

    def frequencies_hz(self) -> dict:
        return {"breathing": 1.0 / self.period_s}


@dataclass(frozen=True)
class Sawtooth(_Waveform):
    """A sawtooth: breathing in and out at two constant speeds, its corners rounded (C2).

    The raw cycle is the phantoms' sawtooth (CIRS Motion Control's library for the Dynamic
    Thorax phantom, model 008A): a straight ramp from end-exhale to end-inhale over
    ``inhale_fraction`` of the period and a straight return. Its two corners would need an
    infinite acceleration: over ``rounding_s`` centred on each, the speed passes from one ramp's to
    the other's along a quintic smoothstep (:func:`_round_corner`; ours, the paper and the
    phantom's manual are silent). The rounded path runs inside the sharp one, at most 5/64
    rounding_s times the change of speed from it (at the corner), and its extremes fall short of
    the corners' by 1.6 % of the stroke each with the defaults;
    the cycle is then rescaled so that ``amplitude_m`` is the peak to peak of the motion.

    Attributes:
        amplitude_m: peak to peak, m; default 0.015 (as :class:`~.breathing.Breathing`).
        period_s: s; default 4 (as :class:`~.breathing.Breathing`).
        inhale_fraction: the ramp's share of the period, in [0.05, 0.95]; default 0.3 (ours: a
            quick inhale and a slow exhale, I:E near 1:2 as in quiet breathing).
        rounding_s: length of each rounded corner, s, in (0, the shorter ramp]; default 0.2
            (ours: the peak acceleration is 1.875 / rounding_s times the change of speed, 0.17
            m/s^2 with the defaults; on ``paper_hardware`` the motors' peak torque is then
            0.37 N m of their 0.63 N m limit).
        direction: unit vector or axis name; default "SI".
        centre: (6,) the pose the motion is centred on (mid-range), rad and m; default home.
    Continuity: C2 (the smoothstep's S' and S'' vanish where the rounding meets the ramps).
    Raises:
        InvalidConfigError: a value out of range, a rounding longer than a ramp (named).
    """

    amplitude_m: float = 0.015
    period_s: float = 4.0
    inhale_fraction: float = 0.3
    rounding_s: float = 0.2
    direction: tuple | str = "SI"
    centre: tuple = tuple(X_HOME)
    name: str = "sawtooth"

    def __post_init__(self):
        self._check_waveform()
        self._set_range()

    def _branches(self):
        T, t_in = self.period_s, self.inhale_fraction * self.period_s

        def inhale(tau):
            return tau / t_in, np.full_like(tau, 1.0 / t_in), np.zeros_like(tau)

        def exhale(tau):
            return (T - tau) / (T - t_in), np.full_like(tau, -1.0 / (T - t_in)), np.zeros_like(tau)

        return inhale, exhale


@dataclass(frozen=True)
class Sharkfin(_Waveform):
    """A shark fin: a fast inhale that slows into end-inhale, then a slow exponential exhale,
    its corners rounded (C2).

    The "shark fin" of the phantoms' libraries (CIRS Motion Control for the Dynamic Thorax
    phantom; the QUASAR respiratory motion phantom): the inhale rises as (1 - exp(-t /
    inhale_tau_s)) over ``inhale_fraction`` of the period, the exhale falls as exp(-t /
    exhale_tau_s) back to end-exhale (each scaled to meet the other at its ends). Over
    ``rounding_s`` centred on the tip and on the base the speed passes from one branch's to the
    other's along a quintic smoothstep (:func:`_round_corner`), and the cycle is rescaled so
    that ``amplitude_m`` is the peak to peak. The branches and the rounding are ours (the
    manuals give no formula; the defaults' reasons and figures: docs/paper_notes.md, "The
    motion phantoms' library: rounded corners").

    Attributes:
        amplitude_m: peak to peak, m; default 0.015 (as :class:`~.breathing.Breathing`).
        period_s: s; default 4 (as :class:`~.breathing.Breathing`).
        inhale_fraction: the inhale's share of the period, in [0.05, 0.95]; default 0.3.
        inhale_tau_s: time constant of the inhale, s; default 0.3.
        exhale_tau_s: time constant of the exhale, s; default 0.7.
        rounding_s: length of each rounded corner, s, in (0, the shorter branch]; default 0.2.
        direction: unit vector or axis name; default "SI".
        centre: (6,) the pose the motion is centred on (mid-range), rad and m; default home.
    Continuity: C2 (the branches are smooth; the smoothstep's S' and S'' vanish where the
        rounding meets them).
    Raises:
        InvalidConfigError: a value out of range, a rounding longer than a branch (named).
    """

    amplitude_m: float = 0.015
    period_s: float = 4.0
    inhale_fraction: float = 0.3
    inhale_tau_s: float = 0.3
    exhale_tau_s: float = 0.7
    rounding_s: float = 0.2
    direction: tuple | str = "SI"
    centre: tuple = tuple(X_HOME)
    name: str = "sharkfin"

    def __post_init__(self):
        self._check_waveform()
        for f in ("inhale_tau_s", "exhale_tau_s"):
            lo, hi = 0.01 * self.period_s, 1e3 * self.period_s
            object.__setattr__(self, f, as_number(f"{self.name}: {f}", getattr(self, f), lo, hi))
        self._set_range()

    def _branches(self):
        T, t_in = self.period_s, self.inhale_fraction * self.period_s
        a, c = self.inhale_tau_s, self.exhale_tau_s
        rise = -math.expm1(-t_in / a)  # 1 - exp(-t_in / a)
        fall = math.exp(-(T - t_in) / c)

        def inhale(tau):
            e = np.exp(-tau / a) / rise
            return (1.0 / rise) - e, e / a, -e / (a * a)

        def exhale(tau):
            e = np.exp(-(tau - t_in) / c) / (1.0 - fall)
            return e - fall / (1.0 - fall), -e / c, e / (c * c)

        return inhale, exhale


__all__ = ["Sawtooth", "Sharkfin"]
