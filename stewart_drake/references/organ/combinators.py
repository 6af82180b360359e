"""References combined: the sum of references (:class:`MotionSum`), motions of the library laid
on any reference (:func:`layered`, :class:`LayeredReference`) and a reference shrunk about its
centre (:func:`scaled`, :class:`ScaledReference`:
:func:`~stewart_drake.organ_motion.reproduction.scale_to_fit` finds the scale the one reference
validator accepts).
"""

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.geometry import X_HOME
from ..motion import Reference, peak_cycles, reference_cycles
from .core import LibraryMotion, check_centre


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
class MotionSum(LibraryMotion):
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
            if not self.parts or not all(isinstance(p, LibraryMotion) for p in self.parts):
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
        if not all(isinstance(m, LibraryMotion) for m in layers):
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
    if isinstance(reference, LibraryMotion) and reference.centre is not None:
        if not all(isinstance(m, LibraryMotion) for m in layers):
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


__all__ = [
    "common_period",
    "MotionSum",
    "LayeredReference",
    "layered",
    "ScaledReference",
    "scaled",
]
