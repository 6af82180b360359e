"""What a loop must survive of what the catalogue does not know, and the scan that finds it.

Every loop we ship (the paper's LQI, the crank servo, the servos' own position loop) meets a
plant its design did not: the motor's torque per ampere departs from its stall ratio by the gears'
losses unit to unit, and the catalogue's rotor inertia is uncertain by a factor of about 2
(docs/motor_catalogue.md), so the plant's gain ``g`` (true torque per command over the believed,
times the believed inertia over the true) lies in :data:`GAIN_RANGE`; and a command may act later
than designed for: a sync read and its USB adapter take about 2 ms on the bus, a late write more
(:data:`EXTRA_DELAY_S`: the bus's own and 4 ms). Ours, not the paper's: the paper states no
robustness requirement (docs/paper_notes.md).

:func:`stable_gain_range` scans the gains about 1 for which a loop's exact sampled model is
stable (each loop's model is its module's: :mod:`.servo.margins`,
:mod:`stewart_drake.station.bus.position_margins`, :func:`lqi_spectral_radius`);
:class:`RobustRange` is what a loop was found to survive, and whether that holds the requirement.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..base.checks import as_number

#: The plant gains a shipped loop must survive (module docstring).
GAIN_RANGE = (0.5, 2.0)
#: The delay beyond the design's a shipped host loop must survive, s: the bus's own (a sync read
#: and its adapter, about 2 ms) and 4 ms more.
EXTRA_DELAY_S = 6e-3


def stable_gain_range(stable: Callable[[float], bool], steps: int = 400) -> tuple[float, float]:
    """(lowest, highest) plant gain about 1 for which ``stable(g)`` holds without a break,
    scanned on a log grid from 1/100 to 100 (``steps`` gains) and each edge refined by bisection
    to 0.1 %; an end of the grid when the loop is stable to it; (nan, nan) when it is unstable
    at gain 1.

    Raises:
        InvalidConfigError: ``steps`` below 3.
    """
    steps = int(as_number("steps", steps, 3))
    if not stable(1.0):
        return (math.nan, math.nan)
    grid = np.exp(np.linspace(math.log(0.01), math.log(100.0), steps))
    ends = []
    for side in (grid[grid < 1.0][::-1], grid[grid > 1.0]):
        inside = 1.0
        for g in side:
            if not stable(float(g)):
                outside = float(g)
                while abs(math.log(outside / inside)) >= 1e-3:
                    mid = math.sqrt(inside * outside)
                    inside, outside = (mid, outside) if stable(mid) else (inside, mid)
                ends.append(inside)
                break
            inside = float(g)
        else:
            ends.append(inside)
    return (ends[0], ends[1])


@dataclass(frozen=True)
class RobustRange:
    """What a loop survives: its stable plant gains, and with the extra delay it is asked to.

    Attributes:
        loop: the loop, in words (its kind, its rates).
        gains: (lowest, highest) stable plant gain with the design's own delay ((nan, nan):
            unstable as designed).
        delayed_gains: the same with ``extra_delay_s`` more delay.
        extra_delay_s: the delay beyond the design's asked of it, s (0: none inside this loop:
            the servos' own loop, whose bus delay is outside it).
        required: the plant gains it must survive (:data:`GAIN_RANGE`).
        notes: what else the loop's margins say, one line each.
    """

    loop: str
    gains: tuple[float, float]
    delayed_gains: tuple[float, float]
    extra_delay_s: float
    required: tuple[float, float] = GAIN_RANGE
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def holds(self) -> bool:
        """Whether the required gains are stable with the extra delay (NaN ranges never hold)."""
        lo, hi = self.delayed_gains
        return bool(lo <= self.required[0] and hi >= self.required[1])

    def verdict(self) -> str:
        """One line: holds or does NOT hold, what, and the range found."""
        lo, hi = self.delayed_gains
        found = "unstable at gain 1" if math.isnan(lo) else f"stable {lo:.2f} to {hi:.2f}"
        delay = (
            f" with {1e3 * self.extra_delay_s:g} ms more delay" if self.extra_delay_s > 0 else ""
        )
        return (
            f"{'holds' if self.holds else 'does NOT hold'} gain {self.required[0]:g} to "
            f"{self.required[1]:g}{delay} ({found})"
        )

    def record(self) -> dict:
        """Plain JSON values (NaN as None)."""

        def plain(pair):
            return [None if math.isnan(v) else float(v) for v in pair]

        out = dataclasses.asdict(self)
        out.update(
            gains=plain(self.gains),
            delayed_gains=plain(self.delayed_gains),
            required=list(self.required),
            notes=list(self.notes),
            holds=self.holds,
        )
        return out


def lqi_spectral_radius(models, plant_of_delay, gain: float, extra_periods: int) -> float:
    """The largest |eigenvalue| of the LQI's closed loop (:func:`~.linear_model.closed_loop`)
    with the plant's torque ``gain`` times the believed and ``extra_periods`` more periods of
    delay before it acts.

    Args:
        models: the loop's linear models (``controller`` and ``J`` of
            :class:`~stewart_drake.analysis.loop_analysis.LoopModels`).
        plant_of_delay: the plant model (:func:`~.linear_model.plant_model`) for a number of
            extra periods of delay.
    """
    from .linear_model import closed_loop

    plant = plant_of_delay(int(extra_periods))
    scaled = dataclasses.replace(plant, B=plant.B * float(gain))
    return float(
        np.abs(np.linalg.eigvals(closed_loop(scaled, models.controller, models.J).A)).max()
    )


__all__ = [
    "EXTRA_DELAY_S",
    "GAIN_RANGE",
    "RobustRange",
    "lqi_spectral_radius",
    "stable_gain_range",
]
