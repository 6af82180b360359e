"""Breathing: Lujan et al.'s model (:class:`Breathing`) and the motions built on its breath,
irregular from cycle to cycle (:class:`IrregularBreathing`), with different inhale and exhale
paths (:class:`HysteresisBreathing`) and paused at a phase (:class:`BreathHold`).
"""

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.geometry import X_HOME
from ..smoothstep import smooth_ramp
from .core import LibraryMotion, along, check_centre, unit_direction


def _lujan_shape(u, n: int):
    """cos^(2n)(u) and its first and second derivatives with respect to u."""
    c, s = np.cos(u), np.sin(u)
    c_pow = c ** (2 * n - 2)
    C = c_pow * c * c
    dC = -2 * n * c_pow * c * s
    ddC = 2 * n * ((2 * n - 1) * c_pow * s * s - C)
    return C, dC, ddC


@dataclass(frozen=True)
class Breathing(LibraryMotion):
    """Breathing, Lujan et al. (Med. Phys. 26, 715, 1999): z(t) = z0 - b cos^(2n)(pi t/tau - phi).

    The displacement along ``direction`` is b (1/2 - cos^(2n)(pi t / tau - phi)): from +b/2 at
    end-exhale (where the motion rests longest) to -b/2 at end-inhale, about ``centre``; the
    platform tilts by ``tilt_rad`` times the same shape about ``tilt_axis``.

    Attributes:
        amplitude_m: b, peak to peak, m; default 0.015 (Lujan et al.: 10-20 mm for the liver and
            diaphragm; Seppenwoolde et al., IJROBP 53, 822, 2002: lung tumours up to ~25 mm).
        period_s: tau, s; default 4 (15 breaths per minute; Lujan et al.: 3-5 s).
        shape_n: n, a positive integer; default 3 (the value Lujan et al. used for the liver:
            long rest at exhale, a sharper inhale; n = 1 is cos^2, a shifted sinusoid).
        phase_rad: phi, rad; default pi/2, so that t = 0 is end-exhale and the cycles (from one
            end-exhale to the next, where the shape is flattest) start at t = k tau.
        direction: unit vector or axis name of the motion in the platform frame; default "SI"
            (the platform's X, :data:`~.core.PATIENT_AXES`): breathing moves organs mostly
            cranio-caudally (Lujan et al., Seppenwoolde et al.).
        tilt_rad: peak-to-peak rotation with the same shape, rad; default 0 (Lujan et al.'s
            model is a translation; Belcher et al., Med. Phys. 41, 121704, 2014 reproduce
            rotations up to 10 deg).
        tilt_axis: rotation axis (unit vector of [roll, pitch, yaw] or an axis name); default
            "rot_LR" (the platform's pitch).
        centre: (6,) the pose the motion is centred on (mid-range), rad and m; default home.
    Continuity: C-infinity; cycles start where cos = 0, so the irregular variant stays
    C^(2n-1) across cycles.
    """

    amplitude_m: float = 0.015
    period_s: float = 4.0
    shape_n: int = 3
    phase_rad: float = math.pi / 2
    direction: tuple | str = "SI"
    tilt_rad: float = 0.0
    tilt_axis: tuple | str = "rot_LR"
    centre: tuple = tuple(X_HOME)
    name: str = "breathing"

    def __post_init__(self):
        _set = object.__setattr__
        _set(self, "amplitude_m", as_number(f"{self.name}: amplitude_m", self.amplitude_m, 0.0))
        _set(self, "period_s", as_number(f"{self.name}: period_s", self.period_s, 0.05, 3600.0))
        n = as_number(f"{self.name}: shape_n", self.shape_n, 1, 20)
        if not n.is_integer():
            raise InvalidConfigError(
                f"{self.name}: shape_n must be an integer in [1, 20], got {self.shape_n!r}"
            )
        _set(self, "shape_n", int(n))
        _set(self, "phase_rad", as_number(f"{self.name}: phase_rad", self.phase_rad))
        _set(self, "direction", unit_direction(f"{self.name}: direction", self.direction))
        _set(
            self,
            "tilt_rad",
            as_number(f"{self.name}: tilt_rad", self.tilt_rad, -math.pi / 2, math.pi / 2),
        )
        _set(self, "tilt_axis", unit_direction(f"{self.name}: tilt_axis", self.tilt_axis, True))
        _set(self, "centre", check_centre(self.name, self.centre))

    def shape(self, t):
        """(s, ds/dt, d2s/dt2) of s(t) = 1/2 - cos^(2n)(pi t / tau - phi), dimensionless."""
        w = math.pi / self.period_s
        C, dC, ddC = _lujan_shape(w * np.asarray(t, dtype=float) - self.phase_rad, self.shape_n)
        return 0.5 - C, -w * dC, -w * w * ddC

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        s, ds, dds = self.shape(t)
        d, v, a = along(np.asarray(self.direction) * self.amplitude_m, s, ds, dds)
        for arr, part in ((d, s), (v, ds), (a, dds)):
            arr[:, :3] = part[:, None] * self.tilt_rad * np.asarray(self.tilt_axis)
        return d, v, a

    def frequencies_hz(self) -> dict:
        return {"breathing": 1.0 / self.period_s}

    @property
    def cycle_offset_s(self) -> float:
        """The first end-exhale at or after t = 0, s (0 with the default phase)."""
        return (self.period_s * ((self.phase_rad - math.pi / 2) / math.pi)) % self.period_s

    def cycles(self, t_end: float):
        """Cycles from one end-exhale to the next (see :meth:`LibraryMotion.cycles`)."""
        t0 = self.cycle_offset_s
        k = max(1, int(math.ceil((t_end - t0) / self.period_s - 1e-9)))
        return t0 + np.arange(k + 1) * self.period_s, np.ones(k)


#: The fields of :class:`Breathing` that the motions built on its breath share.
_BREATH_FIELDS = (
    "amplitude_m",
    "period_s",
    "shape_n",
    "direction",
    "tilt_rad",
    "tilt_axis",
    "centre",
)


def _checked_breathing(motion) -> "Breathing":
    """The :class:`Breathing` of a motion's breath fields (:data:`_BREATH_FIELDS`), which checks
    them; the motion's fields are replaced by the checked values (unit vectors, floats)."""
    breath = Breathing(**{f: getattr(motion, f) for f in _BREATH_FIELDS}, name=motion.name)
    for f in _BREATH_FIELDS:
        object.__setattr__(motion, f, getattr(breath, f))
    return breath


@dataclass(frozen=True)
class IrregularBreathing(LibraryMotion):
    """Breathing whose amplitude and period change from cycle to cycle (seeded).

    Cycle k lasts T_k = period_s (1 + period_cv g_k) and moves b_k = amplitude_m
    (1 + amplitude_cv h_k), with g_k, h_k standard normal draws of ``numpy.random.default_rng
    (seed)``, clipped to +-2.5 standard deviations. Within a cycle the shape is
    :class:`Breathing`'s from end-exhale to end-exhale, b_k deep from the same end-exhale
    position (Lujan et al.'s z0, +amplitude_m / 2 from the centre: the position the breath comes
    back to), so the motion is C^(2n-1) where cycles meet (the shape's first 2n - 1 derivatives
    vanish there).

    Attributes:
        amplitude_m, period_s, shape_n, direction, tilt_rad, tilt_axis, centre: the mean cycle,
            as :class:`Breathing` (same defaults and sources).
        amplitude_cv, period_cv: coefficients of variation from cycle to cycle; default 0.15 and
            0.10 (ours: free breathing varies by this order from breath to breath, e.g. the
            irregular patients of Seppenwoolde et al.).
        seed: of the draws, an integer >= 0.
        max_cycles: cycles drawn (the motion holds the last cycle's end beyond them).
    """

    if TYPE_CHECKING:  # drawn in __post_init__, not fields
        _starts: np.ndarray
        _amplitudes: np.ndarray

    amplitude_m: float = 0.015
    period_s: float = 4.0
    shape_n: int = 3
    direction: tuple | str = "SI"
    tilt_rad: float = 0.0
    tilt_axis: tuple | str = "rot_LR"
    amplitude_cv: float = 0.15
    period_cv: float = 0.10
    seed: int = 0
    max_cycles: int = 2000
    centre: tuple = tuple(X_HOME)
    name: str = "irregular_breathing"

    def __post_init__(self):
        _checked_breathing(self)  # the mean cycle's fields, checked as Breathing checks them
        for f in ("amplitude_cv", "period_cv"):
            object.__setattr__(self, f, as_number(f"{self.name}: {f}", getattr(self, f), 0.0, 0.35))
        for f, lo, hi in (("seed", 0, 2**32 - 1), ("max_cycles", 1, 10**6)):
            v = as_number(f"{self.name}: {f}", getattr(self, f), lo, hi)
            if not v.is_integer():
                raise InvalidConfigError(
                    f"{self.name}: {f} must be an integer in [{lo}, {hi}], got {getattr(self, f)!r}"
                )
            object.__setattr__(self, f, int(v))
        rng = np.random.default_rng(self.seed)
        g, h = np.clip(rng.standard_normal((2, self.max_cycles)), -2.5, 2.5)
        periods = self.period_s * (1 + self.period_cv * g)
        object.__setattr__(self, "_starts", np.concatenate([[0.0], np.cumsum(periods)]))
        object.__setattr__(self, "_amplitudes", self.amplitude_m * (1 + self.amplitude_cv * h))

    @property
    def cycle_periods(self) -> np.ndarray:
        """(max_cycles,) the drawn periods T_k, s."""
        return np.diff(self._starts)

    @property
    def cycle_amplitudes(self) -> np.ndarray:
        """(max_cycles,) the drawn amplitudes b_k (peak to peak), m."""
        return self._amplitudes.copy()

    def displacement(self, t):
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self._starts, t, side="right") - 1, 0, self.max_cycles - 1)
        T, b = np.diff(self._starts)[k], self._amplitudes[k]
        tau = np.clip(t - self._starts[k], 0.0, T)  # held after the last cycle
        w = math.pi / T
        C, dC, ddC = _lujan_shape(w * tau - math.pi / 2, self.shape_n)
        s, ds, dds = 0.5 * self.amplitude_m - b * C, -b * w * dC, -b * w * w * ddC
        moving = t < self._starts[-1]
        ds, dds = ds * moving, dds * moving
        d, v, a = along(self.direction, s, ds, dds)
        ratio = self.tilt_rad / self.amplitude_m if self.amplitude_m > 0 else 0.0
        for arr, part in ((d, s), (v, ds), (a, dds)):
            arr[:, :3] = part[:, None] * ratio * np.asarray(self.tilt_axis)
        return d, v, a

    def frequencies_hz(self) -> dict:
        return {"breathing": 1.0 / self.period_s}

    @property
    def repeat_period_s(self) -> None:
        return None

    def cycles(self, t_end: float):
        """The drawn cycles that begin before ``t_end`` (see :meth:`LibraryMotion.cycles`)."""
        k = max(1, int(np.searchsorted(self._starts, t_end - 1e-9, side="left")))
        k = min(k, self.max_cycles)
        return self._starts[: k + 1].copy(), self._amplitudes[:k] / self.amplitude_m


@dataclass(frozen=True)
class HysteresisBreathing(LibraryMotion):
    """Breathing whose inhale and exhale follow different paths (a loop), Seppenwoolde et al.
    (IJROBP 53, 822, 2002: hysteresis of 1-5 mm in lung tumours).

    The main displacement is :class:`Breathing`'s along ``direction``; a second one, of peak to
    peak ``secondary_amplitude_m`` along ``secondary_direction``, has the same shape delayed by
    ``lag`` of a period: on inhale it lags the main axis, on exhale it leads, and the path in
    the plane of the two axes is a loop whose widest opening is :meth:`loop_width_m`.

    Attributes:
        amplitude_m, period_s, shape_n, phase_rad, direction, centre: as :class:`Breathing`.
        secondary_amplitude_m: m; default 0.005 (an anterior-posterior excursion of a third of
            the cranio-caudal one; ours).
        secondary_direction: unit vector or axis name; default "AP" (the platform's Z).
        lag: delay of the secondary axis, fraction of a period; default 0.045 (ours: a loop
            about 2 mm wide with the defaults, mid-range of Seppenwoolde et al.'s 1-5 mm).
    """

    amplitude_m: float = 0.015
    period_s: float = 4.0
    shape_n: int = 3
    phase_rad: float = math.pi / 2
    direction: tuple | str = "SI"
    secondary_amplitude_m: float = 0.005
    secondary_direction: tuple | str = "AP"
    lag: float = 0.045
    centre: tuple = tuple(X_HOME)
    name: str = "hysteresis"

    def __post_init__(self):
        main = Breathing(
            amplitude_m=self.amplitude_m,
            period_s=self.period_s,
            shape_n=self.shape_n,
            phase_rad=self.phase_rad,
            direction=self.direction,
            centre=self.centre,
            name=self.name,
        )
        for f in ("amplitude_m", "period_s", "shape_n", "phase_rad", "direction", "centre"):
            object.__setattr__(self, f, getattr(main, f))
        object.__setattr__(
            self,
            "secondary_amplitude_m",
            as_number(f"{self.name}: secondary_amplitude_m", self.secondary_amplitude_m, 0.0),
        )
        object.__setattr__(
            self,
            "secondary_direction",
            unit_direction(f"{self.name}: secondary_direction", self.secondary_direction),
        )
        object.__setattr__(self, "lag", as_number(f"{self.name}: lag", self.lag, 0.0, 0.5))

    def _breaths(self):
        main = Breathing(
            amplitude_m=self.amplitude_m,
            period_s=self.period_s,
            shape_n=self.shape_n,
            phase_rad=self.phase_rad,
            direction=self.direction,
            name=self.name,
        )
        second = replace(
            main,
            amplitude_m=self.secondary_amplitude_m,
            direction=self.secondary_direction,
            phase_rad=self.phase_rad + math.pi * self.lag,
        )
        return main, second

    def displacement(self, t):
        main, second = self._breaths()
        return tuple(a + b for a, b in zip(main.displacement(t), second.displacement(t)))

    def frequencies_hz(self) -> dict:
        return {"breathing": 1.0 / self.period_s}

    def cycles(self, t_end: float):
        return self._breaths()[0].cycles(t_end)

    def loop_width_m(self) -> float:
        """Widest gap between the inhale and the exhale path, measured along the secondary
        direction at the same main-axis position, m."""
        main, second = self._breaths()
        t = main.cycle_offset_s + np.linspace(0.0, self.period_s, 4001)
        p = main.shape(t)[0] * self.amplitude_m
        q = second.shape(t)[0] * self.secondary_amplitude_m
        k = int(np.argmin(p))  # end-inhale splits the two paths
        levels = np.linspace(p.min(), p.max(), 201)[1:-1]
        paths = []
        for part in (slice(0, k + 1), slice(k, None)):
            order = np.argsort(p[part])
            paths.append(np.interp(levels, p[part][order], q[part][order]))
        return float(np.abs(paths[0] - paths[1]).max())


@dataclass(frozen=True)
class BreathHold(LibraryMotion):
    """Breathing that pauses at a phase for a stated time, then resumes (a breath-hold).

    The motion is :class:`Breathing`'s at a warped time theta(t): theta' = 1 - S((t - t_a) / r)
    + S((t - t_b) / r), S the quintic smoothstep, r = ``hold_ramp_s``, so the breathing slows to
    a stop over r, stays still for ``hold_s`` at the phase ``hold_phase`` of cycle
    ``hold_cycle``, and speeds up again over r; afterwards it runs hold_s + r behind the
    breathing without a hold. Pose B(theta), rate B'(theta) theta', acceleration B''(theta)
    theta'^2 + B'(theta) theta'' are continuous because theta' and theta'' are. The phantoms
    reproduce breath-holds (CIRS Motion Control imports them as motion files; the QUASAR
    respiratory motion phantom plays breath-hold waveforms) for deep-inspiration breath-hold
    treatments, where the patient holds at end-inhale for about 20 s.

    Attributes:
        amplitude_m, period_s, shape_n, direction, tilt_rad, tilt_axis, centre: the breathing,
            as :class:`Breathing` (same defaults and sources; t = 0 is end-exhale).
        hold_cycle: the cycle the hold is in (0 the first), an integer; default 1.
        hold_phase: where in that cycle it holds, fraction of the period from end-exhale, in
            [0, 1); default 0.5 (end-inhale: a deep-inspiration breath-hold).
        hold_s: s the motion stays still; default 20 (ours: the length of a clinical
            deep-inspiration breath-hold).
        hold_ramp_s: s to slow down (and to speed up again), in (0, period_s]; default 0.5
            (ours).
    Cycles run from one end-exhale to the next; the one with the hold lasts hold_s + r longer.
    Continuity: C2.
    Raises:
        InvalidConfigError: a value out of range, a hold that begins before t = 0.
    """

    if TYPE_CHECKING:  # built in __post_init__, not a field
        _breathing: Breathing

    amplitude_m: float = 0.015
    period_s: float = 4.0
    shape_n: int = 3
    direction: tuple | str = "SI"
    tilt_rad: float = 0.0
    tilt_axis: tuple | str = "rot_LR"
    hold_cycle: int = 1
    hold_phase: float = 0.5
    hold_s: float = 20.0
    hold_ramp_s: float = 0.5
    centre: tuple = tuple(X_HOME)
    name: str = "breath_hold"

    def __post_init__(self):
        breathing = _checked_breathing(self)
        _set, n = object.__setattr__, self.name
        _set(self, "_breathing", breathing)
        k = as_number(f"{n}: hold_cycle", self.hold_cycle, 0, 10**6)
        if not k.is_integer():
            raise InvalidConfigError(
                f"{n}: hold_cycle must be an integer in [0, 1000000], got {self.hold_cycle!r}"
            )
        _set(self, "hold_cycle", int(k))
        phase = as_number(f"{n}: hold_phase", self.hold_phase, 0.0, 1.0)
        if phase == 1.0:
            raise InvalidConfigError(
                f"{n}: hold_phase must be in [0, 1) (a fraction of a period; 1 is the next "
                f"cycle's 0: raise hold_cycle)"
            )
        _set(self, "hold_phase", phase)
        _set(self, "hold_s", as_number(f"{n}: hold_s", self.hold_s, 0.0, 1e6, lo_open=True))
        ramp = as_number(f"{n}: hold_ramp_s", self.hold_ramp_s, 0.0, self.period_s, lo_open=True)
        _set(self, "hold_ramp_s", ramp)
        if self.hold_starts_s < 0.0:
            raise InvalidConfigError(
                f"{n}: the hold would begin slowing down before t = 0 (at {self.hold_starts_s:.3g}"
                f" s): raise hold_cycle or hold_phase, or shorten hold_ramp_s"
            )

    @property
    def hold_starts_s(self) -> float:
        """t_a, s: when the breathing starts slowing down (it stops at t_a + hold_ramp_s)."""
        return (self.hold_cycle + self.hold_phase) * self.period_s - 0.5 * self.hold_ramp_s

    def warp(self, t):
        """(theta, theta', theta'') of the breathing's time at times t (n,), s, 1, 1/s."""
        r, ta = self.hold_ramp_s, self.hold_starts_s
        J1, S1, dS1 = smooth_ramp((t - ta) / r)
        J2, S2, dS2 = smooth_ramp((t - ta - r - self.hold_s) / r)
        return t - r * (J1 - J2), 1.0 - S1 + S2, (dS2 - dS1) / r

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        theta, dtheta, ddtheta = self.warp(np.asarray(t, dtype=float))
        d, v, a = self._breathing.displacement(theta)
        return d, v * dtheta[:, None], a * dtheta[:, None] ** 2 + v * ddtheta[:, None]

    def frequencies_hz(self) -> dict:
        return {"breathing": 1.0 / self.period_s}

    @property
    def repeat_period_s(self) -> None:
        return None

    def _time_at(self, theta) -> np.ndarray:
        """The first times at which the breathing's time reaches ``theta``, s: theta itself
        before the hold, else by bisection (theta(t) never decreases and lags t by at most
        hold_s + hold_ramp_s)."""
        theta = np.asarray(theta, dtype=float)
        lo, hi = theta.copy(), theta + self.hold_s + self.hold_ramp_s
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            below = self.warp(mid)[0] < theta
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        return np.where(self.warp(theta)[0] >= theta, theta, hi)

    def cycles(self, t_end: float):
        """Cycles from one end-exhale to the next, the held one longer (see
        :meth:`LibraryMotion.cycles`)."""
        theta = np.arange(int(math.ceil(t_end / self.period_s)) + 2) * self.period_s
        starts = self._time_at(theta)
        k = max(1, int(np.searchsorted(starts, t_end - 1e-9, side="left")))
        return starts[: k + 1], np.ones(k)


__all__ = ["Breathing", "IrregularBreathing", "HysteresisBreathing", "BreathHold"]
