"""What every motion of the organ-motion library shares: the platform's and the patient's axes,
directions and centres, and the base class of the motions (:class:`LibraryMotion`: ``evaluate``
= centre + displacement, frequencies, repeat period, cycles).

Directions are vectors in the platform frame or axis names: the platform's ``X``, ``Y``, ``Z``
or the patient's ``SI``, ``LR``, ``AP`` (:data:`PATIENT_AXES`: the patient lies supine along
the platform's X axis, head towards +X, left towards +Y, anterior up), with an optional sign.
"""

import math
import re

import numpy as np

from ...base.checks import as_array, as_poses
from ...base.errors import InvalidConfigError
from ...robot.geometry import X_HOME
from ...robot.kinematics import AXIS_NAMES

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


def unit_direction(name: str, value, rotation: bool = False) -> tuple:
    """A unit 3-vector from a vector or an axis name (translation axes, or rotation axes when
    ``rotation``).

    Args:
        name: the field, for messages. value: 3 numbers (a sequence or "x,y,z") or an axis name
            with an optional sign (:func:`axis_index`). rotation: rotation axes (else
            translation axes).
    Returns:
        3 floats of norm 1, in the platform frame (of [X, Y, Z], or of [roll, pitch, yaw]).
    Raises:
        InvalidConfigError: an unknown axis, an axis of the other kind, not 3 finite numbers,
            the zero vector; names ``name``.
    """
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


class LibraryMotion:
    """What every motion of the library shares: ``evaluate`` = centre + displacement.

    A motion defines ``displacement(t)`` ((n,) times, s, to three (n, 6) arrays: displacement
    from ``centre``, rate, acceleration; rad and m) and, when it repeats, ``period_s``.
    """

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


def along(direction, shape, ds, dds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, 6) displacement, rate and acceleration of a scalar shape along a 3-vector direction
    (translation part).

    Args:
        direction: (3,) the direction (its length scales the shape), in the platform frame.
        shape, ds, dds: (n,) the shape, m (or dimensionless with a direction in m), and its first
            and second time derivatives, per s and per s^2.
    Returns:
        three (n, 6) arrays, rotations zero, [rad, rad, rad, m, m, m] and their rates.
    """
    out = []
    for part in (shape, ds, dds):
        a = np.zeros((len(shape), 6))
        a[:, 3:] = part[:, None] * np.asarray(direction)
        out.append(a)
    return out[0], out[1], out[2]


__all__ = [
    "PATIENT_AXES",
    "axis_index",
    "unit_direction",
    "check_centre",
    "LibraryMotion",
    "along",
]
