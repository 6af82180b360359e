"""The evaluation's report: docs/results.md and its pictures, from the grid's rows.

Rendering only: every number comes from a row of :func:`~.evaluation.run_case` (or the tuner
study's summary); the verdict on the ANN tuner (:func:`ann_verdict`) is computed from those rows.
:func:`write_report` writes the Markdown (one function per table, :func:`render_markdown`) and
the three pictures (:func:`~.evaluation_plots.plot_results`).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..base.fileio import atomic_write
from ..base.tables import markdown_lines
from ..references.trajectories import SWEEP_AMPLITUDE, SWEEP_MAX_ACCELERATION
from ..robot import statics
from ..robot.kinematics import AXIS_NAMES, X_HOME
from ..run import metrics
from ..run.metrics import SETTLING_BAND
from ..run.plan import robot_geometry, robot_motor_limits
from ..run.scenario_io import load_scenario
from .evaluation_grid import (
    CONDITIONS,
    CONTROLLERS,
    DEFAULT_BASE,
    DISTURBANCES,
    ENCODER_BITS,
    FIXED_LQI,
    NOISE_STD,
    RATIO_LQI,
    TORQUE_LIMIT_NM,
    encoder_condition,
    index_rows,
)
from .evaluation_plots import plot_results, sweep_range


def write_report(rows, info: dict, tuner: dict | None, docs_dir: Path) -> list[Path]:
    """The pictures (:func:`~.evaluation_plots.plot_results`, and the tuner study's when
    ``tuner``) and then results.md (:func:`render_markdown`) in ``docs_dir``. Returns
    [results.md, pictures...]."""
    paths = plot_results(rows, docs_dir)
    if tuner is not None:
        from ..tuner.tuner_report import plot_tuner_tradeoff

        paths.append(plot_tuner_tradeoff(tuner, docs_dir / "results_tuner.png"))
    text = render_markdown(rows, info, tuner)
    md = docs_dir / "results.md"
    atomic_write(md, lambda f: f.write(text.encode()))
    return [md] + paths


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


def _failed_row(r) -> list:
    return [r["case"]["controller"], f"failed: {r['error'].splitlines()[0][:120]}"]


def _nominal_rows(by: dict, ctrls: list, reference: str, rows: list):
    """(controller, row) of the nominal runs of ``reference`` that succeeded; a failed run's
    table row is appended to rows on the way."""
    for c in ctrls:
        r = by.get((c, reference, "nominal"))
        if r is None:
            continue
        if "error" in r:
            rows.append(_failed_row(r))
            continue
        yield c, r


def _paper_table(by: dict, ctrls: list) -> list:
    L = [
        "## Paper manoeuvre (eqs. 37-38), nominal",
        "",
    ]
    header = ["controller", *AXIS_NAMES, "peak phi", "peak Z", "nRMS", "Sum T^2 dt"]
    header += ["feedback Sum dT^2 dt", "peak T", "max closure [m]", "RTF"]
    rows: list = []
    for c, r in _nominal_rows(by, ctrls, "paper", rows):
        rms, peak = r["rms_error"], r["peak_error"]
        rows.append(
            [c, *(_fmt(v, 1e3) for v in rms), _fmt(peak[0], 1e3), _fmt(peak[5], 1e3)]
            + [_fmt(r["normalized_rms"]), _fmt(r["sum_T2_dt"]), _fmt(r["sum_dT2_dt"])]
            + [_fmt(max(r["peak_torque"])), _fmt(r["max_closure_m"], digits=2)]
            + [_fmt(r["realtime_factor"], digits=2)]
        )
    return L + markdown_lines(header, rows) + [""]


def held_out_answer(tuner: dict | None) -> str:
    """The first line of the ANN section: the verdict over held-out tasks, which is the tuner
    study's on the paper's tuner (``tuner``: its summary), or that these runs decide nothing
    (no study, or a QUICK one)."""
    from ..tuner.study_runs import GOAL
    from ..tuner.tuner_report import pct

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
        f"lambda = {lam}: {pct(c['mean'])} +- {100 * c['std']:.0f} %" for lam, c in entries
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
    ]
    rows = []
    for c in ctrls:
        found = [by.get((c, f"step_{a}", "nominal")) for a in AXIS_NAMES]
        rs = [r for r in found if r is not None]
        if len(rs) < len(found):
            continue
        if any("error" in r for r in rs):
            rows.append(_failed_row(next(r for r in rs if "error" in r)))
            continue
        rows.append(
            [c, *(_fmt(r["settling_time_s"]) for r in rs)]
            + [f"{_fmt(100 * max(r['overshoot'] for r in rs))} %"]
            + [_fmt(sum(r["sum_T2_dt"] for r in rs))]
        )
    header = ["controller", *AXIS_NAMES, "max overshoot", "Sum T^2 dt"]
    return L + markdown_lines(header, rows) + [""]


def _helix_table(by: dict, ctrls: list) -> list:
    L = [
        "## Helix (5 mm circle in X-Y at 2 Hz, Z 3 mm at 0.25 Hz, theta 20 mrad at 1 Hz)",
        "",
    ]
    header = ["controller", "theta RMS", "X RMS", "Y RMS", "Z RMS", "X peak", "Y peak", "nRMS"]
    header += ["Sum T^2 dt", "peak T"]
    rows: list = []
    for c, r in _nominal_rows(by, ctrls, "helix", rows):
        rms, peak = r["rms_error"], r["peak_error"]
        rows.append(
            [c, *(_fmt(rms[k], 1e3) for k in (1, 3, 4, 5))]
            + [_fmt(peak[3], 1e3), _fmt(peak[4], 1e3), _fmt(r["normalized_rms"])]
            + [_fmt(r["sum_T2_dt"]), _fmt(max(r["peak_torque"]))]
        )
    return L + markdown_lines(header, rows) + [""]


def _sweep_bandwidth(r) -> metrics.Bandwidth:
    """The -3 dB bandwidth of a sweep's row, from its stored response (so a row written before
    the bandwidth said "below the sweep" is read right too)."""
    return metrics.bandwidth_hz(r["response"]["f"], r["response"]["gain"])


def _bandwidth_table(by: dict, ctrls: list) -> list:
    corner_hz = np.sqrt(SWEEP_MAX_ACCELERATION[1] / SWEEP_AMPLITUDE[1]) / (2 * np.pi)
    f_lo, f_hi = sweep_range(by)
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
    ]

    def bw(r):
        return _sweep_bandwidth(r).text()

    rows = []
    for c in ctrls:
        rz, rp = by.get((c, "sweep_Z", "nominal")), by.get((c, "sweep_phi", "nominal"))
        if rz is None or rp is None:
            continue
        if "error" in rz or "error" in rp:
            rows.append(_failed_row(rz if "error" in rz else rp))
            continue
        rows.append(
            [c, bw(rz), _fmt(rz["peak_gain_db"], digits=2)]
            + [bw(rp), _fmt(rp["peak_gain_db"], digits=2)]
        )
    header = ["controller", "Z bandwidth", "Z peak gain", "phi bandwidth", "phi peak gain"]
    return L + markdown_lines(header, rows) + [""]


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
    ]
    header = ["controller", *paper_conds, "worst phi RMS [mrad]", "worst Z RMS [mm]"]
    header += [f"{sat}: settling [s]", "overshoot"]
    rows = []
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
        rows.append([c, *cells, _fmt(worst_phi, 1e3), _fmt(worst_z, 1e3), *sat_cells])
    return L + markdown_lines(header, rows) + [""]


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
    ]
    rows = []
    for bits in ENCODER_BITS:
        condition = encoder_condition(bits)
        for c in RATIO_LQI:
            r = by.get((c, "paper", condition))
            if r is None:
                continue
            if "error" in r:
                rows.append([condition, c, f"failed: {r['error'].splitlines()[0][:90]}"])
                continue
            rows.append(
                [f"{bits}-bit", c, *(_fmt(v, 1e6) for v in r["rms_error"])]
                + [_fmt(r["sum_dT2_dt"]), _fmt(max(r["peak_torque"]))]
            )
    header = ["encoder", "controller", *AXIS_NAMES, "feedback Sum dT^2 dt", "peak T"]
    return L + markdown_lines(header, rows) + [""]


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
    ]
    header = ["controller"]
    for n in DISTURBANCES:
        header += [f"{n}: peak angle", "peak position", "nRMS"]
    rows = []
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
        rows.append([c, *cells])
    return L + markdown_lines(header, rows) + [""]


def disturbance_holding_torques(base: str) -> tuple[dict, float | None]:
    """({disturbance: N m}, limit): the largest static crank torque holding home under each
    tool disturbance's peak wrench needs (:func:`~stewart_drake.robot.statics.tool_load_torques`,
    gravity included), and the motors' torque limit of the base scenario (N m, None: none);
    above the limit no controller can hold the pose."""
    scenario = load_scenario(base)
    g = robot_geometry(scenario)
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
    return needs, robot_motor_limits(scenario).peak_torque_Nm


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
