"""The units a user writes beside a number (``15mm``, ``0.1deg``, ``4s``, ``12bpm``), one table
for every reader, and the one reader of a length with an angle (``0.1mm,0.1deg``): verify's and
reproduce's tolerance and action level, calibrate's tracker noise.

A unit is written as in :data:`UNITS` or all in capitals (``0.1MM``, as a device's display has
it); a mixed case is refused, ``0.05Mm`` being no millimetre.
"""

from __future__ import annotations

import math
import re

from .errors import InvalidConfigError

#: Each quantity's units and their factors to SI (m, rad, s; beats a minute).
UNITS = {
    "m": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6},
    "rad": {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180},
    "s": {"s": 1.0, "ms": 1e-3, "min": 60.0},
    "bpm": {"bpm": 1.0, "/min": 1.0, "hz": 60.0},
}
LENGTH_UNITS = UNITS["m"]
ANGLE_UNITS = UNITS["rad"]

_QUANTITY = re.compile(r"\s*((?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Z]+)\s*")


def length_and_angle(
    text: str,
    option: str,
    maximum: tuple[float, float],
    beyond: str,
    example: str = "0.1mm,0.1deg",
    zero: bool = False,
) -> tuple[float, float]:
    """(m, rad) of "LENGTH,ANGLE", each a number with its unit (lengths m, cm, mm, um; angles
    rad, mrad, urad, deg; either order).

    Args:
        text: what the user wrote.
        option: the option it came from, named by every refusal ("--tolerance").
        maximum: the largest (m, rad) taken.
        beyond: why a larger one is refused, in words ("at most 1 m and 180 deg (...)").
        example: a good value, shown by a refusal.
        zero: whether 0 is taken (a tracker's noise may be none; a tolerance may not).

    Raises:
        InvalidConfigError: naming ``option``: not one length and one angle, each a finite
            number with its unit, positive (or 0 with ``zero``), at most ``maximum``.
    """
    units = ", ".join([*LENGTH_UNITS, *ANGLE_UNITS])
    sign = "non-negative" if zero else "positive"
    found: dict[str, float] = {}
    for part in str(text).split(","):
        m = _QUANTITY.fullmatch(part)
        unit = m.group(2) if m else ""
        unit = unit.lower() if unit.isupper() else unit
        kind = next((k for k in ("m", "rad") if unit in UNITS[k]), None)
        value = float(m.group(1)) if m else math.nan
        allowed = value > 0 or (zero and value == 0)
        if kind is None or kind in found or not (allowed and value < math.inf):
            why = f"the unit {unit!r} is not one of {units}" if m and kind is None else (
                f"each a finite {sign} number with its unit"
            )  # fmt: skip
            raise InvalidConfigError(
                f"{option}: one length and one angle, {why}, e.g. {example}; got {text!r}"
            )
        found[kind] = value * UNITS[kind][unit]
    if len(found) != 2:
        raise InvalidConfigError(
            f"{option}: one length and one angle, e.g. {example}; got {text!r}"
        )
    if found["m"] > maximum[0] or found["rad"] > maximum[1]:
        raise InvalidConfigError(f"{option}: {beyond}; got {text!r}")
    return found["m"], found["rad"]


__all__ = ["ANGLE_UNITS", "LENGTH_UNITS", "UNITS", "length_and_angle"]
