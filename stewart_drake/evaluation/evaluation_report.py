"""The evaluation's report: docs/results.md and its pictures, from the grid's rows.

Rendering only: every number comes from a row of :func:`~.evaluation.run_case` (or the tuner
study's summary); the verdict on the ANN tuner (:func:`ann_verdict`) is computed from those rows.
:func:`write_report` writes the Markdown (one function per table, :func:`render_markdown`) and
the three pictures (one function each, :func:`plot_results`).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..references.trajectories import SWEEP_AMPLITUDE, SWEEP_MAX_ACCELERATION
from ..robot import statics
from ..robot.kinematics import AXIS_NAMES, X_HOME
from ..run import metrics
from ..run.metrics import SETTLING_BAND
from ..run.plan import make_plan
from ..run.scenario_io import load_scenario
from .evaluation_grid import (
    CONDITIONS,
    CONTROLLERS,
    DEFAULT_BASE,
    DISTURBANCES,
    ENCODER_BITS,
    FIXED_LQI,
    FIXED_WEIGHTS,
    NOISE_STD,
    RATIO_LQI,
    TORQUE_LIMIT_NM,
    encoder_condition,
)

#: How the controllers that are not a fixed LQI are drawn in the plots: label, marker, colour.
_OTHERS = {
    "pd": ("crank-space PD", "s", "C3"),
    "ann_best_cost": ("ANN tuner, best-cost labels", "*", "C1"),
    "ann_paper": ("ANN tuner, paper labels", "D", "C6"),
}


def write_report(rows, info: dict, tuner: dict | None, docs_dir: Path) -> list[Path]:
    """The pictures (:func:`plot_results`, and the tuner study's when ``tuner``) and then
    results.md (:func:`render_markdown`) in ``docs_dir``. Returns [results.md, pictures...]."""
    paths = plot_results(rows, docs_dir)
    if tuner is not None:
        from ..tuner.tuner_report import plot_tuner_tradeoff

        paths.append(plot_tuner_tradeoff(tuner, docs_dir / "results_tuner.png"))
    text = render_markdown(rows, info, tuner)
    md = docs_dir / "results.md"
    atomic_write(md, lambda f: f.write(text.encode()))
    return [md] + paths


def index_rows(rows) -> dict:
    """{(controller, reference, condition): row} of the grid's rows."""
    return {
        (r["case"]["controller"], r["case"]["scenario"], r["case"]["condition"]): r for r in rows
    }


def ann_verdict(rows, scenario: str = "paper", condition: str = "nominal") -> dict:
    """Does the ANN-tuned LQI beat the best fixed-gain LQI on tracking at no more effort?

    Effort is the *feedback* effort, Sum (T - T_ff)^2 dt (``sum_dT2_dt``): the total Sum T^2 dt
    is set by gravity and the motion, the same for every controller to a few per mille.
    "Best fixed-gain LQI" is the fixed pair with the lowest normalized RMS among those whose
    feedback effort is no more than the ANN run's (the fair comparison); the ANN wins if its
    normalized RMS is lower. One run of one task: the tuner study (:mod:`.tuner_study`) is the
    verdict over held-out tasks. Returns a dict per ANN variant with both figures and the ratio.
    """
    by = index_rows(rows)
    out = {}
    for ann in ("ann_best_cost", "ann_paper"):
        a = by.get((ann, scenario, condition))
        if a is None or "error" in a:
            continue
        fixed = [
            by[(c, scenario, condition)]
            for c in FIXED_LQI
            if (c, scenario, condition) in by and "error" not in by[(c, scenario, condition)]
        ]
        admissible = [r for r in fixed if r["sum_dT2_dt"] <= a["sum_dT2_dt"] * (1 + 1e-9)]
        best_overall = min(fixed, key=lambda r: r["normalized_rms"]) if fixed else None
        best = min(admissible, key=lambda r: r["normalized_rms"]) if admissible else None
        dominated_by = [
            r["case"]["controller"]
            for r in fixed
            if r["normalized_rms"] < a["normalized_rms"] and r["sum_dT2_dt"] < a["sum_dT2_dt"]
        ]
        out[ann] = {
            "ann": a,
            "best_fixed": best,
            "best_fixed_overall": best_overall,
            "dominated_by": dominated_by,
            "beats": bool(best is not None and a["normalized_rms"] < best["normalized_rms"]),
            "ratio": (a["normalized_rms"] / best["normalized_rms"]) if best else None,
        }
    return out


def _fmt(v, scale=1.0, digits=3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and not np.isfinite(v):
        return "inf"
    return f"{scale * v:.{digits}g}"


def _ratio(controller: str) -> float | None:
    """omega_Q / omega_R of a fixed LQI of the grid, None for the others."""
    if controller not in FIXED_WEIGHTS:
        return None
    q, r = FIXED_WEIGHTS[controller]
    return q / r


# -- results.md ------------------------------------------------------------------------------------


def render_markdown(rows, info: dict, tuner: dict | None = None) -> str:
    """The text of docs/results.md from the grid's rows (see the evaluation's module docstring),
    led by the tuner study's section when ``tuner`` (its summary) is given."""
    by = index_rows(rows)
    ctrls = [c for c in CONTROLLERS if any(k[0] == c for k in by)]
    L = _heading(rows, info)
    if tuner is not None:
        from ..tuner.tuner_report import render_tuner_markdown

        L += [render_tuner_markdown(tuner), "## The controller grid", ""]
    L += [
        "Units: angles in mrad, positions in mm, torques in N m, Sum T^2 dt in N^2 m^2 s. "
        "RMS and peak errors are over the second half of each run (the true pose from the "
        "plant state, not the noisy measurement). `nRMS` = sqrt(mean_i (RMS_i / s_i)^2) with "
        "the LQI's error scales s = 1 mrad | 1 mm. RTF = real-time factor of that run in its "
        "worker process.",
        "",
    ]
    for section in (
        _paper_table,
        functools.partial(_verdict_lines, tuner=tuner),
        _step_table,
        _helix_table,
        _bandwidth_table,
        _robustness_table,
        _encoder_table,
    ):
        L += section(by, ctrls)
    L += _disturbance_table(by, ctrls, info.get("base", DEFAULT_BASE))
    failed = [r for r in rows if "error" in r]
    L += ["## Runs that failed", ""]
    L += [
        f"- {r['case']['controller']} / {r['case']['scenario']} / {r['case']['condition']}: "
        f"{r['error'].splitlines()[0]}"
        for r in failed
    ] or ["None."]
    L += [
        "",
        "## Pictures",
        "",
        "![tracking vs effort](results_tradeoff.png)",
        "",
        "![frequency responses](results_bandwidth.png)",
        "",
        "![step responses](results_steps.png)",
        "",
    ]
    return "\n".join(L)


def _heading(rows, info: dict) -> list:
    """The title and what made the report: runs, times, workers, quick mode, the base."""
    quick = ", QUICK mode: smoke-test durations, not figures to quote" if info["quick"] else ""
    reused = f", {info['reused']} runs read back from an earlier call" if info.get("reused") else ""
    return [
        "# Evaluation results",
        "",
        "Generated by `stewart-drake evaluate` "
        f"({info['n_cases']} runs whose own times add up to "
        f"{sum(float(r.get('wall_s') or 0.0) for r in rows):.0f} s; this call "
        f"{info['wall_s']:.0f} s wall on {info['workers']} workers{reused}{quick})."
        " Do not edit by hand: rerun the command.",
        "",
        f"Every run starts from the scenario `{info.get('base', DEFAULT_BASE)}` "
        "(`stewart-drake scenario` prints it; docs/hardware.md describes the robot as built).",
        "",
    ]


def _failed_line(r) -> str:
    return f"| {r['case']['controller']} | failed: {r['error'].splitlines()[0][:120]} |"


def _nominal_rows(by: dict, ctrls: list, reference: str, L: list):
    """(controller, row) of the nominal runs of ``reference`` that succeeded; a failed run's
    line is appended to L on the way."""
    for c in ctrls:
        r = by.get((c, reference, "nominal"))
        if r is None:
            continue
        if "error" in r:
            L.append(_failed_line(r))
            continue
        yield c, r


def _paper_table(by: dict, ctrls: list) -> list:
    L = [
        "## Paper manoeuvre (eqs. 37-38), nominal",
        "",
        "| controller | phi | theta | psi | X | Y | Z | peak phi | peak Z | nRMS | Sum T^2 dt | "
        "feedback Sum dT^2 dt | peak T | max closure [m] | RTF |",
        "|---|" + "---|" * 14,
    ]
    for c, r in _nominal_rows(by, ctrls, "paper", L):
        rms, peak = r["rms_error"], r["peak_error"]
        L.append(
            f"| {c} | "
            + " | ".join(_fmt(v, 1e3) for v in rms)
            + f" | {_fmt(peak[0], 1e3)} | {_fmt(peak[5], 1e3)} | {_fmt(r['normalized_rms'])}"
            f" | {_fmt(r['sum_T2_dt'])} | {_fmt(r['sum_dT2_dt'])}"
            f" | {_fmt(max(r['peak_torque']))} | {_fmt(r['max_closure_m'], digits=2)}"
            f" | {_fmt(r['realtime_factor'], digits=2)} |"
        )
    return L + [""]


def held_out_answer(tuner: dict | None) -> str:
    """The first line of the ANN section: the verdict over held-out tasks, which is the tuner
    study's on the paper's tuner (``tuner``: its summary), or that these runs decide nothing
    (no study, or a QUICK one)."""
    from ..tuner.tuner_report import _pct
    from ..tuner.tuner_study import GOAL

    entries = []
    if tuner is not None and not tuner["settings"].get("quick"):
        entries = [
            (lam, v["controllers"]["paper tuner"])
            for lam, v in tuner["verdicts"].items()
            if "paper tuner" in v["controllers"]
        ]
    if not entries:
        return (
            "**Not decided here**: below is one run of one task per controller; the verdict "
            "over held-out tasks is the tuner study's (`stewart-drake evaluate` without "
            "`--no-tuner-study` or `--quick`; docs/tuners.md)."
        )
    met = [c["beats"] for _, c in entries]
    answer = "Yes" if all(met) else "No" if not any(met) else "Not at every lambda"
    figures = "; ".join(
        f"lambda = {lam}: {_pct(c['mean'])} +- {100 * c['std']:.0f} %" for lam, c in entries
    )
    return (
        f"**{answer}**, over the held-out tasks of the tuner study (above): the paper's tuner "
        f"(the network of ann_paper) against the best fixed ratio of each task, {figures} "
        f"(goal: {100 * GOAL:.0f} % below, beyond the spread). The runs below are one run "
        "each of the paper manoeuvre: figures, not a verdict."
    )


def _verdict_lines(by: dict, ctrls: list, tuner: dict | None = None) -> list:
    L = ["## Does the ANN tuner beat the best fixed-gain LQI?", "", held_out_answer(tuner), ""]
    for ann, v in ann_verdict(list(by.values())).items():
        a, b = v["ann"], v["best_fixed"]
        if b is None:
            L.append(
                f"- **{ann}**: no fixed-gain LQI uses as little feedback effort (Sum dT^2 dt "
                f"{_fmt(a['sum_dT2_dt'])}); the closest in effort is compared in the table."
            )
            continue
        best = v["best_fixed_overall"]
        how = "better" if v["beats"] else "worse"
        L.append(
            f"- **{ann}** tracks {how} on this one run than the best fixed-gain LQI at no more "
            f"effort, {b['case']['controller']}: nRMS {_fmt(a['normalized_rms'])} vs "
            f"{_fmt(b['normalized_rms'])} (ratio {_fmt(v['ratio'])}), feedback Sum dT^2 dt "
            f"{_fmt(a['sum_dT2_dt'])} vs {_fmt(b['sum_dT2_dt'])}. Best fixed pair "
            f"regardless of effort: {best['case']['controller']} (nRMS "
            f"{_fmt(best['normalized_rms'])}). "
            + (
                f"Fixed pairs better on both tracking and effort: {', '.join(v['dominated_by'])}."
                if v["dominated_by"]
                else "No fixed pair is better on both tracking and effort (the ANN run is on the "
                "fixed pairs' Pareto front)."
            )
        )
    return L + [
        "",
        "Effort here is the feedback effort, `feedback Sum dT^2 "
        "dt`, what the controller adds to the gravity feed-forward: Sum T^2 dt is mostly "
        "the torque that holds the platform up, the same for every controller. The 9 "
        "fixed pairs are 5 distinct controllers: only omega_Q / omega_R matters (scaling "
        "Q and R together leaves the gain unchanged), so rows with the same ratio "
        "repeat.",
        "",
    ]


def _step_table(by: dict, ctrls: list) -> list:
    L = [
        "## Steps (20 mrad on angles, 5 mm on positions, at t = 0.5 s)",
        "",
        f"Settling time to a {100 * SETTLING_BAND:g} % band, s (`-`: not settled in the run), "
        "and Sum T^2 dt of all six step runs.",
        "",
        "| controller | " + " | ".join(AXIS_NAMES) + " | max overshoot | Sum T^2 dt |",
        "|---|" + "---|" * 8,
    ]
    for c in ctrls:
        found = [by.get((c, f"step_{a}", "nominal")) for a in AXIS_NAMES]
        rs = [r for r in found if r is not None]
        if len(rs) < len(found):
            continue
        if any("error" in r for r in rs):
            L.append(_failed_line(next(r for r in rs if "error" in r)))
            continue
        L.append(
            f"| {c} | "
            + " | ".join(_fmt(r["settling_time_s"]) for r in rs)
            + f" | {_fmt(100 * max(r['overshoot'] for r in rs))} %"
            f" | {_fmt(sum(r['sum_T2_dt'] for r in rs))} |"
        )
    return L + [""]


def _helix_table(by: dict, ctrls: list) -> list:
    L = [
        "## Helix (5 mm circle in X-Y at 2 Hz, Z 3 mm at 0.25 Hz, theta 20 mrad at 1 Hz)",
        "",
        "| controller | theta RMS | X RMS | Y RMS | Z RMS | X peak | Y peak | nRMS | Sum T^2 dt "
        "| peak T |",
        "|---|" + "---|" * 9,
    ]
    for c, r in _nominal_rows(by, ctrls, "helix", L):
        rms, peak = r["rms_error"], r["peak_error"]
        L.append(
            f"| {c} | {_fmt(rms[1], 1e3)} | {_fmt(rms[3], 1e3)} | {_fmt(rms[4], 1e3)} | "
            f"{_fmt(rms[5], 1e3)} | {_fmt(peak[3], 1e3)} | {_fmt(peak[4], 1e3)} | "
            f"{_fmt(r['normalized_rms'])} | {_fmt(r['sum_T2_dt'])} | "
            f"{_fmt(max(r['peak_torque']))} |"
        )
    return L + [""]


def _sweep_bandwidth(r) -> metrics.Bandwidth:
    """The -3 dB bandwidth of a sweep's row, from its stored response (so a row written before
    the bandwidth said "below the sweep" is read right too)."""
    return metrics.bandwidth_hz(r["response"]["f"], r["response"]["gain"])


def _sweep_range(by: dict) -> tuple[float, float]:
    """The frequencies the sweeps' responses actually span, Hz (the first segment, the start
    transient, is dropped: :func:`~.metrics.frequency_response`); (1, 50) when none ran."""
    fs = [
        f
        for (_, ref, _), r in by.items()
        if ref.startswith("sweep_") and "error" not in r
        for f in r["response"]["f"]
    ]
    return (min(fs), max(fs)) if fs else (1.0, 50.0)


def _bandwidth_table(by: dict, ctrls: list) -> list:
    corner_hz = np.sqrt(SWEEP_MAX_ACCELERATION[1] / SWEEP_AMPLITUDE[1]) / (2 * np.pi)
    f_lo, f_hi = _sweep_range(by)
    L = [
        f"## Bandwidth (sine sweep 1 -> 50 Hz: {1e3 * SWEEP_AMPLITUDE[1]:g} mm on Z, "
        f"{1e3 * SWEEP_AMPLITUDE[0]:g} mrad on phi)",
        "",
        "-3 dB bandwidth of the pose's response to the reference, Hz, and the peak gain, dB. "
        f"The gain is measured from {f_lo:.3g} to {f_hi:.3g} Hz (the sweep's first two cycles "
        "are its start transient): `> f (above the sweep)` when the gain never falls below "
        "-3 dB there, `< f (below the sweep)` when it is already below -3 dB at the first "
        "frequency. Above "
        f"{corner_hz:.3g} Hz the amplitude falls as 1/f^2 (constant acceleration: "
        f"{SWEEP_MAX_ACCELERATION[1]:.3g} m/s^2, {SWEEP_MAX_ACCELERATION[0]:.3g} rad/s^2), "
        "what the motors can give. The figure draws each fixed LQI's linear model beside its "
        "sweep (dotted, friction-free; margins and bandwidths: [analysis.md](analysis.md)): "
        "where a sweep falls below its model at these small amplitudes, the motors' dry "
        "friction is why.",
        "",
        "| controller | Z bandwidth | Z peak gain | phi bandwidth | phi peak gain |",
        "|---|---|---|---|---|",
    ]

    def bw(r):
        return _sweep_bandwidth(r).text()

    for c in ctrls:
        rz, rp = by.get((c, "sweep_Z", "nominal")), by.get((c, "sweep_phi", "nominal"))
        if rz is None or rp is None:
            continue
        if "error" in rz or "error" in rp:
            L.append(_failed_line(rz if "error" in rz else rp))
            continue
        L.append(
            f"| {c} | {bw(rz)} | {_fmt(rz['peak_gain_db'], digits=2)} | {bw(rp)} | "
            f"{_fmt(rp['peak_gain_db'], digits=2)} |"
        )
    return L + [""]


def _robustness_table(by: dict, ctrls: list) -> list:
    paper_conds = [k for k, (_, scen) in CONDITIONS.items() if scen in (None, "paper")]
    sat = next(k for k, (_, scen) in CONDITIONS.items() if scen == "step_Z")
    L = [
        "## Robustness",
        "",
        "On the paper manoeuvre: nRMS (and Sum T^2 dt) per condition. Payload: platform mass "
        "and inertia scaled, unknown to the controller. Noise: 1 sigma "
        f"{NOISE_STD[0] * 1e3:g} mrad, {NOISE_STD[3] * 1e3:g} mm, {NOISE_STD[6]:g} rad/s, "
        f"{NOISE_STD[9]:g} m/s on the measured pose and rate, white at 1 kHz. Saturation: "
        f"|T_i| <= {TORQUE_LIMIT_NM:g} N m on the 5 mm Z step (its settling time and overshoot; "
        "the unsaturated ones are in the step table). The paper manoeuvre needs 0.41 N m at "
        "most: below that the platform rolls past its reference and falls whatever the "
        "controller, above it the limit never acts.",
        "",
        "| controller | " + " | ".join(paper_conds) + " | worst phi RMS [mrad] | worst Z RMS "
        f"[mm] | {sat}: settling [s] | overshoot |",
        "|---|" + "---|" * (len(paper_conds) + 4),
    ]
    for c in ctrls:
        found = [by.get((c, "paper", k)) for k in paper_conds]
        rs = [r for r in found if r is not None]
        rsat = by.get((c, "step_Z", sat))
        if len(rs) < len(found) or rsat is None:
            continue
        cells = [
            "failed" if "error" in r else f"{_fmt(r['normalized_rms'])} ({_fmt(r['sum_T2_dt'])})"
            for r in rs
        ]
        ok = [r for r in rs if "error" not in r]
        worst_phi = max((r["rms_error"][0] for r in ok), default=None)
        worst_z = max((r["rms_error"][5] for r in ok), default=None)
        sat_cells = (
            ["failed", "-"]
            if "error" in rsat
            else [_fmt(rsat["settling_time_s"]), f"{_fmt(100 * rsat['overshoot'])} %"]
        )
        L.append(
            f"| {c} | " + " | ".join(cells) + f" | {_fmt(worst_phi, 1e3)} | "
            f"{_fmt(worst_z, 1e3)} | " + " | ".join(sat_cells) + " |"
        )
    return L + [""]


def _encoder_table(by: dict, ctrls: list) -> list:
    if not any(key[2] == encoder_condition(b) for key in by for b in ENCODER_BITS):
        return []
    L = [
        "## Encoder resolution (paper manoeuvre)",
        "",
        "RMS error per axis in urad and um, the feedback effort Sum (T - T_ff)^2 dt in "
        "N^2 m^2 s (what the controller adds to the gravity feed-forward) and the peak "
        "torque in N m, for each encoder resolution and the five distinct weight ratios "
        "omega_Q / omega_R (100, 10, 1, 0.1, 0.01).",
        "",
        "| encoder | controller | phi | theta | psi | X | Y | Z | feedback Sum dT^2 dt | peak T |",
        "|---|---|" + "---|" * 8,
    ]
    for bits in ENCODER_BITS:
        condition = encoder_condition(bits)
        for c in RATIO_LQI:
            r = by.get((c, "paper", condition))
            if r is None:
                continue
            if "error" in r:
                L.append(f"| {condition} | {c} | failed: {r['error'].splitlines()[0][:90]} |")
                continue
            L.append(
                f"| {bits}-bit | {c} | "
                + " | ".join(_fmt(v, 1e6) for v in r["rms_error"])
                + f" | {_fmt(r['sum_dT2_dt'])} | {_fmt(max(r['peak_torque']))} |"
            )
    return L + [""]


def _disturbance_table(by: dict, ctrls: list, base: str) -> list:
    if not any(key[2] in DISTURBANCES for key in by):
        return []
    described = "; ".join(
        f"{name}: {d.kind} {d.magnitude:g} {'N m' if d.kind == 'twist' else 'N'} along "
        f"{d.direction}" + (f" at {d.frequency_hz:g} Hz" if d.kind == "contact" else "")
        for name, d in DISTURBANCES.items()
    )
    L = [
        "## Tool disturbances (holding home; from t = 1 s)",
        "",
        "Peak and RMS pose error over the second half of each run: angles in mrad, "
        f"positions in mm. {described}.",
        "",
        _disturbance_statics(base),
        "",
        "| controller | "
        + " | ".join(f"{n}: peak angle | peak position | nRMS" for n in DISTURBANCES)
        + " |",
        "|---|" + "---|" * (3 * len(DISTURBANCES)),
    ]
    for c in ctrls:
        cells = []
        for name in DISTURBANCES:
            r = by.get((c, "home", name))
            cells += (
                ["-"] * 3
                if r is None
                else ["failed", "-", "-"]
                if "error" in r
                else [
                    _fmt(max(r["peak_error"][:3]), 1e3),
                    _fmt(max(r["peak_error"][3:]), 1e3),
                    _fmt(r["normalized_rms"]),
                ]
            )
        L.append(f"| {c} | " + " | ".join(cells) + " |")
    return L + [""]


def disturbance_holding_torques(base: str) -> tuple[dict, float | None]:
    """({disturbance: N m}, limit): the largest static crank torque holding home under each
    tool disturbance's peak wrench needs (:func:`~stewart_drake.robot.statics.tool_load_torques`,
    gravity included), and the motors' torque limit of the base scenario (N m, None: none);
    above the limit no controller can hold the pose."""
    plan = make_plan(load_scenario(base), with_reference=False)
    g = plan.geometry
    needs = {}
    for name, d in DISTURBANCES.items():
        needs[name] = float(
            np.abs(
                statics.tool_load_torques(
                    g,
                    X_HOME,
                    d.wrench(
                        [d.start_s + 0.5 / d.frequency_hz if d.kind == "contact" else d.start_s]
                    )[0],
                )
            ).max()
        )
    return needs, plan.torque_limit_Nm


def _disturbance_statics(base: str) -> str:
    """One sentence per tool disturbance: :func:`disturbance_holding_torques` against the
    motors' limit of the base scenario: above it, no controller can hold the pose."""
    needs, limit = disturbance_holding_torques(base)
    parts = []
    for name, need in needs.items():
        verdict = (
            ""
            if limit is None
            else " (beyond the motors' limit: no controller can hold it)"
            if need > limit
            else " (within the motors' limit)"
        )
        parts.append(f"{name} {need:.3f} N m{verdict}")
    return (
        "Static crank torque needed to hold home under each disturbance's peak wrench "
        f"(gravity included; motors' limit {'none' if limit is None else f'{limit:.3f} N m'})"
        ": " + "; ".join(parts) + "."
    )


# -- the pictures ----------------------------------------------------------------------------------


def _ratio_colors(ratios) -> dict:
    """One colour per omega_Q / omega_R, soft (yellow) to stiff (purple): viridis, which the
    red, orange and pink of the other controllers do not resemble."""
    import matplotlib

    ratios = sorted(set(ratios))
    shades = matplotlib.colormaps["viridis"](np.linspace(0.9, 0.05, max(len(ratios), 2)))
    return {r: shades[k] for k, r in enumerate(ratios)}


def _by_ratio(by: dict, reference: str, condition: str) -> dict:
    """{ratio: row} of the fixed LQIs that ran (reference, condition); pairs of one ratio are one
    controller (only the ratio sets the gain), the first one stands for them."""
    out: dict = {}
    for c in FIXED_LQI:
        r = by.get((c, reference, condition))
        if r is not None and "error" not in r:
            out.setdefault(_ratio(c), r)
    return dict(sorted(out.items()))


def _others(by: dict, reference: str, condition: str = "nominal"):
    """(label, marker, colour, row) of the controllers that are not a fixed LQI and ran."""
    for c, (label, marker, color) in _OTHERS.items():
        r = by.get((c, reference, condition))
        if r is not None and "error" not in r:
            yield label, marker, color, r


def plot_results(rows, out_dir: str | Path) -> list[Path]:
    """Three PNGs in out_dir: tracking vs feedback effort (paper manoeuvre, nominal and with
    noise), frequency responses (Z and phi sweeps), step responses (Z step). Fixed LQIs are one
    line or point per weight ratio omega_Q / omega_R (the nine pairs are five controllers).
    Returns their paths."""
    by = index_rows(rows)
    colors = _ratio_colors(_ratio(c) for c in FIXED_LQI)
    paths = []
    for name, draw in (
        ("results_tradeoff.png", _plot_tradeoff),
        ("results_bandwidth.png", _plot_bandwidth),
        ("results_steps.png", _plot_steps),
    ):
        fig = draw(by, colors)
        path = Path(out_dir) / name
        atomic_write(path, functools.partial(fig.savefig, dpi=100, format="png"))
        paths.append(path)
    return paths


def _plot_tradeoff(by: dict, colors: dict):
    """Tracking against the feedback effort, the figure of the ANN verdict."""
    import matplotlib.ticker
    from matplotlib.figure import Figure  # no pyplot: no global backend switch

    fig = Figure(figsize=(12, 5.2))
    axes = fig.subplots(1, 2)
    for ax, condition, title in (
        (axes[0], "nominal", "nominal"),
        (axes[1], "noise", "with sensor noise"),
    ):
        fixed = _by_ratio(by, "paper", condition)
        if fixed:
            x = [r["sum_dT2_dt"] for r in fixed.values()]
            y = [r["normalized_rms"] for r in fixed.values()]
            ax.plot(x, y, "-", color="0.75", lw=1, zorder=1)
            ax.scatter(
                x,
                y,
                s=60,
                c=[colors[k] for k in fixed],
                edgecolors="k",
                lw=0.5,
                zorder=2,
                label=r"fixed LQI, labelled by $\omega_Q/\omega_R$",
            )
            for ratio, xi, yi in zip(fixed, x, y):
                ax.annotate(
                    f"{ratio:g}",
                    (xi, yi),
                    xytext=(6, -3),
                    textcoords="offset points",
                    fontsize=8,
                    color="0.25",
                )
        for label, marker, color, r in _others(by, "paper", condition):
            # hollow, drawn on top: a point under it stays visible
            ax.plot(
                r["sum_dT2_dt"],
                r["normalized_rms"],
                marker,
                mfc="none",
                mec=color,
                mew=1.8,
                ms=15 if marker == "*" else 10,
                ls="none",
                zorder=3,
                label=label,
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        for axis in (ax.xaxis, ax.yaxis):  # 0.02, not 2 x 10^-2
            axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(
                matplotlib.ticker.FuncFormatter(
                    lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""
                )
            )
        ax.set_xlabel(r"feedback effort $\sum (T - T_{ff})^2 \Delta t$ [N$^2$ m$^2$ s]")
        ax.set_title(f"paper manoeuvre, {title}", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper left")
    axes[0].set_ylabel("normalized RMS tracking error (1 = 1 mrad | 1 mm)")
    fig.suptitle("Tracking against feedback effort: lower left is better", fontsize=11)
    fig.tight_layout()
    return fig


def _model_tracking(row: dict, ratio: float, f) -> np.ndarray | None:
    """(K, 6) complex x_i / x_d,i of the linear model (:mod:`~.loop_analysis`) of the LQI of
    weight ratio ``ratio`` on the row's base scenario at home, at f (K,) Hz; None when the row
    names no base, the model cannot be built (a base whose loop is not an LQI's) or its closed
    loop is unstable."""
    from ..analysis.loop_analysis import loop_models, tracking_response
    from ..base.errors import StewartError
    from ..control.lqi.driver import LqiDriver

    base = row.get("case", {}).get("base")
    if not base:
        return None
    try:
        scenario = load_scenario(base)
        driver = scenario.controller if isinstance(scenario.controller, LqiDriver) else LqiDriver()
        driver = driver.with_weights(omega_Q=float(ratio), omega_R=1.0)
        models = loop_models(scenario, driver=driver)
        # an unstable linear loop has no frequency response to draw (the sweep ran on friction)
        return tracking_response(models, f) if models.spectral_radius < 1 else None
    except (StewartError, OSError):
        return None


def _plot_bandwidth(by: dict, colors: dict):
    """The frequency responses of the Z and phi sweeps: gain (top) and phase (bottom), over
    the frequencies actually measured, with the linear model's response of each fixed LQI
    (dotted; :mod:`~.loop_analysis`, friction-free: where the sweep falls below it at small
    amplitude, the cranks' dry friction is why, docs/analysis.md)."""
    import matplotlib.ticker
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 7.5))
    axes = fig.subplots(2, 2, sharex=True, sharey="row", height_ratios=[3, 2])
    f_lo, f_hi = _sweep_range(by)
    for col, reference in enumerate(("sweep_Z", "sweep_phi")):
        ax, ax_phase = axes[0, col], axes[1, col]
        ratios = _by_ratio(by, reference, "nominal")
        curves = [
            (rf"LQI $\omega_Q/\omega_R$ = {ratio:g}", colors[ratio], "-", r)
            for ratio, r in ratios.items()
        ] + [(label, color, "--", r) for label, _, color, r in _others(by, reference)]
        f_model = np.geomspace(f_lo, f_hi, 200)
        k = 5 if reference == "sweep_Z" else 0
        for n, (ratio, r) in enumerate(ratios.items()):
            G = _model_tracking(r, ratio, f_model)
            if G is None:
                continue
            ax.semilogx(
                f_model,
                20 * np.log10(np.abs(G[:, k])),
                color=colors[ratio],
                lw=0.9,
                ls=":",
                label="linear model (same colour), no Coulomb friction" if n == 0 else None,
            )
            ax_phase.semilogx(
                f_model,
                np.degrees(np.unwrap(np.angle(G[:, k]))),
                color=colors[ratio],
                lw=0.9,
                ls=":",
            )
        for label, color, ls, r in curves:
            f = r["response"]["f"]
            if not f:
                continue
            ax.semilogx(
                f, 20 * np.log10(r["response"]["gain"]), color=color, lw=1.2, ls=ls, label=label
            )
            if "phase" in r["response"]:
                ax_phase.semilogx(f, np.degrees(r["response"]["phase"]), color=color, lw=1.2, ls=ls)
        ax.axhline(-3, color="k", ls=":", lw=1)
        ax.annotate(
            "-3 dB: the bandwidth is where a gain crosses it",
            (0.01, -3),
            xycoords=("axes fraction", "data"),
            xytext=(0, -10),
            textcoords="offset points",
            fontsize=8,
            ha="left",
        )
        for a in (ax, ax_phase):
            a.xaxis.set_major_locator(matplotlib.ticker.FixedLocator([1, 2, 5, 10, 20, 50]))
            a.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
            a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            a.grid(alpha=0.3, which="both")
        ax_phase.set_xlabel("frequency [Hz]")
        axis = reference.replace("sweep_", "")
        ax.set_title(
            f"reference to pose, {axis}: sine sweep measured {f_lo:.2g} to {f_hi:.3g} Hz",
            fontsize=10,
        )
    axes[0, 0].set_ylabel("gain [dB]")
    axes[1, 0].set_ylabel("phase [deg]")
    axes[0, 1].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    return fig


def _plot_steps(by: dict, colors: dict):
    """The Z step responses, and under the saturation condition for one of each kind."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4.8))
    ax = fig.subplots()
    for ratio, r in _by_ratio(by, "step_Z", "nominal").items():
        ax.plot(
            r["trace"]["t"],
            1e3 * np.asarray(r["trace"]["y"]),
            color=colors[ratio],
            lw=1,
            label=rf"LQI $\omega_Q/\omega_R$ = {ratio:g}",
        )
    for label, _, color, r in _others(by, "step_Z"):
        ax.plot(
            r["trace"]["t"], 1e3 * np.asarray(r["trace"]["y"]), color=color, lw=1.5, label=label
        )
    for c in ("lqi_1_1", "pd", "ann_best_cost"):
        rs = next(
            (
                v
                for k, v in by.items()
                if k[0] == c and k[1] == "step_Z" and k[2] != "nominal" and "error" not in v
            ),
            None,
        )
        if rs is not None:
            ax.plot(
                rs["trace"]["t"],
                1e3 * np.asarray(rs["trace"]["y"]),
                ls="--",
                lw=1,
                color=_OTHERS.get(c, (None, None, colors[1.0]))[2],
                label=f"{_OTHERS.get(c, ('LQI ratio 1',))[0]}, |T| <= {TORQUE_LIMIT_NM:g} N m",
            )
    ax.set_xlim(0.4, 1.2)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("Z - Z_home [mm]")
    ax.set_title("5 mm step on Z at t = 0.5 s")
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
