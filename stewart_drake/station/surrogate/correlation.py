"""The external signal of a library motion: the internal motion along its main direction, through
a correlation model (amplitude ratio, phase lead, baseline drift of the external alone, and a
change of lead and ratio mid-run), each from the literature (docs/surrogate.md, "Sources").

    e(t) = k(t) s(t + tau(t)) + drift t,

s the internal's displacement along its first principal direction
(:func:`~stewart_drake.base.signals.principal_displacement`), k and tau the ratio and lead,
each going from its value before ``change_at_s`` to its value after over ``change_blend_s`` by
the quintic smoothstep. In the (internal, external) plane a lead draws the hysteresis loop, of area
pi A_i A_e sin(2 pi tau / T) per cycle on a sine of period T (:func:`sine_loop_area`).
"""

import math
from dataclasses import dataclass

import numpy as np

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...references.smoothstep import smoothstep


@dataclass
class CorrelationModel:
    """How the external follows the internal (module docstring); SI units.

    Attributes:
        amplitude_ratio: external m per internal m along its main direction (k).
        lead_s: the external's lead, s (> 0: the chest moves first; Hoisak et al. 2004 measured
            -0.65 to +0.50 s between tumour and abdominal surrogate).
        drift_m_per_s: the external's baseline drift, m/s; the internal keeps its baseline.
        change_at_s: when the relationship changes, s, or None: never.
        lead_after_s, ratio_after: the lead and ratio after the change (None: unchanged).
        change_blend_s: how long the change takes, s.
    """

    amplitude_ratio: float = 1.0
    lead_s: float = 0.0
    drift_m_per_s: float = 0.0
    change_at_s: float | None = None
    lead_after_s: float | None = None
    ratio_after: float | None = None
    change_blend_s: float = 1.0

    def validate(self) -> "CorrelationModel":
        """Check the fields. Raises: InvalidConfigError naming ``surrogate.correlation.*``."""
        p = "surrogate.correlation."
        as_number(p + "amplitude_ratio", self.amplitude_ratio, -20.0, 20.0)
        if self.amplitude_ratio == 0:
            raise InvalidConfigError(p + "amplitude_ratio must not be 0 (no external motion)")
        as_number(p + "lead_s", self.lead_s, -5.0, 5.0)
        as_number(p + "drift_m_per_s", self.drift_m_per_s, -1e-3, 1e-3)
        as_number(p + "change_blend_s", self.change_blend_s, 0.0, 60.0, lo_open=True)
        if self.change_at_s is None:
            if self.lead_after_s is not None or self.ratio_after is not None:
                raise InvalidConfigError(
                    p + "lead_after_s and ratio_after need change_at_s: when the change happens"
                )
        else:
            as_number(p + "change_at_s", self.change_at_s, 0.0)
            if self.lead_after_s is not None:
                as_number(p + "lead_after_s", self.lead_after_s, -5.0, 5.0)
            if self.ratio_after is not None:
                as_number(p + "ratio_after", self.ratio_after, -20.0, 20.0)
        return self

    def _blend(self, t: np.ndarray, before: float, after: float | None) -> np.ndarray:
        if self.change_at_s is None or after is None:
            return np.full_like(t, before)
        w = smoothstep((t - self.change_at_s) / self.change_blend_s + 0.5)[0]
        return before + (after - before) * w

    def lead(self, t: np.ndarray) -> np.ndarray:
        """tau(t), s, (n,)."""
        return self._blend(np.asarray(t, float), self.lead_s, self.lead_after_s)

    def ratio(self, t: np.ndarray) -> np.ndarray:
        """k(t), (n,)."""
        return self._blend(np.asarray(t, float), self.amplitude_ratio, self.ratio_after)

    def max_lead_s(self) -> float:
        """The largest |lead| the model asks for, s."""
        return max(abs(self.lead_s), abs(self.lead_after_s or 0.0))

    def external(self, t: np.ndarray, internal) -> np.ndarray:
        """e(t) (module docstring), m.

        Args:
            t: (n,) s. internal: a callable s(t) -> (n,) m, defined over t + tau(t).
        """
        t = np.asarray(t, float)
        return self.ratio(t) * internal(t + self.lead(t)) + self.drift_m_per_s * t


def sine_loop_area(amplitude_i: float, amplitude_e: float, lead_s: float, period_s: float):
    """The loop a sine pair encloses per cycle, m^2: pi A_i A_e sin(2 pi lead / period) (the
    shoelace formula over one cycle of (A_i sin w t, A_e sin w (t + lead)))."""
    return math.pi * amplitude_i * amplitude_e * math.sin(2 * math.pi * lead_s / period_s)
