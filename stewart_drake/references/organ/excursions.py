"""The motion phantoms' one-off displacements: a drift of the mean position
(:class:`BaselineDrift`), an excursion away and back (:class:`TransientExcursion`) and a step to
a new baseline (:class:`PersistentExcursion`), each a C2 profile of the quintic smoothstep
(:func:`~.smoothstep.smoothstep`) along a direction, on one base (:class:`Excursion`) that checks
their shared fields.

A drift or an excursion is a displacement alone; :func:`~.combinators.layered` lays it on
another motion or on a recorded trace (``reproduce breathing --add baseline_drift``, a
scenario's ``add``).
"""

import math
from dataclasses import dataclass

import numpy as np

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.geometry import X_HOME
from ..smoothstep import smooth_ramp, smoothstep
from .core import LibraryMotion, along, check_centre, unit_direction


class Excursion(LibraryMotion):
    """A one-off displacement along a direction (no breathing): what the phantoms add to a
    motion (:func:`~.combinators.layered`) or run alone. It does not repeat: no cycles of its
    own.

    An excursion names its fields by their role (class attributes, not fields): ``size_field``
    (the displacement, m, signed, at most 1 m in size), ``start_field`` (when it begins, s,
    >= 0), ``ramp_field`` (the time its smooth steps take, s, > 0) and ``direction_field``
    (a unit vector or axis name); its ``__post_init__`` calls :meth:`_check_size_and_start`,
    then checks its own fields, then :meth:`_check_ramp` and :meth:`_check_direction`, each
    naming the field it refuses.
    """

    size_field = start_field = ramp_field = direction_field = ""

    def _check_size_and_start(self) -> None:
        _set, n = object.__setattr__, self.name
        size, start = self.size_field, self.start_field
        _set(self, size, as_number(f"{n}: {size}", getattr(self, size), -1.0, 1.0))
        _set(self, start, as_number(f"{n}: {start}", getattr(self, start), 0.0))

    def _check_ramp(self, longest: float | None = None, of: str = "") -> None:
        """The ramp's time, > 0 s and, with ``longest``, at most that (half of ``of``)."""
        n, ramp = self.name, self.ramp_field
        value = as_number(f"{n}: {ramp}", getattr(self, ramp), 0.0, lo_open=True)
        if longest is not None and value > longest:
            raise InvalidConfigError(
                f"{n}: {ramp} must be at most half {of} ({longest:g} s), got {value:g}"
            )
        object.__setattr__(self, ramp, value)

    def _check_direction(self) -> None:
        field_name = self.direction_field
        value = unit_direction(f"{self.name}: {field_name}", getattr(self, field_name))
        object.__setattr__(self, field_name, value)
        object.__setattr__(self, "centre", check_centre(self.name, self.centre))

    @property
    def _unit(self):
        return np.asarray(getattr(self, self.direction_field))

    def _profile(self, t):  # pragma: no cover - every excursion defines it
        """(s, ds/dt, d2s/dt2) of the displacement along the direction, m."""
        raise NotImplementedError

    def displacement(self, t):
        """(n, 6) displacement, rate, acceleration from the centre at times t (n,)."""
        s, ds, dds = self._profile(np.asarray(t, dtype=float))
        return along(self._unit, s, ds, dds)


@dataclass(frozen=True)
class BaselineDrift(Excursion):
    """A slow drift of the mean position: linear (by ``drift_m`` over ``drift_duration_s``,
    then held) or sinusoidal (between 0 and ``drift_m`` every ``drift_period_s``).

    The continuous drift of the phantoms' library (CIRS Motion Control for the Dynamic Pelvis
    phantom, model 008P), after the continuous target drift Langen et al. (IJROBP 71, 1084,
    2008) saw in prostates tracked electromagnetically. Linear: the rate rises from 0 to
    drift_m / (drift_duration_s - drift_rounding_s) over ``drift_rounding_s`` (a quintic
    smoothstep), holds, and falls back to 0 over the drift's last ``drift_rounding_s``: the
    position reaches ``drift_m`` at drift_start_s + drift_duration_s. Sinusoidal:
    drift_m (1 - cos(2 pi (t - t0) / drift_period_s)) / 2 faded in by a smoothstep over
    ``drift_rounding_s``. Laid on breathing (:func:`~.combinators.layered`, ``reproduce
    breathing --add baseline_drift``) it moves the breathing's mean position.

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

    size_field, start_field = "drift_m", "drift_start_s"
    ramp_field, direction_field = "drift_rounding_s", "drift_direction"

    def __post_init__(self):
        _set, n = object.__setattr__, self.name
        self._check_size_and_start()
        duration = as_number(f"{n}: drift_duration_s", self.drift_duration_s, 0.0, lo_open=True)
        period = as_number(f"{n}: drift_period_s", self.drift_period_s, 0.0, 1e6)
        longest = 0.5 * (period if period > 0 else duration)
        self._check_ramp(longest, f"the drift's {'period' if period > 0 else 'duration'}")
        _set(self, "drift_duration_s", duration)
        _set(self, "drift_period_s", period)
        self._check_direction()

    def _profile(self, t):
        r, t0, b = self.drift_rounding_s, self.drift_start_s, self.drift_m
        if self.drift_period_s == 0.0:
            slope = b / (self.drift_duration_s - r)
            J1, S1, dS1 = smooth_ramp((t - t0) / r)
            J2, S2, dS2 = smooth_ramp((t - t0 - self.drift_duration_s + r) / r)
            return slope * r * (J1 - J2), slope * (S1 - S2), slope * (dS1 - dS2) / r
        w = 2.0 * math.pi / self.drift_period_s
        u = np.maximum(t - t0, 0.0)
        y, dy, ddy = 0.5 * b * (1 - np.cos(w * u)), 0.5 * b * w * np.sin(w * u), 0.5 * b * w * w
        ddy = ddy * np.cos(w * u)
        S, dS, ddS = smoothstep(u / r)
        dS, ddS = dS / r, ddS / r**2
        return S * y, S * dy + dS * y, S * ddy + 2.0 * dS * dy + ddS * y


@dataclass(frozen=True)
class TransientExcursion(Excursion):
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

    size_field, start_field = "excursion_m", "excursion_start_s"
    ramp_field, direction_field = "excursion_rise_s", "excursion_direction"

    def __post_init__(self):
        self._check_size_and_start()
        duration = as_number(
            f"{self.name}: excursion_duration_s", self.excursion_duration_s, 0.0, lo_open=True
        )
        self._check_ramp(0.5 * duration, "excursion_duration_s")
        object.__setattr__(self, "excursion_duration_s", duration)
        self._check_direction()

    def _profile(self, t):
        r, t0, b = self.excursion_rise_s, self.excursion_start_s, self.excursion_m
        up = smoothstep((t - t0) / r)
        down = smoothstep((t - t0 - self.excursion_duration_s + r) / r)
        return b * (up[0] - down[0]), b * (up[1] - down[1]) / r, b * (up[2] - down[2]) / r**2


@dataclass(frozen=True)
class PersistentExcursion(Excursion):
    """A persistent excursion: a smooth step to a new baseline that stays,
    s(t) = shift_m S((t - shift_start_s) / shift_rise_s), S the quintic smoothstep.

    The persistent excursion of the phantoms' library (CIRS Motion Control for the Dynamic
    Pelvis phantom), after Langen et al. (IJROBP 71, 1084, 2008): a prostate that moves to a
    new position and stays there; a baseline shift of breathing when laid on it
    (:func:`~.combinators.layered`).

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

    size_field, start_field = "shift_m", "shift_start_s"
    ramp_field, direction_field = "shift_rise_s", "shift_direction"

    def __post_init__(self):
        self._check_size_and_start()
        self._check_ramp()
        self._check_direction()

    def _profile(self, t):
        r = self.shift_rise_s
        S, dS, ddS = smoothstep((t - self.shift_start_s) / r)
        return self.shift_m * S, self.shift_m * dS / r, self.shift_m * ddS / r**2


__all__ = ["Excursion", "BaselineDrift", "TransientExcursion", "PersistentExcursion"]
