"""What a shaper did, counted in its state (:mod:`.shaping`): the counts' order in the state, how
a period adds to them, and the record they make (:class:`ShapingRecord`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The flags of a shaped period (:meth:`~.shaping.Shaper.step`'s second value; 0: the followed
#: reference): shaped, stopped short of a pose not admissible, its acceleration clipped to the
#: box of the limits, scaled for a motor's torque or speed, a motor over its limit regardless.
SHAPED_FLAG, LIMITED_FLAG, CLIPPED_FLAG, SCALED_FLAG, OVER_FLAG = 1, 2, 4, 8, 16


@dataclass
class ShapingRecord:
    """What a :class:`~.shaping.Shaper` did, period by period.

    Attributes:
        period_s: the control period, s. periods: periods stepped.
        shaped: periods whose reference was not the followed one.
        limited: of them, periods stopped short of a pose that is not admissible.
        clipped: periods whose acceleration was clipped to the box of the limits (or for the
            rate's) while stopped short of a pose (the approach and coming to rest not
            counted).
        scaled: periods whose acceleration was scaled for a motor's torque or speed.
        over: periods where even no acceleration left a motor over its torque or speed limit
            (the validator refuses such a reference; never seen on a motion that fits).
        departure_m, departure_rad: the largest distance of the shaped pose from the followed
            one, translation (3-D) in m and rotation (roll, pitch, yaw as a 3-vector) in rad.
        first_shaped_s, first_limited_s: when it was first shaped, first stopped short, s
            (None: never).
        joined_s: when the reference first was the followed one, s (None: never); approach:
            the periods before, the reference going from where it started (where the robot
            rests, live) towards the followed one, not counted as shaped.
    """

    period_s: float
    periods: int = 0
    approach: int = 0
    joined_s: float | None = None
    shaped: int = 0
    limited: int = 0
    clipped: int = 0
    scaled: int = 0
    over: int = 0
    departure_m: float = 0.0
    departure_rad: float = 0.0
    first_shaped_s: float | None = None
    first_limited_s: float | None = None

    #: Its counts' order in the shaper's state (:data:`~.shaping.Shaper.RECORD`); a time not yet
    #: reached is NaN there.
    FIELDS = (
        "periods", "approach", "joined_s", "shaped", "limited", "clipped", "scaled", "over",
        "departure_m", "departure_rad", "first_shaped_s", "first_limited_s",
    )  # fmt: skip
    _TIMES = ("joined_s", "first_shaped_s", "first_limited_s")

    @classmethod
    def initial_values(cls) -> np.ndarray:
        """(len(:data:`FIELDS`),) the counts of no period: zeros, NaN for the times."""
        return np.array([np.nan if f in cls._TIMES else 0.0 for f in cls.FIELDS])

    @classmethod
    def from_values(cls, period_s: float, values) -> ShapingRecord:
        """The record the counts ``values`` (in the order of :data:`FIELDS`) say."""
        out: dict = {}
        for name, v in zip(cls.FIELDS, np.asarray(values, dtype=float), strict=True):
            if name in cls._TIMES:
                out[name] = None if np.isnan(v) else float(v)
            elif name.startswith("departure"):
                out[name] = float(v)
            else:
                out[name] = int(v)
        return cls(period_s, **out)

    def as_dict(self) -> dict:
        """The record as plain numbers (the JSON's ``shaping``)."""
        keys: tuple[str, ...] = (
            "period_s", "periods", "approach", "shaped", "limited", "clipped", "scaled", "over",
            "joined_s",
        )  # fmt: skip
        out: dict = {k: getattr(self, k) for k in keys}
        out |= {
            "departure_m": self.departure_m,
            "departure_rad": self.departure_rad,
            "first_shaped_s": self.first_shaped_s,
            "first_limited_s": self.first_limited_s,
        }
        return out

    def words(self) -> str:
        """One clause: how many periods were shaped, by how much and why."""
        if self.joined_s is None:
            return (
                f"never joined the followed reference in {self.periods} periods: it could not "
                "be reached within the robot's limits"
            )
        if not self.shaped:
            joined = f" from t = {self.joined_s:.3f} s" if self.approach else ""
            return (
                f"the followed reference within the robot's limits throughout{joined} "
                f"({self.periods - self.approach} periods): not shaped, the pose admissible "
                "throughout"
            )
        h = self.period_s
        why = [
            f"stopped short of a pose not admissible for {self.limited * h:.3g} s from "
            f"t = {self.first_limited_s:.3f} s"
            if self.limited
            else "the pose admissible throughout",
            f"the acceleration scaled for a motor's torque or speed in {self.scaled}",
        ]
        if self.clipped:
            why.append(f"clipped to the box of the limits in {self.clipped}")
        if self.over:
            why.append(f"a motor over its limit even without acceleration in {self.over}")
        why.append("going back onto the followed reference in the others")
        joined = (
            f"joined the followed reference at t = {self.joined_s:.3f} s, from where it started; "
            if self.approach
            else ""
        )
        return joined + (
            f"shaped to the robot's limits in {self.shaped} of {self.periods} periods "
            f"({self.shaped * h:.3g} s, from t = {self.first_shaped_s:.3f} s), at most "
            f"{self.departure_m * 1e3:.3g} mm and {math.degrees(self.departure_rad):.3g} deg from "
            f"the followed reference ({'; '.join(why)})"
        )


_R = {name: i for i, name in enumerate(ShapingRecord.FIELDS)}


def count_joined(r: np.ndarray, t: float, count: int = 1) -> None:
    """Count in the record's values ``r`` (:data:`ShapingRecord.FIELDS`) ``count`` periods
    given the followed reference as it was, the first at ``t`` (s)."""
    r[_R["periods"]] += count
    if np.isnan(r[_R["joined_s"]]):
        r[_R["joined_s"]] = t


def count_shaped(r: np.ndarray, t: float, what: int, gap) -> None:
    """Count in ``r`` a shaped period at ``t`` (s): ``what`` (the flags above) and
    ``gap`` (6,) the shaped pose minus the followed one (None: nothing followed). Before the
    reference first joins the followed one, the period is the approach (not counted as
    shaped)."""
    r[_R["periods"]] += 1
    if np.isnan(r[_R["joined_s"]]):
        r[_R["approach"]] += 1
        return
    r[_R["shaped"]] += 1
    if np.isnan(r[_R["first_shaped_s"]]):
        r[_R["first_shaped_s"]] = t
    if what & LIMITED_FLAG:
        r[_R["limited"]] += 1
        if np.isnan(r[_R["first_limited_s"]]):
            r[_R["first_limited_s"]] = t
    r[_R["clipped"]] += bool(what & CLIPPED_FLAG)
    r[_R["scaled"]] += bool(what & SCALED_FLAG)
    r[_R["over"]] += bool(what & OVER_FLAG)
    if gap is not None:
        r[_R["departure_m"]] = max(r[_R["departure_m"]], float(np.linalg.norm(gap[3:])))
        r[_R["departure_rad"]] = max(r[_R["departure_rad"]], float(np.linalg.norm(gap[:3])))


__all__ = [
    "ShapingRecord",
    "SHAPED_FLAG",
    "LIMITED_FLAG",
    "CLIPPED_FLAG",
    "SCALED_FLAG",
    "OVER_FLAG",
    "count_joined",
    "count_shaped",
]
