"""What a pair reproduced in the Diagram (``reproduce ... --surrogate``) is judged by: each
motion's fidelity, their relative latency, and the pair's relationship as reproduced against as
asked (:mod:`stewart_drake.base.pair_figures`, the one definition of each figure), with the lines
the command prints.
"""

import numpy as np

from ..base.measures import rms_per_axis
from ..base.pair_figures import pair_figures, relative_latency
from ..base.signals import principal_displacement

#: The figures compared to 5 %, as asked against as reproduced (the pair's relationship).
COMPARED = ("lead_s", "hysteresis_area_m2", "correlation", "amplitude_ratio")


def pair_report(t, x, x_d, p, p_asked, window: tuple, split_s: float | None = None) -> dict:
    """The figures of a reproduced pair over ``window``.

    Args:
        t: (n,) uniform s. x, x_d: (n, >= 6) the platform's pose as reproduced and as asked
            [rad, m]. p, p_asked: (n,) the surrogate as reproduced and as asked, m.
        window: (t0, t1) s, the measured window. split_s: when the relationship changes, s.
    Returns:
        {"window_s", "internal_rms_m" (3,) per translation axis, "external_rms_m",
        "direction" (3,), "latency"
        (:meth:`~stewart_drake.base.pair_figures.PairLatency.as_dict`), "asked",
        "reproduced" (:func:`~stewart_drake.base.pair_figures.pair_figures` each), "match"
        {figure: relative difference}}.
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
        "latency": relative_latency(tk, xa, xi, pa, pk).as_dict(),
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
