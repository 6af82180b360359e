"""What a reproduced pair is judged by: each motion's fidelity, their relative latency, and the
pair's relationship as reproduced against as asked (:mod:`.sync_figures`, the one definition of
each figure), with the lines a command prints and the command-line form of a correlation model.
"""

import re

import numpy as np

from ...base.errors import InvalidConfigError
from ...base.measures import rms_per_axis
from ...base.signals import principal_displacement
from .correlation import CorrelationModel
from .sync_figures import pair_figures, relative_latency

#: ``--surrogate-param`` keys: the :class:`~.correlation.CorrelationModel` field each sets.
MODEL_KEYS = {
    "ratio": "amplitude_ratio",
    "lead": "lead_s",
    "drift": "drift_m_per_s",
    "change_at": "change_at_s",
    "lead_after": "lead_after_s",
    "ratio_after": "ratio_after",
    "blend": "change_blend_s",
}
#: Units a value may carry: factor to SI.
_UNITS = {"": 1.0, "s": 1.0, "ms": 1e-3, "m/s": 1.0, "mm/s": 1e-3, "mm/min": 1e-3 / 60}
#: The figures compared to 5 %, as asked against as reproduced (the pair's relationship).
COMPARED = ("lead_s", "hysteresis_area_m2", "correlation", "amplitude_ratio")


def correlation_model(items) -> CorrelationModel:
    """The :class:`~.correlation.CorrelationModel` of ``KEY=VALUE`` words (:data:`MODEL_KEYS`;
    values with a unit of ``s``, ``ms``, ``mm/s``, ``mm/min``, ``m/s`` or none), validated.

    Raises:
        InvalidConfigError: an unknown key (the keys listed), a value that is not a number with
            one of those units, a model refused by its validation.
    """
    fields = {}
    for item in items or ():
        key, _, value = item.partition("=")
        if key not in MODEL_KEYS:
            raise InvalidConfigError(
                f"--surrogate-param {item!r}: the keys are {', '.join(MODEL_KEYS)}"
            )
        match = re.fullmatch(r"\s*([-+0-9.eE]+)\s*([a-z/]*)\s*", value)
        if match is None or match.group(2) not in _UNITS:
            raise InvalidConfigError(
                f"--surrogate-param {item!r}: a number with a unit of "
                f"{', '.join(u for u in _UNITS if u)} (or none)"
            )
        try:
            number = float(match.group(1))
        except ValueError:
            raise InvalidConfigError(f"--surrogate-param {item!r}: not a number") from None
        fields[MODEL_KEYS[key]] = number * _UNITS[match.group(2)]
    return CorrelationModel(**fields).validate()


def pair_report(t, x, x_d, p, p_asked, window: tuple, split_s: float | None = None) -> dict:
    """The figures of a reproduced pair over ``window``.

    Args:
        t: (n,) uniform s. x, x_d: (n, >= 6) the platform's pose as reproduced and as asked
            [rad, m]. p, p_asked: (n,) the surrogate as reproduced and as asked, m.
        window: (t0, t1) s, the measured window. split_s: when the relationship changes, s.
    Returns:
        {"window_s", "internal_rms_m" (3,) per translation axis, "external_rms_m",
        "direction" (3,), "latency" (:func:`~.sync_figures.relative_latency`), "asked",
        "reproduced" (:func:`~.sync_figures.pair_figures` each), "match" {figure: relative
        difference}}.
    """
    t = np.asarray(t, float)
    keep = (t >= window[0]) & (t <= window[1])
    tk = t[keep]
    xi = np.asarray(x, float)[keep, 3:6]
    xa = np.asarray(x_d, float)[keep, 3:6]
    pk, pa = np.asarray(p, float)[keep], np.asarray(p_asked, float)[keep]
    s_asked, u = principal_displacement(xa)
    s_meas = (xi - xa.mean(axis=0)) @ u
    asked = pair_figures(tk, s_asked, pa, split_s)
    reproduced = pair_figures(tk, s_meas, pk, split_s)
    match = {
        k: abs(reproduced[k] - asked[k]) / abs(asked[k]) for k in COMPARED if abs(asked[k]) > 1e-12
    }
    return {
        "window_s": (float(tk[0]), float(tk[-1])),
        "internal_rms_m": rms_per_axis(xi - xa).tolist(),
        "external_rms_m": float(np.sqrt(np.mean((pk - pa) ** 2))),
        "direction": u.tolist(),
        "latency": relative_latency(tk, xa, xi, pa, pk),
        "asked": asked,
        "reproduced": reproduced,
        "match": match,
    }


def report_lines(fig: dict) -> list[str]:
    """The lines a command prints for :func:`pair_report`'s figures."""
    lat, a, r = fig["latency"], fig["asked"], fig["reproduced"]
    lines = [
        f"surrogate: RMS error {fig['external_rms_m'] * 1e6:.3g} um against its signal; "
        f"internal target RMS {max(fig['internal_rms_m']) * 1e6:.3g} um (worst axis)",
        f"relative latency {lat['relative_latency_s'] * 1e3:+.3g} ms (target lag "
        f"{lat['lag_internal_s'] * 1e3:+.3g} ms less surrogate lag "
        f"{lat['lag_external_s'] * 1e3:+.3g} ms; > 0: the target late, < 0: the surrogate late)",
        f"lead of the external: asked {a['lead_s']:+.3f} s, reproduced {r['lead_s']:+.3f} s",
        f"hysteresis area per cycle: asked {a['hysteresis_area_m2'] * 1e6:+.3g} mm^2, "
        f"reproduced {r['hysteresis_area_m2'] * 1e6:+.3g} mm^2",
        f"correlation: asked {a['correlation']:.4f}, reproduced {r['correlation']:.4f}; "
        f"amplitude ratio asked {a['amplitude_ratio']:.4f}, reproduced "
        f"{r['amplitude_ratio']:.4f}",
    ]
    if "lead_before_s" in a:
        lines.append(
            f"lead before/after the change: asked {a['lead_before_s']:+.3f}/"
            f"{a['lead_after_s']:+.3f} s, reproduced {r['lead_before_s']:+.3f}/"
            f"{r['lead_after_s']:+.3f} s"
        )
    return lines
