"""Organ motion as references of the platform pose: breathing, heartbeat and their variants.

A motion of the library is a frozen dataclass with ``evaluate(t)`` -> (pose, rate,
acceleration), each ``t.shape + (6,)`` in [rad, rad, rad, m, m, m] (and /s, /s^2), a
:class:`~.motion.Reference` like every reference of :mod:`~.trajectories`, plus what fidelity
and learning need: ``frequencies_hz()`` (the fundamentals whose harmonics the report analyses),
``repeat_period_s`` (the time after which the motion repeats exactly, or None) and
``cycles(t_end)`` (the start of each cycle and its amplitude relative to the mean, for per-cycle
errors and the learning controller's alignment).

Motions (every parameter in SI units, its default and source in the class docstring):

=========================  =====================================================================
``breathing``              :class:`Breathing`, Lujan et al., Med. Phys. 26, 715 (1999):
                           z(t) = z0 - b cos^(2n)(pi t / tau - phi), with a direction and a tilt
``heartbeat``              :class:`Heartbeat`: a fundamental at the heart rate and harmonics
``breathing_heartbeat``    :class:`MotionSum` of the two
``irregular_breathing``    :class:`IrregularBreathing`: amplitude and period drawn per cycle, seeded
``hysteresis``             :class:`HysteresisBreathing`: different inhale and exhale paths
``sawtooth``               :class:`Sawtooth`: straight ramps in and out, corners rounded
``sharkfin``               :class:`Sharkfin`: a fast inhale, an exponential exhale, rounded
``baseline_drift``         :class:`BaselineDrift`: a linear or sinusoidal drift of the mean
``transient_excursion``    :class:`TransientExcursion`: away for a while, then back
``persistent_excursion``   :class:`PersistentExcursion`: a smooth step to a new baseline
``breath_hold``            :class:`BreathHold`: breathing that stops at a phase, then resumes
=========================  =====================================================================

The last six are the library of the commercial motion phantoms (CIRS Motion Control), each C2:
where the phantom's waveform has a corner, a smoothstep blend over a stated time replaces it.
A drift or an excursion is a displacement alone; :func:`layered` lays it on another motion or
on a recorded trace (``reproduce breathing --add baseline_drift``, a scenario's ``add``).

Directions are vectors in the platform frame or axis names: the platform's ``X``, ``Y``, ``Z``
or the patient's ``SI``, ``LR``, ``AP`` (:data:`PATIENT_AXES`: the patient lies supine along
the platform's X axis, head towards +X, left towards +Y, anterior up), with an optional sign.
:func:`make_motion` builds a motion from a name and ``key=value`` parameters carrying units
("amplitude=15mm", "rate=72bpm", "direction=SI"), as the CLI and scenarios give them;
:class:`OrganMotionReference` is a scenario's choice of one.

References add up (:class:`MotionSum`) and shrink about their centre (:class:`ScaledReference`:
:func:`~.fidelity.scale_to_fit` finds the scale the one reference validator
accepts). Recorded traces of organ motion are read by :mod:`~.traces`.

Drake's YAML loader reads :class:`OrganMotionReference`'s field types: this module must not use
``from __future__ import annotations``.
"""

import math
import re
from dataclasses import dataclass, field, fields, replace
from fractions import Fraction
from typing import TYPE_CHECKING

import numpy as np

from ..base.checks import as_array, as_number, as_poses
from ..base.errors import InvalidConfigError
from ..robot.geometry import X_HOME, StewartGeometry
from .motion import Reference, ReferenceConfig, peak_cycles, reference_cycles
from .trajectories import AXIS_NAMES

#: The patient frame in the platform frame: the patient lies supine along the platform's X axis,
#: head towards +X (superior), left towards +Y, anterior up (+Z). Rotations about the patient's
#: axes are the platform's roll, pitch and yaw about the same axes.
PATIENT_AXES = {
    "SI": "X",
    "LR": "Y",
    "AP": "Z",
    "rot_SI": "phi",
    "rot_LR": "theta",
    "rot_AP": "psi",
}
#: Platform axis names accepted besides AXIS_NAMES.
_AXIS_SYNONYMS = {"roll": "phi", "pitch": "theta", "yaw": "psi", "x": "X", "y": "Y", "z": "Z"}


def axis_index(name: str) -> tuple[int, float]:
    """(platform axis 0..5, sign +-1) of an axis name: ``X``, ``-Z``, ``phi``, ``pitch``, the
    patient's ``SI``, ``-LR``, ``rot_AP`` (:data:`PATIENT_AXES`).

    Raises:
        InvalidConfigError: an unknown name (the message lists the known ones).
    """
    text = str(name).strip()
    sign = -1.0 if text.startswith("-") else 1.0
    key = text[1:].strip() if text[:1] in "+-" else text
    if key[:1] in ("+", "-"):
        raise InvalidConfigError(f"axis {name!r}: one sign at most (e.g. -Z)")
    key = PATIENT_AXES.get(key, _AXIS_SYNONYMS.get(key, key))
    if key not in AXIS_NAMES:
        raise InvalidConfigError(
            f"unknown axis {name!r}: use a platform axis ({', '.join(AXIS_NAMES)}, roll, pitch, "
            f"yaw) or a patient axis ({', '.join(PATIENT_AXES)}), with an optional sign"
        )
    return AXIS_NAMES.index(key), sign


def _direction(name: str, value, rotation: bool = False) -> tuple:
    """A unit 3-vector from a vector or an axis name (translation axes, or rotation axes when
    ``rotation``)."""
    if isinstance(value, str) and not re.fullmatch(r"[\s\d.,eE+-]+", value):
        k, sign = axis_index(value)
        if (k < 3) != rotation:
            kind = (
                "a rotation axis (phi, theta, psi, rot_SI...)"
                if rotation
                else "a translation axis (X, Y, Z, SI, LR, AP)"
            )
            raise InvalidConfigError(f"{name} must be {kind}, got {value!r}")
        v = np.zeros(3)
        v[k % 3] = sign
        return tuple(v)
    if isinstance(value, str):
        value = [float(c) for c in value.split(",") if c.strip()]
    v = as_array(name, value, shape=(3,))
    norm = float(np.linalg.norm(v))
    if not norm > 0:
        raise InvalidConfigError(f"{name} must not be the zero vector")
    return tuple(float(c) / norm for c in v)


def _lujan_shape(u, n: int):
    """cos^(2n)(u) and its first and second derivatives with respect to u."""
    c, s = np.cos(u), np.sin(u)
    c_pow = c ** (2 * n - 2)
    C = c_pow * c * c
    dC = -2 * n * c_pow * c * s
    ddC = 2 * n * ((2 * n - 1) * c_pow * s * s - C)
    return C, dC, ddC


def check_centre(name: str, centre) -> tuple:
    """``centre`` as one pose, 6 floats [phi, theta, psi, X, Y, Z] in rad and m.

    Raises:
        InvalidConfigError: not 6 finite numbers, or a position beyond 1 km; names ``name``.
    """
    c = as_poses(f"{name}: centre", centre)
    if c.shape != (6,):
        raise InvalidConfigError(
            f"{name}: centre must be one pose (6,) [phi, theta, psi, X, Y, "
            f"Z] in rad and m, got shape {c.shape}"
        )
    return tuple(float(v) for v in c)


class _Motion:
    """What every motion of the library shares: ``evaluate`` = centre + displacement."""

    centre: tuple | None = tuple(X_HOME)
    name: str = ""

    def displacement(self, t):  # pragma: no cover - every motion defines it
        raise NotImplementedError

    def evaluate(self, t):
        """Pose, rate, acceleration at times t (s): three ``t.shape + (6,)`` arrays, rad and m."""
        t = np.asarray(t, dtype=float)
        d, v, a = self.displacement(t.reshape(-1))
        shape = t.shape + (6,)
        return ((np.asarray(self.centre) + d).reshape(shape), v.reshape(shape), a.reshape(shape))

    def frequencies_hz(self) -> dict:
        """{"breathing": Hz, "cardiac": Hz}: the fundamentals present (mean rate if varying)."""
        return {}

    @property
    def repeat_period_s(self) -> float | None:
        """The time after which the motion repeats exactly, s (None: it never does): every
        periodic motion of the library has a ``period_s``."""
        return getattr(self, "period_s", None)

    def cycles(self, t_end: float) -> tuple[np.ndarray, np.ndarray]:
        """(starts (K + 1,), scale (K,)): the cycles that begin in [0, t_end), their starts in
        s (the last entry ends the last cycle) and their amplitude over the mean's; a motion
        that repeats every :attr:`repeat_period_s` has cycles of that length from t = 0."""
        period = self.repeat_period_s
        if period is None:
            raise InvalidConfigError(
                f"{self.name or 'the motion'} does not repeat: it has no cycles"
            )
        k = max(1, int(math.ceil(t_end / period - 1e-9)))
        return np.arange(k + 1) * period, np.ones(k)


def _along(direction, shape, ds, dds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, 6) displacement, rate and acceleration of a scalar shape along a 3-vector direction
    (translation part)."""
    out = []
    for part in (shape, ds, dds):
        a = np.zeros((len(shape), 6))
        a[:, 3:] = part[:, None] * np.asarray(direction)
        out.append(a)
    return out[0], out[1], out[2]


@dataclass(frozen=True)
class Breathing(_Motion):
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
            (the platform's X, :data:`PATIENT_AXES`): breathing moves organs mostly
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
        _set(self, "direction", _direction(f"{self.name}: direction", self.direction))
        _set(
            self,
            "tilt_rad",
            as_number(f"{self.name}: tilt_rad", self.tilt_rad, -math.pi / 2, math.pi / 2),
        )
        _set(self, "tilt_axis", _direction(f"{self.name}: tilt_axis", self.tilt_axis, True))
        _set(self, "centre", check_centre(self.name, self.centre))

    def shape(self, t):
        """(s, ds/dt, d2s/dt2) of s(t) = 1/2 - cos^(2n)(pi t / tau - phi), dimensionless."""
        w = math.pi / self.period_s
        C, dC, ddC = _lujan_shape(w * np.asarray(t, dtype=float) - self.phase_rad, self.shape_n)
        return 0.5 - C, -w * dC, -w * w * ddC

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        s, ds, dds = self.shape(t)
        d, v, a = _along(np.asarray(self.direction) * self.amplitude_m, s, ds, dds)
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
        """Cycles from one end-exhale to the next (see :meth:`_Motion.cycles`)."""
        t0 = self.cycle_offset_s
        k = max(1, int(math.ceil((t_end - t0) / self.period_s - 1e-9)))
        return t0 + np.arange(k + 1) * self.period_s, np.ones(k)


#: Bound on the size of a heartbeat's largest relative harmonic amplitude, and its inverse
#: (their ratios are what matter).
MAX_RELATIVE_HARMONIC = 1e6
#: Relative amplitudes of the heartbeat's harmonics by default (ours; see :class:`Heartbeat`).
HEARTBEAT_HARMONICS = (1.0, 0.5, 0.25)


@dataclass(frozen=True)
class Heartbeat(_Motion):
    """Cardiac motion: a fundamental at the heart rate and its harmonics.

    d(t) = amplitude_m / p2p * sum_k a_k sin(2 pi k f t + phi_k) along ``direction``, with
    f = rate_bpm / 60 and p2p the peak to peak of the sum (so ``amplitude_m`` is the peak to
    peak of the motion).

    Attributes:
        amplitude_m: peak to peak, m; default 0.002 (Seppenwoolde et al., IJROBP 53, 822, 2002:
            a cardiac component of 1-4 mm in lung tumours near the heart).
        rate_bpm: beats per minute; default 72 (a resting adult).
        harmonics: relative amplitudes a_1, a_2, ... of the fundamental and its harmonics;
            default (1, 0.5, 0.25): ours, a beat sharper than a sine (Seppenwoolde et al. give
            the amplitude, not the shape).
        harmonic_phases_rad: phi_k, rad (as many as harmonics; default zeros).
        direction: unit vector or axis name; default "LR" (the platform's Y; Seppenwoolde et
            al. found the cardiac component mostly left-right).
        centre: (6,) pose, rad and m; default home.
    """

    amplitude_m: float = 0.002
    rate_bpm: float = 72.0
    harmonics: tuple = HEARTBEAT_HARMONICS
    harmonic_phases_rad: tuple = ()
    direction: tuple | str = "LR"
    centre: tuple = tuple(X_HOME)
    name: str = "heartbeat"

    def __post_init__(self):
        _set = object.__setattr__
        _set(self, "amplitude_m", as_number(f"{self.name}: amplitude_m", self.amplitude_m, 0.0))
        _set(self, "rate_bpm", as_number(f"{self.name}: rate_bpm", self.rate_bpm, 1.0, 600.0))
        a = as_array(f"{self.name}: harmonics", self.harmonics).reshape(-1)
        if a.size < 1 or a.size > 20 or not np.any(a != 0):
            raise InvalidConfigError(
                f"{self.name}: harmonics needs 1 to 20 relative "
                f"amplitudes, not all zero, got {self.harmonics!r}"
            )
        if not 1.0 / MAX_RELATIVE_HARMONIC <= np.max(np.abs(a)) <= MAX_RELATIVE_HARMONIC:
            # Only their ratios matter (the sum is scaled to amplitude_m); beyond these the
            # acceleration's sums overflow float64, or the scale dividing by their peak to peak.
            raise InvalidConfigError(
                f"{self.name}: harmonics are relative amplitudes, the largest between "
                f"{1.0 / MAX_RELATIVE_HARMONIC:g} and {MAX_RELATIVE_HARMONIC:g} in size, got "
                f"{self.harmonics!r}: divide them by the largest"
            )
        phases = (
            np.zeros(a.size)
            if len(self.harmonic_phases_rad) == 0
            else as_array(
                f"{self.name}: harmonic_phases_rad", self.harmonic_phases_rad, shape=(a.size,)
            )
        )
        _set(self, "harmonics", tuple(float(v) for v in a))
        _set(self, "harmonic_phases_rad", tuple(float(v) for v in phases))
        _set(self, "direction", _direction(f"{self.name}: direction", self.direction))
        _set(self, "centre", check_centre(self.name, self.centre))
        _set(self, "_p2p", self._peak_to_peak())

    @property
    def frequency_hz(self) -> float:
        return self.rate_bpm / 60.0

    @property
    def period_s(self) -> float:
        return 60.0 / self.rate_bpm

    def _unit(self, t):
        f, k = self.frequency_hz, np.arange(1, len(self.harmonics) + 1)
        arg = 2 * np.pi * f * np.asarray(t, dtype=float)[:, None] * k + np.asarray(
            self.harmonic_phases_rad
        )
        w = 2 * np.pi * f * k
        a = np.asarray(self.harmonics)
        return (np.sin(arg) @ a, np.cos(arg) @ (a * w), -np.sin(arg) @ (a * w * w))

    def _peak_to_peak(self) -> float:
        s = self._unit(np.linspace(0.0, self.period_s, 4001))[0]
        return float(s.max() - s.min())

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        scale = self.amplitude_m / self._p2p
        s, ds, dds = self._unit(t)
        return _along(np.asarray(self.direction) * scale, s, ds, dds)

    def frequencies_hz(self) -> dict:
        return {"cardiac": self.frequency_hz}


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


def common_period(periods, max_ratio_denominator: int = 24) -> float | None:
    """The shortest time after which every period repeats (their least common multiple), s, or
    None when two periods are not in a ratio of small integers (denominator up to
    ``max_ratio_denominator``, within 1e-9 relative).

    Raises:
        InvalidConfigError: no period, or one that is not a finite positive number.
    """
    periods = [float(p) for p in periods]
    if not periods or not all(0 < p < math.inf for p in periods):
        raise InvalidConfigError(f"periods must be finite positive numbers of s, got {periods}")
    total = periods[0]
    for p in periods[1:]:
        ratio = Fraction(total / p).limit_denominator(max_ratio_denominator)
        if abs(ratio - total / p) > 1e-9 * total / p:
            return None
        total = total * ratio.denominator  # = p * ratio.numerator
    return total


@dataclass(frozen=True)
class MotionSum(_Motion):
    """The sum of references: breathing plus heartbeat about one centre, or a multi-sine.

    With a ``centre``, the parts are motions of the library and the pose is the centre plus the
    sum of their displacements (their own centres are ignored). Without (``centre=None``), the
    parts are any references (:class:`~.motion.Reference`) and the pose is the sum of their
    poses (a sine about home plus sines about zero); the sum has no centre then. Rates and
    accelerations add up alike.

    Attributes:
        parts: the motions or references.  centre: (6,) pose, rad and m, or None; default home.
        name: label used in result files.
    The sum repeats after the common period of its parts (:func:`common_period`: a 4 s breath
    and a 72 bpm heartbeat repeat every 20 s, 5 breaths and 24 beats), its cycles are those
    periods; when the parts have no common period it has the cycles of its first part (the
    rest is not periodic in them), or, when that part has none of its own, those found where
    the sum peaks (:func:`~.motion.peak_cycles`).
    Raises:
        InvalidConfigError: no parts, or parts that are not motions of the library (with a
            centre) or have no ``evaluate`` (without).
    """

    parts: tuple = ()
    centre: tuple | None = tuple(X_HOME)
    name: str = "sum"

    def __post_init__(self):
        if self.centre is None:
            if not self.parts or not all(
                callable(getattr(p, "evaluate", None)) for p in self.parts
            ):
                raise InvalidConfigError(
                    f"{self.name}: parts must be references (with evaluate(t))"
                )
        else:
            if not self.parts or not all(isinstance(p, _Motion) for p in self.parts):
                raise InvalidConfigError(f"{self.name}: parts must be motions of the library")
            object.__setattr__(self, "centre", check_centre(self.name, self.centre))
        object.__setattr__(self, "parts", tuple(self.parts))

    def displacement(self, t):
        """(n, 6) the sum's displacement from its centre (its pose when it has none), rate and
        acceleration at times t (n,)."""
        out = [np.zeros((len(t), 6)) for _ in range(3)]
        for part in self.parts:
            adds = part.evaluate(t) if self.centre is None else part.displacement(t)
            for acc, add in zip(out, adds):
                acc += add
        return tuple(out)

    def evaluate(self, t):
        """Pose, rate, acceleration at times t (s): three ``t.shape + (6,)`` arrays, rad and m."""
        if self.centre is not None:
            return super().evaluate(t)
        t = np.asarray(t, dtype=float)
        shape = t.shape + (6,)
        return tuple(part.reshape(shape) for part in self.displacement(t.reshape(-1)))

    def frequencies_hz(self) -> dict:
        out: dict = {}
        for part in self.parts:
            f = getattr(part, "frequencies_hz", None)
            out.update(f() if callable(f) else {})
        return out

    @property
    def repeat_period_s(self) -> float | None:
        periods = [getattr(p, "repeat_period_s", None) for p in self.parts]
        return None if any(p is None for p in periods) else common_period(periods)

    def cycles(self, t_end: float):
        period = self.repeat_period_s
        first = self.parts[0]
        if period is None:
            if callable(getattr(first, "cycles", None)):
                return first.cycles(t_end)
            return peak_cycles(self, t_end)
        t0 = first.cycles(period)[0][0]
        k = max(1, int(math.ceil((t_end - t0) / period - 1e-9)))
        return t0 + np.arange(k + 1) * period, np.ones(k)


@dataclass(frozen=True)
class IrregularBreathing(_Motion):
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
        d, v, a = _along(self.direction, s, ds, dds)
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
        """The drawn cycles that begin before ``t_end`` (see :meth:`_Motion.cycles`)."""
        k = max(1, int(np.searchsorted(self._starts, t_end - 1e-9, side="left")))
        k = min(k, self.max_cycles)
        return self._starts[: k + 1].copy(), self._amplitudes[:k] / self.amplitude_m


@dataclass(frozen=True)
class HysteresisBreathing(_Motion):
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
            _direction(f"{self.name}: secondary_direction", self.secondary_direction),
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


# -- the motion phantoms' library: rounded corners, drift, excursions, breath-hold ---------------
#
# The waveforms of the commercial motion phantoms (CIRS Motion Control for the Dynamic Thorax,
# Dynamic Pelvis and Dynamic Platform: sin, cos^4, cos^6, sawtooth, sharkfin; continuous drift,
# transient and persistent excursion) have corners, which a reference with rate and acceleration
# feed-forward cannot have: every corner here is a C2 blend of the two sides over a stated time.


def _smoothstep(x):
    """(S, S', S'') of the quintic smoothstep S(x) = 10 x^3 - 15 x^4 + 6 x^5 on [0, 1] (0 below,
    1 above): S' and S'' vanish at both ends, so a step or a blend made of it is C2."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return (
        x**3 * (10.0 - 15.0 * x + 6.0 * x * x),
        30.0 * x * x * (1.0 - x) ** 2,
        60.0 * x * (1.0 - x) * (1.0 - 2.0 * x),
    )


def _smooth_ramp(x):
    """(J, J', J'') of J(x), the integral of :func:`_smoothstep` from -inf to x: 0 below 0,
    x - 1/2 above 1, a ramp whose slope rises smoothly from 0 to 1 over [0, 1] (C3)."""
    x = np.asarray(x, dtype=float)
    c = np.clip(x, 0.0, 1.0)
    S, dS, _ = _smoothstep(x)
    return np.where(x > 1.0, x - 0.5, c**4 * (2.5 - 3.0 * c + c * c)), S, dS


#: Gauss-Legendre nodes and weights on [-1, 1] of :func:`_round_corner`'s integral (16 nodes
#: integrate its smooth integrand to round-off over a corner's few tenths of a second).
_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)


def _round_corner(t, corner: float, width: float, first, second):
    """(y, y', y'') at times ``t`` within ``width`` s centred on ``corner``, where the branch
    ``first`` hands over to ``second`` (each a function of time to (y, y', y''), meeting at the
    corner), the corner rounded by blending the branches' *rates*:
    y' = (1 - S) first' + S second', S = :func:`_smoothstep` across the window, integrated from
    the window's start (Gauss-Legendre), plus delta S, where delta (zero for straight branches)
    makes y meet ``second`` at the window's end. At both ends y, y' and y'' are those of the
    branch there: C2. Blending rates rather than positions cuts the corner on its inside (for
    straight branches exactly; curved ones add delta S, 0.8 % of the stroke at the shark fin's
    base with its defaults): the rounded path does not pass beyond the corner, and between two
    branches moving the same way it does not turn back (blending positions would overshoot, a
    hook at the shark fin's base)."""
    a = corner - 0.5 * width
    f, g = first(t), second(t)
    S, dS, ddS = _smoothstep((t - a) / width)
    dS, ddS = dS / width, ddS / width**2

    def integral(upper):
        half = 0.5 * (upper - a)
        u = a + half[:, None] * (1.0 + _GAUSS_NODES)
        gap = second(u)[1] - first(u)[1]
        return half * ((_smoothstep((u - a) / width)[0] * gap) @ _GAUSS_WEIGHTS)

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


class _Waveform(_Motion):
    """A periodic waveform of the phantoms' library from its cycle's two branches
    (:meth:`_branches`) with rounded corners: the displacement is b (1/2 - u(t)) along
    ``direction``, u the rounded cycle scaled to [0, 1], from +b/2 at end-exhale to -b/2 at
    end-inhale about the centre as :class:`Breathing`'s; cycles start at t = k period, in the
    middle of the rounded corner between exhale and inhale."""

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
        _set(self, "direction", _direction(f"{self.name}: direction", self.direction))
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
        return _along(np.asarray(self.direction) * self.amplitude_m, s, ds, dds)

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
        amplitude_m: peak to peak, m; default 0.015 (as :class:`Breathing`).
        period_s: s; default 4 (as :class:`Breathing`).
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

    The raw cycle is the waveform of a square wave through a first-order lag, the "shark fin"
    of the phantoms' libraries (CIRS Motion Control for the Dynamic Thorax phantom; the QUASAR
    respiratory motion phantom's breathing waveforms): the inhale rises as (1 - exp(-t /
    inhale_tau_s)) over ``inhale_fraction`` of the period, the exhale falls as exp(-t /
    exhale_tau_s) back to end-exhale (each scaled to meet the other at its ends). The fin's
    tip and its base are corners: over ``rounding_s`` centred on each, the speed passes from one
    branch's to the other's along a quintic smoothstep (:func:`_round_corner`; ours, the manuals
    give no formula), which cuts inside the corner: by 0.5 % of the stroke at the tip and 0.24 %
    at the base with the defaults, the motion never turning back between them; the cycle is
    then rescaled so that ``amplitude_m`` is the peak to peak.

    Attributes:
        amplitude_m: peak to peak, m; default 0.015 (as :class:`Breathing`).
        period_s: s; default 4 (as :class:`Breathing`).
        inhale_fraction: the inhale's share of the period, in [0.05, 0.95]; default 0.3 (ours).
        inhale_tau_s: time constant of the inhale, s; default 0.3 (ours: 4 time constants in the
            1.2 s inhale, the fin's steep front).
        exhale_tau_s: time constant of the exhale, s; default 0.7 (ours: 4 time constants in the
            2.8 s exhale, a long rest at end-exhale as Lujan et al.'s cos^6).
        rounding_s: length of each rounded corner, s, in (0, the shorter branch]; default 0.2
            (ours: peak acceleration 0.42 m/s^2 with the defaults, at the fin's base, where the
            exhale's slow end meets the inhale's steep start; on ``paper_hardware`` the motors'
            peak torque is then 0.41 N m of their 0.63 N m limit, 0.49 N m with 0.1 s, and
            0.65 N m, refused, with 0.05 s).
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


class _Excursion(_Motion):
    """A one-off displacement along a direction (no breathing): what the phantoms add to a
    motion (:func:`layered`) or run alone. It does not repeat: no cycles of its own."""

    def _direction_field(self, field_name: str) -> None:
        value = _direction(f"{self.name}: {field_name}", getattr(self, field_name))
        object.__setattr__(self, field_name, value)
        object.__setattr__(self, "centre", check_centre(self.name, self.centre))

    def _profile(self, t):  # pragma: no cover - every excursion defines it
        """(s, ds/dt, d2s/dt2) of the displacement along the direction, m."""
        raise NotImplementedError

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        s, ds, dds = self._profile(np.asarray(t, dtype=float))
        return _along(self._unit, s, ds, dds)


@dataclass(frozen=True)
class BaselineDrift(_Excursion):
    """A slow drift of the mean position: linear (by ``drift_m`` over ``drift_duration_s``,
    then held) or sinusoidal (between 0 and ``drift_m`` every ``drift_period_s``).

    The continuous drift of the phantoms' library (CIRS Motion Control for the Dynamic Pelvis
    phantom, model 008P), after the continuous target drift Langen et al. (IJROBP 71, 1084,
    2008) saw in prostates tracked electromagnetically. Linear: the rate rises from 0 to
    drift_m / (drift_duration_s - drift_rounding_s) over ``drift_rounding_s`` (a quintic
    smoothstep), holds, and falls back to 0 over the drift's last ``drift_rounding_s``: the
    position reaches ``drift_m`` at drift_start_s + drift_duration_s. Sinusoidal:
    drift_m (1 - cos(2 pi (t - t0) / drift_period_s)) / 2 faded in by a smoothstep over
    ``drift_rounding_s``. Laid on breathing (:func:`layered`, ``reproduce breathing --add
    baseline_drift``) it moves the breathing's mean position.

    Attributes:
        drift_m: the drift's total (linear) or peak to peak (sinusoidal), m, signed; default
            0.003 (ours: a few mm, Langen et al.'s order for a prostate over minutes).
        drift_duration_s: s the linear drift lasts; default 60.
        drift_period_s: period of a sinusoidal drift, s; default 0 (linear).
        drift_start_s: s when the drift begins; default 0.
        drift_rounding_s: s over which the rate rises (and falls), at most half the duration
            (and the period); default 2 (ours).
        drift_direction: unit vector or axis name; default "SI".
        centre: (6,) the pose the drift starts from, rad and m; default home.
    Continuity: C2 (C3 for the linear drift: its rate is a smoothstep).
    Raises:
        InvalidConfigError: a value out of range, a rounding longer than half the drift.
    """

    drift_m: float = 0.003
    drift_duration_s: float = 60.0
    drift_period_s: float = 0.0
    drift_start_s: float = 0.0
    drift_rounding_s: float = 2.0
    drift_direction: tuple | str = "SI"
    centre: tuple = tuple(X_HOME)
    name: str = "baseline_drift"

    def __post_init__(self):
        _set, n = object.__setattr__, self.name
        _set(self, "drift_m", as_number(f"{n}: drift_m", self.drift_m, -1.0, 1.0))
        _set(self, "drift_start_s", as_number(f"{n}: drift_start_s", self.drift_start_s, 0.0))
        duration = as_number(f"{n}: drift_duration_s", self.drift_duration_s, 0.0, lo_open=True)
        period = as_number(f"{n}: drift_period_s", self.drift_period_s, 0.0, 1e6)
        rounding = as_number(f"{n}: drift_rounding_s", self.drift_rounding_s, 0.0, lo_open=True)
        longest = 0.5 * (period if period > 0 else duration)
        if rounding > longest:
            raise InvalidConfigError(
                f"{n}: drift_rounding_s must be at most half the drift's "
                f"{'period' if period > 0 else 'duration'} ({longest:g} s), got {rounding:g}"
            )
        _set(self, "drift_duration_s", duration)
        _set(self, "drift_period_s", period)
        _set(self, "drift_rounding_s", rounding)
        self._direction_field("drift_direction")

    @property
    def _unit(self):
        return np.asarray(self.drift_direction)

    def _profile(self, t):
        r, t0, b = self.drift_rounding_s, self.drift_start_s, self.drift_m
        if self.drift_period_s == 0.0:
            slope = b / (self.drift_duration_s - r)
            J1, S1, dS1 = _smooth_ramp((t - t0) / r)
            J2, S2, dS2 = _smooth_ramp((t - t0 - self.drift_duration_s + r) / r)
            return slope * r * (J1 - J2), slope * (S1 - S2), slope * (dS1 - dS2) / r
        w = 2.0 * math.pi / self.drift_period_s
        u = np.maximum(t - t0, 0.0)
        y, dy, ddy = 0.5 * b * (1 - np.cos(w * u)), 0.5 * b * w * np.sin(w * u), 0.5 * b * w * w
        ddy = ddy * np.cos(w * u)
        S, dS, ddS = _smoothstep(u / r)
        dS, ddS = dS / r, ddS / r**2
        return S * y, S * dy + dS * y, S * ddy + 2.0 * dS * dy + ddS * y


@dataclass(frozen=True)
class TransientExcursion(_Excursion):
    """A one-off excursion: the position moves ``excursion_m`` away along a direction and comes
    back, a smooth step up and a smooth step down.

    The transient excursion of the phantoms' library (CIRS Motion Control for the Dynamic Pelvis
    phantom), after the transient excursions of the prostate that Langen et al. (IJROBP 71,
    1084, 2008) saw (gas or the bowel pushing it away for seconds to a minute, then letting it
    go): s(t) = excursion_m (S((t - t0) / r) - S((t - t0 - D + r) / r)), S the quintic
    smoothstep, t0 = ``excursion_start_s``, D = ``excursion_duration_s``, r =
    ``excursion_rise_s``: away in r, held for D - 2 r, back in r.

    Attributes:
        excursion_m: the excursion, m, signed; default 0.005 (ours: Langen et al. count
            excursions beyond 3 and 5 mm).
        excursion_start_s: s when it begins; default 2.
        excursion_duration_s: s from leaving to being back; default 10.
        excursion_rise_s: s to go away (and to come back), at most half the duration; default 2
            (ours: peak speed 1.875 excursion_m / rise, 4.7 mm/s with the defaults).
        excursion_direction: unit vector or axis name; default "SI".
        centre: (6,) the pose it leaves and comes back to, rad and m; default home.
    Continuity: C2 (the smoothstep's S' and S'' vanish at its ends).
    Raises:
        InvalidConfigError: a value out of range, a rise longer than half the duration.
    """

    excursion_m: float = 0.005
    excursion_start_s: float = 2.0
    excursion_duration_s: float = 10.0
    excursion_rise_s: float = 2.0
    excursion_direction: tuple | str = "SI"
    centre: tuple = tuple(X_HOME)
    name: str = "transient_excursion"

    def __post_init__(self):
        _set, n = object.__setattr__, self.name
        _set(self, "excursion_m", as_number(f"{n}: excursion_m", self.excursion_m, -1.0, 1.0))
        _set(
            self,
            "excursion_start_s",
            as_number(f"{n}: excursion_start_s", self.excursion_start_s, 0.0),
        )
        duration = as_number(
            f"{n}: excursion_duration_s", self.excursion_duration_s, 0.0, lo_open=True
        )
        rise = as_number(f"{n}: excursion_rise_s", self.excursion_rise_s, 0.0, lo_open=True)
        if rise > 0.5 * duration:
            raise InvalidConfigError(
                f"{n}: excursion_rise_s must be at most half excursion_duration_s "
                f"({0.5 * duration:g} s), got {rise:g}"
            )
        _set(self, "excursion_duration_s", duration)
        _set(self, "excursion_rise_s", rise)
        self._direction_field("excursion_direction")

    @property
    def _unit(self):
        return np.asarray(self.excursion_direction)

    def _profile(self, t):
        r, t0, b = self.excursion_rise_s, self.excursion_start_s, self.excursion_m
        up = _smoothstep((t - t0) / r)
        down = _smoothstep((t - t0 - self.excursion_duration_s + r) / r)
        return b * (up[0] - down[0]), b * (up[1] - down[1]) / r, b * (up[2] - down[2]) / r**2


@dataclass(frozen=True)
class PersistentExcursion(_Excursion):
    """A persistent excursion: a smooth step to a new baseline that stays,
    s(t) = shift_m S((t - shift_start_s) / shift_rise_s), S the quintic smoothstep.

    The persistent excursion of the phantoms' library (CIRS Motion Control for the Dynamic
    Pelvis phantom), after Langen et al. (IJROBP 71, 1084, 2008): a prostate that moves to a
    new position and stays there; a baseline shift of breathing when laid on it
    (:func:`layered`).

    Attributes:
        shift_m: the step, m, signed; default 0.005 (ours, as :class:`TransientExcursion`).
        shift_start_s: s when it begins; default 2.
        shift_rise_s: s the step takes; default 2 (ours).
        shift_direction: unit vector or axis name; default "SI".
        centre: (6,) the pose it leaves, rad and m; default home.
    Continuity: C2 (the smoothstep's S' and S'' vanish at its ends).
    Raises:
        InvalidConfigError: a value out of range.
    """

    shift_m: float = 0.005
    shift_start_s: float = 2.0
    shift_rise_s: float = 2.0
    shift_direction: tuple | str = "SI"
    centre: tuple = tuple(X_HOME)
    name: str = "persistent_excursion"

    def __post_init__(self):
        _set, n = object.__setattr__, self.name
        _set(self, "shift_m", as_number(f"{n}: shift_m", self.shift_m, -1.0, 1.0))
        _set(self, "shift_start_s", as_number(f"{n}: shift_start_s", self.shift_start_s, 0.0))
        _set(
            self,
            "shift_rise_s",
            as_number(f"{n}: shift_rise_s", self.shift_rise_s, 0.0, lo_open=True),
        )
        self._direction_field("shift_direction")

    @property
    def _unit(self):
        return np.asarray(self.shift_direction)

    def _profile(self, t):
        r = self.shift_rise_s
        S, dS, ddS = _smoothstep((t - self.shift_start_s) / r)
        return self.shift_m * S, self.shift_m * dS / r, self.shift_m * ddS / r**2


@dataclass(frozen=True)
class BreathHold(_Motion):
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
        J1, S1, dS1 = _smooth_ramp((t - ta) / r)
        J2, S2, dS2 = _smooth_ramp((t - ta - r - self.hold_s) / r)
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
        :meth:`_Motion.cycles`)."""
        theta = np.arange(int(math.ceil(t_end / self.period_s)) + 2) * self.period_s
        starts = self._time_at(theta)
        k = max(1, int(np.searchsorted(starts, t_end - 1e-9, side="left")))
        return starts[: k + 1], np.ones(k)


# -- the library by name ---------------------------------------------------------------------------


def _breathing_heartbeat(**kw):
    heart = {k[len("heart_") :]: v for k, v in kw.items() if k.startswith("heart_")}
    breath = {k: v for k, v in kw.items() if not k.startswith("heart_") and k != "centre"}
    centre = kw.get("centre", tuple(X_HOME))
    return MotionSum(
        parts=(Breathing(**breath), Heartbeat(**heart)), centre=centre, name="breathing_heartbeat"
    )


#: name -> (factory, the class whose fields are its parameters).
LIBRARY = {
    "breathing": (Breathing, Breathing),
    "heartbeat": (Heartbeat, Heartbeat),
    "breathing_heartbeat": (_breathing_heartbeat, None),
    "irregular_breathing": (IrregularBreathing, IrregularBreathing),
    "hysteresis": (HysteresisBreathing, HysteresisBreathing),
    "sawtooth": (Sawtooth, Sawtooth),
    "sharkfin": (Sharkfin, Sharkfin),
    "baseline_drift": (BaselineDrift, BaselineDrift),
    "transient_excursion": (TransientExcursion, TransientExcursion),
    "persistent_excursion": (PersistentExcursion, PersistentExcursion),
    "breath_hold": (BreathHold, BreathHold),
}

#: Units a parameter value may carry, by the suffix of the field it sets: factor to SI.
UNITS = {
    "m": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6},
    "rad": {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180},
    "s": {"s": 1.0, "ms": 1e-3, "min": 60.0},
    "bpm": {"bpm": 1.0, "/min": 1.0, "hz": 60.0},
}


def parameter_names(motion: str) -> list[str]:
    """The parameters :func:`make_motion` takes for ``motion`` (field names; a field with a
    unit suffix, ``amplitude_m``, is also given without it, ``amplitude=15mm``)."""
    factory, cls = _library(motion)
    if cls is None:
        names = [f.name for f in fields(Breathing) if f.name not in ("name", "centre")]
        names += [f"heart_{f.name}" for f in fields(Heartbeat) if f.name not in ("name", "centre")]
        return names + ["centre"]
    return [f.name for f in fields(cls) if f.name != "name"]


def _library(motion: str):
    if motion not in LIBRARY:
        raise InvalidConfigError(
            f"unknown motion {motion!r}; the library has "
            f"{', '.join(LIBRARY)} (or give a trace file, .csv)"
        )
    return LIBRARY[motion]


def _parse_value(key: str, field_name: str, value):
    """A parameter value in the unit of ``field_name``'s suffix (SI), from a number or a string
    with a unit ("15mm", "72 bpm", "2deg"); vectors and axis names pass through."""
    field_name = field_name.removeprefix("heart_")
    suffix = field_name.rsplit("_", 1)[-1] if "_" in field_name else ""
    if not isinstance(value, str):
        return value
    text = value.strip()
    if suffix in UNITS:
        m = re.fullmatch(r"([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Z/]*)", text)
        if m is None or not math.isfinite(float(m.group(1))):
            raise InvalidConfigError(
                f"parameter {key}: {value!r} is not a finite number with a unit "
                f"(e.g. 15mm); units: {', '.join(UNITS[suffix])}"
            )
        number, unit = float(m.group(1)), m.group(2).lower()
        units = {u.lower(): f for u, f in UNITS[suffix].items()}
        if unit and unit not in units:
            raise InvalidConfigError(
                f"parameter {key}: unknown unit {m.group(2)!r}; use one of "
                f"{', '.join(UNITS[suffix])}"
            )
        return number * (units[unit] if unit else 1.0)
    if "direction" in field_name or "axis" in field_name:
        return text
    try:
        if field_name in ("harmonics", "harmonic_phases_rad", "centre"):
            return tuple(float(c) for c in text.split(",") if c.strip())
        return float(text)
    except ValueError:
        raise InvalidConfigError(
            f"parameter {key}: {value!r} is not a number"
            + (" list (1,0.5,0.25)" if "," in text else "")
        ) from None


def make_motion(motion: str, parameters: dict | None = None):
    """A motion of the library by name with parameters carrying units.

    Args:
        motion: one of :data:`LIBRARY` (breathing, heartbeat, breathing_heartbeat,
            irregular_breathing, hysteresis, sawtooth, sharkfin, baseline_drift,
            transient_excursion, persistent_excursion, breath_hold).
        parameters: {name: value}: a field of the motion's class (``amplitude_m``: a number in
            its SI unit) or the field without its unit suffix with a value carrying a unit
            (``amplitude``: "15mm"; ``rate``: "72bpm"; ``tilt``: "2deg"); directions as axis
            names ("SI", "-Z") or "x,y,z"; for breathing_heartbeat the heart's parameters
            start with ``heart_`` (``heart_amplitude``, ``heart_rate``).
    Returns:
        the motion (frozen dataclass with ``evaluate``).
    Raises:
        InvalidConfigError: an unknown motion or parameter (the known ones listed), a value
            without a number, an unknown unit, or a value out of range (named).
    """
    factory, cls = _library(motion)
    known = parameter_names(motion)
    kwargs = {}
    for key, value in (parameters or {}).items():
        key = str(key).strip()
        name = (
            key
            if key in known
            else next(
                (
                    n
                    for n in known
                    if "_" in n
                    and n.rsplit("_", 1)[0] == key
                    and n.rsplit("_", 1)[1] in (*UNITS, "n")
                ),
                None,
            )
        )
        if name is None:
            raise InvalidConfigError(
                f"{motion} has no parameter {key!r}; its parameters: "
                f"{', '.join(known)} (a unit suffix may be left out and "
                f"given with the value: amplitude=15mm)"
            )
        kwargs[name] = _parse_value(key, name, value)
    try:
        return factory(**kwargs)
    except TypeError as err:
        raise InvalidConfigError(f"{motion}: {err}") from None


def _has_parameter(known: list[str], key: str) -> bool:
    """Whether ``key`` names one of the ``known`` fields, with or without its unit suffix."""
    return key in known or any(
        "_" in n and n.rsplit("_", 1)[0] == key and n.rsplit("_", 1)[1] in (*UNITS, "n")
        for n in known
    )


def split_parameters(motions, parameters: dict | None) -> list[dict]:
    """Each motion's share of one set of ``KEY=VALUE`` parameters (as ``reproduce --param``
    gives them for a motion and the motions ``--add`` lays on it).

    A key goes to the one motion that has it (``drift=3mm`` to baseline_drift, whose field is
    ``drift_m``), or to the motion written in front of it (``heartbeat.amplitude=2mm``); every
    key goes to a motion alone.

    Args:
        motions: names of the library (:data:`LIBRARY`).  parameters: {key: value}.
    Returns:
        one dict per motion, in order.
    Raises:
        InvalidConfigError: an unknown motion, a key no motion has or several have (the
            message says to put the motion in front), a motion named that is not among them.
    """
    motions = list(motions)
    known = [parameter_names(m) for m in motions]
    out: list[dict] = [{} for _ in motions]
    for key, value in (parameters or {}).items():
        key = str(key).strip()
        motion, dot, bare = key.rpartition(".")
        if dot:
            if motion not in motions:
                raise InvalidConfigError(
                    f"parameter {key}: {motion!r} is not among the motions ({', '.join(motions)})"
                )
            out[motions.index(motion)][bare] = value
            continue
        owners = [i for i, names in enumerate(known) if _has_parameter(names, key)]
        if not owners and len(motions) == 1:
            owners = [0]  # make_motion names what is wrong
        if len(owners) != 1:
            raise InvalidConfigError(
                f"parameter {key}: "
                + (
                    f"{' and '.join(motions[i] for i in owners)} both have it; write the motion "
                    f"in front: {motions[owners[0]]}.{key}="
                    if owners
                    else f"none of {', '.join(motions)} has it; their parameters: "
                    + "; ".join(f"{m}: {', '.join(n)}" for m, n in zip(motions, known))
                )
            )
        out[owners[0]][key] = value
    return out


def make_layers(add: dict | None) -> tuple:
    """The motions of the library to lay on a reference (:func:`layered`), from {name:
    parameters} (:func:`make_motion` each).

    Raises:
        InvalidConfigError: as :func:`make_motion`.
    """
    return tuple(make_motion(str(name), dict(p or {})) for name, p in (add or {}).items())


class LayeredReference:
    """A reference with motions of the library laid on it: the reference's pose plus each
    motion's displacement from its own centre; rates and accelerations add alike. A baseline
    drift or an excursion on a recorded trace, as the phantoms' software adds them to a
    patient's file.

    The sum keeps what the reference says of itself: its ``centre`` (the fixed point of
    :class:`ScaledReference`), its ``start_time`` and ``end_time`` (a trace's length bounds the
    run) and its cycles (a layer does not move where the breaths begin: the reference's own,
    else those found where it peaks, :func:`~.motion.reference_cycles`); its frequencies are
    those of all.

    Args:
        reference: any :class:`~.motion.Reference` (a trace).  layers: motions of the library.
        name: label; default the names joined by "+".
    Raises:
        InvalidConfigError: a layer that is not a motion of the library.
    """

    def __init__(self, reference: Reference, layers, name: str | None = None):
        layers = tuple(layers)
        if not all(isinstance(m, _Motion) for m in layers):
            raise InvalidConfigError("layers must be motions of the library (make_motion)")
        self.reference, self.layers = reference, layers
        self.name = name or "+".join(
            [getattr(reference, "name", "reference")] + [m.name for m in layers]
        )
        centre = getattr(reference, "centre", None)
        self.centre = None if centre is None else tuple(float(v) for v in np.ravel(centre))
        for bound in ("start_time", "end_time"):
            if getattr(reference, bound, None) is not None:
                setattr(self, bound, getattr(reference, bound))

    def evaluate(self, t):
        """Pose, rate, acceleration at times t (s): three ``t.shape + (6,)`` arrays, rad and m."""
        t = np.asarray(t, dtype=float)
        shape = t.shape + (6,)
        out = [np.array(np.reshape(p, shape), dtype=float) for p in self.reference.evaluate(t)]
        for layer in self.layers:
            for acc, add in zip(out, layer.displacement(t.reshape(-1))):
                acc += add.reshape(shape)
        return tuple(out)

    def frequencies_hz(self) -> dict:
        out: dict = {}
        for part in (self.reference, *self.layers):
            f = getattr(part, "frequencies_hz", None)
            out.update(f() if callable(f) else {})
        return out

    @property
    def repeat_period_s(self) -> float | None:
        periods = [getattr(p, "repeat_period_s", None) for p in (self.reference, *self.layers)]
        return None if any(p is None for p in periods) else common_period(periods)

    def cycles(self, t_end: float):
        return reference_cycles(self.reference, t_end)


def layered(reference: Reference, layers, name: str | None = None) -> Reference:
    """``reference`` with the motions ``layers`` laid on it: itself when there are none, a
    :class:`MotionSum` about its centre when it is a motion of the library (breathing with a
    drift), else a :class:`LayeredReference` (a trace with a drift).

    Raises:
        InvalidConfigError: a layer that is not a motion of the library.
    """
    layers = tuple(layers)
    if not layers:
        return reference
    label = name or "+".join([getattr(reference, "name", "reference")] + [m.name for m in layers])
    if isinstance(reference, _Motion) and reference.centre is not None:
        if not all(isinstance(m, _Motion) for m in layers):
            raise InvalidConfigError("layers must be motions of the library (make_motion)")
        return MotionSum(parts=(reference, *layers), centre=reference.centre, name=label)
    return LayeredReference(reference, layers, label)


# -- scaling a reference into what the robot can do ----------------------------------------------


class ScaledReference:
    """A reference shrunk about its centre: centre + scale (x(t) - centre), rates and
    accelerations scaled alike.

    Args:
        reference: a :class:`~.motion.Reference` (its ``centre`` attribute, else its pose at
            t = 0, is the fixed point).  scale: in (0, 1].
    Raises:
        InvalidConfigError: a scale outside (0, 1].
    """

    def __init__(self, reference: Reference, scale: float):
        self.reference = reference
        self.scale = as_number("scale", scale, 0.0, 1.0, lo_open=True)
        centre = getattr(reference, "centre", None)
        self.centre = np.asarray(
            centre if centre is not None else np.ravel(reference.evaluate(0.0)[0]), dtype=float
        )
        self.name = getattr(reference, "name", "reference")
        self.end_time = getattr(reference, "end_time", None)

    def evaluate(self, t):
        x, v, a = self.reference.evaluate(t)
        s = self.scale
        return self.centre + s * (np.asarray(x) - self.centre), s * np.asarray(v), s * np.asarray(a)

    def frequencies_hz(self) -> dict:
        f = getattr(self.reference, "frequencies_hz", None)
        return f() if callable(f) else {}

    @property
    def repeat_period_s(self):
        return getattr(self.reference, "repeat_period_s", None)

    def cycles(self, t_end: float):
        return reference_cycles(self.reference, t_end)


def scaled(reference: Reference, scale: float) -> Reference:
    """``reference`` shrunk about its centre by ``scale`` (:class:`ScaledReference`), or itself
    when ``scale`` is 1."""
    return reference if scale == 1.0 else ScaledReference(reference, scale)


# -- a scenario's choice of a motion ---------------------------------------------------------------


@dataclass
class OrganMotionReference(ReferenceConfig):
    """A motion of the organ-motion library (:mod:`~.organ_motion`: breathing, heartbeat,
    breathing_heartbeat, irregular_breathing, hysteresis and the phantoms' sawtooth, sharkfin,
    baseline_drift, transient_excursion, persistent_excursion, breath_hold) with parameters
    carrying units, e.g.
    ``{amplitude: 15mm, period: 4s, direction: SI}`` (:func:`~.organ_motion.make_motion`).

    Attributes:
        motion: the library's name. parameters: name -> value (a number in the field's SI unit,
            or text with a unit). scale: the motion shrunk about its centre, in (0, 1]
            (``reproduce --scale-to-fit`` finds it). add: motions of the library laid on it,
            name -> parameters (``{baseline_drift: {drift: 3mm}}``, :func:`layered`).
    """

    motion: str = "breathing"
    parameters: dict[str, str] = field(default_factory=dict)
    scale: float = 1.0
    add: dict[str, dict[str, str]] = field(default_factory=dict)

    def validate(self) -> None:
        as_number("reference.scale", self.scale, 0.0, 1.0, lo_open=True)
        self._motion()  # names an unknown motion or parameter

    def make(
        self, geometry: StewartGeometry, duration_s: float, torque_limit_Nm: float | None
    ) -> Reference:
        return self._motion()

    def _motion(self) -> Reference:
        motion = layered(make_motion(self.motion, self.parameters), make_layers(self.add))
        return scaled(motion, self.scale)

    @property
    def label(self) -> str:
        return "+".join([self.motion, *self.add])


__all__ = [
    "Breathing",
    "Heartbeat",
    "MotionSum",
    "IrregularBreathing",
    "HysteresisBreathing",
    "Sawtooth",
    "Sharkfin",
    "BaselineDrift",
    "TransientExcursion",
    "PersistentExcursion",
    "BreathHold",
    "LayeredReference",
    "layered",
    "make_layers",
    "split_parameters",
    "LIBRARY",
    "make_motion",
    "parameter_names",
    "ScaledReference",
    "scaled",
    "axis_index",
    "check_centre",
    "common_period",
    "PATIENT_AXES",
    "UNITS",
    "OrganMotionReference",
]
