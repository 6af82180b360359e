"""The evaluation: every controller on every scenario, side by side.

``stewart-drake evaluate`` runs a grid of :class:`Case` (controller x scenario x condition) over
a runner (:mod:`.runners`, local processes by default), keeps each row on disk as it arrives
(``results/evaluation/rows/``, resumable: :mod:`.store`), and once the grid is complete writes

- ``docs/results.md``: tables generated from the runs (never edited by hand), with the verdict
  on the ANN tuner computed from the numbers;
- ``docs/results_*.png``: the tracking-vs-effort map, frequency responses and step responses;
- ``results/evaluation/rows.json``: every row, for notebooks and further analysis.

Controllers: the LQI at each of the paper's 9 fixed (omega_Q, omega_R) pairs, the crank-space PD
with gravity feed-forward, and the ANN-tuned LQI with best-cost and with paper labels.
Scenarios: the paper manoeuvre (eqs. 37-38), a step on each axis, a helix, and sine sweeps of Z
and phi for the -3 dB bandwidth. Conditions (on the paper manoeuvre): nominal, +-20 % platform
mass and inertia unknown to the controller, sensor noise, motor torque saturation.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..control.lqi import LqiScales
from ..errors import IncompleteResultsError, InvalidConfigError
from ..fileio import atomic_write
from ..model import statics
from ..model.kinematics import X_HOME
from ..model.statics import feedforward_torques
from ..simulation.scenario import (
    DEFAULT_SCENARIO,
    AnnTunerDriver,
    LqiDriver,
    NamedReference,
    PdDriver,
    Scenario,
    SensorNoise,
    ToolDisturbance,
    dump_scenario,
    load_scenario,
    use_paper_tuner,
)
from ..simulation.trajectories import AXIS_NAMES, ChirpTrajectory, StepTrajectory
from .collection import PAPER_WEIGHTS
from .experiments import run_experiment
from .runners import JobFailure, ProcessRunner
from .store import ResultStore, file_digest, run_jobs

FIXED_LQI = tuple(f"lqi_{q:g}_{r:g}" for q in PAPER_WEIGHTS for r in PAPER_WEIGHTS)
CONTROLLERS = FIXED_LQI + ("pd", "ann_best_cost", "ann_paper")
#: The controllers of ``evaluate --quick``: one of each kind, enough to draw every table and plot.
QUICK_CONTROLLERS = ("lqi_1_1", "pd", "ann_best_cost")
#: Sensor noise of the "noise" condition on the ideal robot: 0.1 mrad, 0.05 mm, 0.01 rad/s,
#: 5 mm/s (1 sigma); on the robot as built, encoder noise of ENCODER_NOISE_COUNTS (1 sigma).
NOISE_STD = (1e-4,) * 3 + (5e-5,) * 3 + (1e-2,) * 3 + (5e-3,) * 3
ENCODER_NOISE_COUNTS = 2.0
#: The scenario every case starts from (a shipped name or a path): the robot as built.
DEFAULT_BASE = DEFAULT_SCENARIO
#: Encoder resolutions of the encoder table (bits: 2^bits counts per crank turn), run with the
#: five distinct weight ratios omega_Q / omega_R on the paper manoeuvre.
ENCODER_BITS = (12, 14, 16, 17, 20)
RATIO_LQI = ("lqi_10_0.1", "lqi_10_1", "lqi_1_1", "lqi_1_10", "lqi_0.1_10")
#: Tool disturbances (world frame, on the tool tip) while holding home: from t = 1 s on.
DISTURBANCES = {"push 5 N": ToolDisturbance("push", 5.0, [1.0, 0.0, 0.0]),
                "twist 0.2 N m": ToolDisturbance("twist", 0.2, [0.0, 0.0, 1.0]),
                "contact 2 Hz": ToolDisturbance("contact", 3.0, [0.0, 0.0, -1.0],
                                                frequency_hz=2.0)}
#: Motor torque limit of the "saturation" condition, N m. It runs on the Z step, whose transient
#: asks for 1.5 to 7.6 N m. On the paper manoeuvre, which needs at most 0.41 N m once on its
#: way, any limit below that loses the platform (it rolls past phi = 0.52 rad and falls: physics,
#: not the controller), and any limit above it never acts.
TORQUE_LIMIT_NM = 0.6
def _noise(scenario: Scenario) -> None:
    if scenario.hardware is not None:
        scenario.hardware.encoders.noise_counts = ENCODER_NOISE_COUNTS
    else:
        scenario.sensor_noise = SensorNoise(std=list(NOISE_STD))


def _set(**fields):
    return lambda scenario: [setattr(scenario, k, v) for k, v in fields.items()]


def _encoder_bits(bits: int):
    def apply(scenario: Scenario) -> None:
        if scenario.hardware is None:
            raise InvalidConfigError("the encoder conditions need a scenario with hardware")
        scenario.hardware.encoders.counts_per_rev = 2 ** bits
    return apply


#: Conditions: a change of the scenario and the reference it runs on (robustness is on the paper
#: manoeuvre but for the saturation, see TORQUE_LIMIT_NM, and the tool disturbances, while
#: holding home).
CONDITIONS = {
    "nominal": (None, None),
    "payload+20%": (_set(payload_scale=1.2), "paper"),
    "payload-20%": (_set(payload_scale=0.8), "paper"),
    "noise": (_noise, "paper"),
    f"saturation {TORQUE_LIMIT_NM:g} N m": (_set(torque_limit_Nm=TORQUE_LIMIT_NM), "step_Z"),
    **{name: (_set(disturbance=d), "home") for name, d in DISTURBANCES.items()},
}
#: The encoder conditions, run only by RATIO_LQI (the encoder table).
ENCODER_CONDITIONS = {f"encoders {b}-bit": (_encoder_bits(b), "paper") for b in ENCODER_BITS}
#: Simulated seconds per scenario.
SCENARIO_DURATION_S = {"paper": 10.0, "helix": 4.0, "sweep_Z": 9.0, "sweep_phi": 9.0,
                       **{f"step_{a}": 2.5 for a in AXIS_NAMES}}
#: Simulated seconds of the runs that only hold home (the tool disturbances).
HOLD_DURATION_S = 3.0
#: Settling band of the step responses, as a fraction of the step.
SETTLING_BAND = 0.02


@dataclass(frozen=True)
class Case:
    """One run of the grid: a controller name, a scenario name, a condition name, a duration."""

    controller: str
    scenario: str
    condition: str = "nominal"
    duration_s: float = 10.0
    base: str = DEFAULT_BASE

    @property
    def key(self) -> str:
        return f"{self.controller} | {self.scenario} | {self.condition}"


def controller_settings(name: str) -> dict:
    """Scenario fields (``controller``, ``tuner``) of a controller name of :data:`CONTROLLERS`.

    Raises:
        InvalidConfigError: unknown name (the message lists the known ones).
    """
    from ..control.tuner import DEFAULT_TUNER_PATH, PAPER_LABEL_TUNER_PATH

    if name.startswith("lqi_"):
        try:
            _, q, r = name.split("_")
            return {"controller": LqiDriver(omega_Q=float(q), omega_R=float(r))}
        except ValueError:
            pass
    elif name == "pd":
        return {"controller": PdDriver()}
    elif name == "ann_best_cost":
        return {"tuner": AnnTunerDriver(weights=str(DEFAULT_TUNER_PATH))}
    elif name == "ann_paper":
        return {"tuner": AnnTunerDriver(weights=str(PAPER_LABEL_TUNER_PATH))}
    raise InvalidConfigError(f"unknown controller {name!r}; choose lqi_<omega_Q>_<omega_R> or "
                             f"one of {CONTROLLERS[-3:]}")


def cases(quick: bool = False, controllers=CONTROLLERS, base: str = DEFAULT_BASE) -> list[Case]:
    """The evaluation grid.

    Every controller runs every scenario in nominal conditions, and each other condition on its
    scenario (:data:`CONDITIONS`); on a base with hardware the five weight ratios also run the
    encoder resolutions (:data:`ENCODER_CONDITIONS`). ``quick`` shortens every run to 1 s
    (sweeps and disturbances 2 s) for tests and notebooks: the tables are then only a smoke
    test, not figures to quote.
    """
    def duration(scenario):
        if quick:
            return 2.0 if scenario.startswith("sweep") or scenario == "home" else 1.0
        return SCENARIO_DURATION_S.get(scenario, HOLD_DURATION_S)

    hardware = load_scenario(base).hardware is not None
    out = []
    for c in controllers:
        for scenario in SCENARIO_DURATION_S:
            out.append(Case(c, scenario, "nominal", duration(scenario), base))
        conditions = dict(CONDITIONS, **(ENCODER_CONDITIONS if hardware and c in RATIO_LQI
                                         else {}))
        for condition, (_, scenario) in conditions.items():
            if scenario is not None:
                out.append(Case(c, scenario, condition, duration(scenario), base))
    return out


def _normalized_rms(rms, scales: LqiScales) -> float:
    """sqrt(mean_i (rms_i / s_i)^2): one tracking figure, with the LQI's error scales
    (1 mrad, 1 mm by default), so angles and positions count alike."""
    return float(np.sqrt(np.mean((np.asarray(rms) / np.asarray(scales.pose)) ** 2)))


def settling_time(t, error, size: float, t_step: float, band: float = SETTLING_BAND):
    """Time after ``t_step`` from which |error| stays within band * |size|, s (None if never).

    Args:
        t: (N,) s. error: (N,) x - x_d on the stepped axis (rad or m). size: the step.
    """
    t = np.asarray(t)
    after = t >= t_step
    outside = after & (np.abs(error) > band * abs(size))
    if not np.any(after):
        return None
    if not np.any(outside):
        return 0.0
    last = int(np.flatnonzero(outside)[-1])
    if last == len(t) - 1:
        return None                                   # still outside at the end of the run
    return float(t[last + 1] - t_step)


def frequency_response(t, y, chirp: ChirpTrajectory, cycles_per_segment: float = 2.0):
    """Gain and phase of y against a sine sweep, segment by segment.

    Each segment spans ``cycles_per_segment`` cycles of the sweep; on it y - offset is fitted by
    least squares with a sin(phase) + b cos(phase) + c, and the gain is |a + i b| / amplitude.

    Returns:
        (f (K,) Hz, gain (K,), phase (K,) rad).
    """
    t = np.asarray(t)
    y = np.asarray(y) - chirp.offset[chirp.axis]
    m = t <= chirp.duration_s
    t, y = t[m], y[m]
    ph = chirp.phase(t)
    seg = np.floor(ph / (2 * np.pi * cycles_per_segment)).astype(int)
    f, gain, phase = [], [], []
    for k in np.unique(seg)[1:]:                      # the first segment holds the start transient
        sel = seg == k
        if sel.sum() < 8:
            continue
        basis = np.stack([np.sin(ph[sel]), np.cos(ph[sel]), np.ones(sel.sum())], axis=1)
        (a, b, _), *_ = np.linalg.lstsq(basis, y[sel], rcond=None)
        f.append(float(np.mean(chirp.frequency(t[sel]))))
        gain.append(float(np.hypot(a, b) / chirp.amplitude))
        phase.append(float(np.arctan2(b, a)))
    return np.array(f), np.array(gain), np.array(phase)


def bandwidth_hz(f, gain):
    """Lowest frequency where the gain falls below -3 dB (1/sqrt 2), log-interpolated; None if
    the gain stays above it over the whole sweep."""
    below = np.flatnonzero(gain < 1 / np.sqrt(2))
    if len(below) == 0:
        return None
    k = int(below[0])
    if k == 0:
        return float(f[0])
    g0, g1 = np.log(gain[k - 1]), np.log(gain[k])
    w = (np.log(1 / np.sqrt(2)) - g0) / (g1 - g0)
    return float(np.exp(np.log(f[k - 1]) + w * (np.log(f[k]) - np.log(f[k - 1]))))


def case_config(case: Case) -> Scenario:
    """The scenario of one case: the base scenario with the case's reference, duration,
    controller and condition."""
    scenario = load_scenario(case.base)
    scenario.reference = NamedReference(case.scenario)
    scenario.duration_s = case.duration_s
    settings = controller_settings(case.controller)
    if "controller" in settings:               # keep the base's LQI options (riccati, ...)
        driver, base = settings["controller"], scenario.controller
        if isinstance(driver, LqiDriver) and isinstance(base, LqiDriver):
            settings["controller"] = dataclasses.replace(base, omega_Q=driver.omega_Q,
                                                         omega_R=driver.omega_R)
    for name, value in settings.items():
        setattr(scenario, name, value)
    if isinstance(scenario.tuner, AnnTunerDriver):     # with the paper's gain switching
        use_paper_tuner(scenario, scenario.tuner)
    change = {**CONDITIONS, **ENCODER_CONDITIONS}[case.condition][0]
    if change is not None:
        change(scenario)
    return scenario.validate()


def case_id(case: Case) -> str:
    """The case's job id and file stem: ``controller__scenario__condition``, filename-safe."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", f"{case.controller}__{case.scenario}__"
                  f"{case.condition}")


def run_case(case: Case, divergence_dir: str | None = None) -> dict:
    """Simulate one case and reduce it to a row of figures (a plain, picklable dict).

    Args:
        case: the case.  divergence_dir: where the logs of a diverged run go (default: the
            base scenario's ``guard.divergence_dir``).

    Returns:
        the row: ``case`` (its fields), the run's metrics, ``normalized_rms``, the feedback
        effort ``sum_dT2_dt``, ``mean_omega``, ``wall_s`` (build and run, s) and per scenario
        the settling time, overshoot and trace (steps) or the frequency response (sweeps).
    Raises:
        whatever the run raises (a refused reference, a diverged simulation); the runner turns
        it into a :class:`~.runners.JobFailure` and :func:`evaluate` into a row with ``error``.
    """
    t0 = time.perf_counter()
    row = {"case": asdict(case)}
    config = case_config(case)
    if divergence_dir is not None:
        config.guard.divergence_dir = str(divergence_dir)
    result = run_experiment(config)
    m = result.metrics
    row.update({k: m[k] for k in ("rms_error", "peak_error", "peak_torque", "sum_T2_dt",
                                  "max_closure_m", "realtime_factor", "finite", "window_s",
                                  "status")})
    row["normalized_rms"] = _normalized_rms(m["rms_error"], LqiScales())
    # The controller's own effort: what it adds to the gravity feed-forward of the nominal robot
    # (Sum T^2 dt is dominated by holding the platform up, the same for every controller).
    dT = result.T - feedforward_torques(config.geometry(), result.x_d[:, :6])
    dt = np.diff(result.t, prepend=result.t[0])
    row["sum_dT2_dt"] = float(np.sum(dT ** 2 * dt[:, None]))
    row["mean_omega"] = (None if result.omega is None
                         else [float(v) for v in np.mean(result.omega, axis=0)])
    trajectory = config.make_reference()
    if isinstance(trajectory, StepTrajectory):
        k = trajectory.axis
        err = result.x[:, k] - result.x_d[:, k]
        row["settling_time_s"] = settling_time(result.t, err, trajectory.size, trajectory.t_step)
        row["overshoot"] = float(max(0.0, np.max(np.sign(trajectory.size) * err)
                                     / abs(trajectory.size)))
        stride = max(1, len(result.t) // 400)
        row["trace"] = {"t": result.t[::stride].tolist(),
                        "y": (result.x[::stride, k] - trajectory.offset[k]).tolist()}
    if isinstance(trajectory, ChirpTrajectory):
        f, gain, phase = frequency_response(result.t, result.x[:, trajectory.axis], trajectory)
        row["bandwidth_hz"] = bandwidth_hz(f, gain)
        row["peak_gain_db"] = float(20 * np.log10(gain.max())) if len(gain) else None
        row["response"] = {"f": f.tolist(), "gain": gain.tolist(), "phase": phase.tolist()}
    row["wall_s"] = time.perf_counter() - t0
    return row


#: What a finished row holds (:func:`run_case`) and the report reads: name -> (JSON types,
#: or "6" for six numbers), per scenario prefix ("" for every row).
ROW_FIELDS = {"": {"rms_error": "6", "peak_error": "6", "peak_torque": "6",
                   "sum_T2_dt": (int, float), "normalized_rms": (int, float),
                   "sum_dT2_dt": (int, float), "max_closure_m": (int, float)},
              "step_": {"settling_time_s": (int, float, type(None)), "overshoot": (int, float),
                        "trace": dict},
              "sweep_": {"bandwidth_hz": (int, float, type(None)),
                         "peak_gain_db": (int, float, type(None)), "response": dict}}


def load_row(store: ResultStore, job_id: str, case: Case) -> dict:
    """The row :func:`evaluate` stored for ``case``, checked before it is reused: a JSON object
    that holds this very case (not another case's row a damaged manifest points at) and either
    its ``error`` or every figure of :data:`ROW_FIELDS`.

    Raises:
        CorruptFileError: names the file and what is wrong (delete it and run again).
    """
    from ..errors import CorruptFileError

    row = store.load_json(job_id)
    path = store.folder / store.manifest["jobs"][job_id]["file"]

    def bad(problem):
        return CorruptFileError(path, "evaluation row", problem, "delete it and run the same "
                                "command again to redo that case")

    if not isinstance(row, dict):
        raise bad(f"a JSON {type(row).__name__}, not an object")
    if "case" not in row:
        raise bad("the entry 'case' is missing")
    if row["case"] != json.loads(json.dumps(asdict(case))):
        other = row["case"]
        name = (" | ".join(str(other.get(k)) for k in ("controller", "scenario", "condition"))
                if isinstance(other, dict) else repr(other)[:80])
        raise bad(f"it holds the row of another case ({name}), not of {case.key}")
    if "error" in row:
        if not isinstance(row["error"], str):
            raise bad("the entry 'error' must be a string")
        return row
    for prefix, fields in ROW_FIELDS.items():
        if not case.scenario.startswith(prefix):
            continue
        for name, kind in fields.items():
            value = row.get(name)
            ok = (isinstance(value, list) and len(value) == 6 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
                  if kind == "6" else isinstance(value, kind) and not isinstance(value, bool))
            if not ok:
                what = "6 numbers" if kind == "6" else "an object" if kind is dict else "a number"
                raise bad(f"the entry {name!r} is missing or not {what}")
    return row


# -- the report -----------------------------------------------------------------------------------

def _fmt(v, scale=1.0, digits=3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and not np.isfinite(v):
        return "inf"
    return f"{scale * v:.{digits}g}"


def _index(rows) -> dict:
    return {(r["case"]["controller"], r["case"]["scenario"], r["case"]["condition"]): r
            for r in rows}


def ann_verdict(rows, scenario: str = "paper", condition: str = "nominal") -> dict:
    """Does the ANN-tuned LQI beat the best fixed-gain LQI on tracking at no more effort?

    Effort is the *feedback* effort, Sum (T - T_ff)^2 dt (``sum_dT2_dt``): the total Sum T^2 dt
    is set by gravity and the motion, the same for every controller to a few per mille.
    "Best fixed-gain LQI" is the fixed pair with the lowest normalized RMS among those whose
    feedback effort is no more than the ANN run's (the fair comparison); the ANN wins if its
    normalized RMS is lower. One run of one task: the tuner study (:mod:`.tuner_study`) is the
    verdict over held-out tasks. Returns a dict per ANN variant with both figures and the ratio.
    """
    by = _index(rows)
    out = {}
    for ann in ("ann_best_cost", "ann_paper"):
        a = by.get((ann, scenario, condition))
        if a is None or "error" in a:
            continue
        fixed = [by[(c, scenario, condition)] for c in FIXED_LQI
                 if (c, scenario, condition) in by and "error" not in by[(c, scenario, condition)]]
        admissible = [r for r in fixed if r["sum_dT2_dt"] <= a["sum_dT2_dt"] * (1 + 1e-9)]
        best_overall = min(fixed, key=lambda r: r["normalized_rms"]) if fixed else None
        best = min(admissible, key=lambda r: r["normalized_rms"]) if admissible else None
        dominated_by = [r["case"]["controller"] for r in fixed
                        if r["normalized_rms"] < a["normalized_rms"]
                        and r["sum_dT2_dt"] < a["sum_dT2_dt"]]
        out[ann] = {
            "ann": a, "best_fixed": best, "best_fixed_overall": best_overall,
            "dominated_by": dominated_by,
            "beats": bool(best is not None and a["normalized_rms"] < best["normalized_rms"]),
            "ratio": (a["normalized_rms"] / best["normalized_rms"]) if best else None,
        }
    return out


def _disturbance_statics(base: str) -> str:
    """One sentence per tool disturbance: the static crank torque holding home under its peak
    wrench needs (:func:`~stewart_drake.model.statics.tool_load_torques`), against the motors'
    limit of the base scenario: above it, no controller can hold the pose."""
    scenario = load_scenario(base)
    limit = scenario.torque_limit()
    g = scenario.geometry()
    parts = []
    for name, d in DISTURBANCES.items():
        need = float(np.abs(statics.tool_load_torques(g, X_HOME, d.wrench(
            [d.start_s + 0.5 / d.frequency_hz if d.kind == "contact" else d.start_s])[0])).max())
        verdict = ("" if limit is None else
                   " (beyond the motors' limit: no controller can hold it)" if need > limit
                   else " (within the motors' limit)")
        parts.append(f"{name} {need:.3f} N m{verdict}")
    return ("Static crank torque needed to hold home under each disturbance's peak wrench "
            f"(gravity included; motors' limit {'none' if limit is None else f'{limit:.3f} N m'})"
            ": " + "; ".join(parts) + ".")


def render_markdown(rows, info: dict, tuner: dict | None = None) -> str:
    """The text of docs/results.md from the grid's rows (see module docstring), led by the tuner
    study's section when ``tuner`` (its summary) is given."""
    by = _index(rows)
    ctrls = [c for c in CONTROLLERS if any(k[0] == c for k in by)]
    L = ["# Evaluation results", "",
         "Generated by `stewart-drake evaluate` "
         f"({info['n_cases']} runs whose own times add up to "
         f"{sum(float(r.get('wall_s') or 0.0) for r in rows):.0f} s; this call "
         f"{info['wall_s']:.0f} s wall on {info['workers']} workers"
         + (f", {info['reused']} runs read back from an earlier call" if info.get("reused")
            else "")
         + f"{', QUICK mode: smoke-test durations, not figures to quote' if info['quick'] else ''})."
         " Do not edit by hand: rerun the command.", "",
         f"Every run starts from the scenario `{info.get('base', DEFAULT_BASE)}` "
         "(`stewart-drake scenario` prints it; docs/hardware.md describes the robot as built).",
         ""]
    if tuner is not None:
        from .tuner_study import render_tuner_markdown

        L += [render_tuner_markdown(tuner), "## The controller grid", ""]
    L += ["Units: angles in mrad, positions in mm, torques in N m, Sum T^2 dt in N^2 m^2 s. "
          "RMS and peak errors are over the second half of each run (the true pose from the "
          "plant state, not the noisy measurement). `nRMS` = sqrt(mean_i (RMS_i / s_i)^2) with "
          "the LQI's error scales s = 1 mrad | 1 mm. RTF = real-time factor of that run in its "
          "worker process.", ""]

    def errors_row(r):
        return f"| {r['case']['controller']} | failed: {r['error'].splitlines()[0][:120]} |"

    def nominal_rows(scenario):
        """(controller, row) of the runs of ``scenario`` that succeeded; a failed run's line is
        written to the table on the way."""
        for c in ctrls:
            r = by.get((c, scenario, "nominal"))
            if r is None:
                continue
            if "error" in r:
                L.append(errors_row(r))
                continue
            yield c, r

    # 1. Paper manoeuvre, nominal.
    L += ["## Paper manoeuvre (eqs. 37-38), nominal", "",
          "| controller | phi | theta | psi | X | Y | Z | peak phi | peak Z | nRMS | Sum T^2 dt | "
          "feedback Sum dT^2 dt | peak T | max closure [m] | RTF |",
          "|---|" + "---|" * 14]
    for c, r in nominal_rows("paper"):
        rms, peak = r["rms_error"], r["peak_error"]
        L.append(f"| {c} | " + " | ".join(_fmt(v, 1e3) for v in rms)
                 + f" | {_fmt(peak[0], 1e3)} | {_fmt(peak[5], 1e3)} | {_fmt(r['normalized_rms'])}"
                 f" | {_fmt(r['sum_T2_dt'])} | {_fmt(r['sum_dT2_dt'])}"
                 f" | {_fmt(max(r['peak_torque']))} | {_fmt(r['max_closure_m'], digits=2)} | {_fmt(r['realtime_factor'], digits=2)} |")
    L.append("")

    # 2. Verdict.
    L += ["## Does the ANN tuner beat the best fixed-gain LQI?", ""]
    for ann, v in ann_verdict(rows).items():
        a, b = v["ann"], v["best_fixed"]
        if b is None:
            L.append(f"- **{ann}**: no fixed-gain LQI uses as little feedback effort (Sum dT^2 dt "
                     f"{_fmt(a['sum_dT2_dt'])}); the closest in effort is compared in the table.")
            continue
        verdict = "beats" if v["beats"] else "does not beat"
        L.append(f"- **{ann} {verdict}** the best fixed-gain LQI at no more effort, "
                 f"{b['case']['controller']}: nRMS {_fmt(a['normalized_rms'])} vs "
                 f"{_fmt(b['normalized_rms'])} (ratio {_fmt(v['ratio'])}), feedback Sum dT^2 dt "
                 f"{_fmt(a['sum_dT2_dt'])} vs {_fmt(b['sum_dT2_dt'])}. Best fixed pair regardless of "
                 f"effort: {v['best_fixed_overall']['case']['controller']} (nRMS "
                 f"{_fmt(v['best_fixed_overall']['normalized_rms'])}). "
                 + (f"Fixed pairs better on both tracking and effort: "
                    f"{', '.join(v['dominated_by'])}." if v["dominated_by"] else
                    "No fixed pair is better on both tracking and effort (the ANN run is on the "
                    "fixed pairs' Pareto front)."))
    L += ["", "One run of the paper manoeuvre each: the verdict over held-out tasks is the tuner "
          "study at the top. Effort here is the feedback effort, `feedback Sum dT^2 dt`, what the "
          "controller adds to the gravity feed-forward: Sum T^2 dt is mostly the torque that "
          "holds the platform up, the same for every controller. The 9 fixed pairs are 5 distinct controllers: "
          "only omega_Q / omega_R matters (scaling Q and R together leaves the gain unchanged), "
          "so rows with the same ratio repeat.", ""]

    # 3. Steps.
    L += ["## Steps (20 mrad on angles, 5 mm on positions, at t = 0.5 s)", "",
          f"Settling time to a {100 * SETTLING_BAND:g} % band, s (`-`: not settled in the run), and "
          "Sum T^2 dt of all six step runs.", "",
          "| controller | " + " | ".join(AXIS_NAMES) + " | max overshoot | Sum T^2 dt |",
          "|---|" + "---|" * 8]
    for c in ctrls:
        rs = [by.get((c, f"step_{a}", "nominal")) for a in AXIS_NAMES]
        if any(r is None for r in rs):
            continue
        if any("error" in r for r in rs):
            L.append(errors_row(next(r for r in rs if "error" in r)))
            continue
        L.append(f"| {c} | " + " | ".join(_fmt(r["settling_time_s"]) for r in rs)
                 + f" | {_fmt(100 * max(r['overshoot'] for r in rs))} %"
                 f" | {_fmt(sum(r['sum_T2_dt'] for r in rs))} |")
    L.append("")

    # 4. Helix.
    L += ["## Helix (5 mm circle in X-Y at 2 Hz, Z 3 mm at 0.25 Hz, theta 20 mrad at 1 Hz)", "",
          "| controller | theta RMS | X RMS | Y RMS | Z RMS | X peak | Y peak | nRMS | Sum T^2 dt "
          "| peak T |", "|---|" + "---|" * 9]
    for c, r in nominal_rows("helix"):
        rms, peak = r["rms_error"], r["peak_error"]
        L.append(f"| {c} | {_fmt(rms[1], 1e3)} | {_fmt(rms[3], 1e3)} | {_fmt(rms[4], 1e3)} | "
                 f"{_fmt(rms[5], 1e3)} | {_fmt(peak[3], 1e3)} | {_fmt(peak[4], 1e3)} | "
                 f"{_fmt(r['normalized_rms'])} | {_fmt(r['sum_T2_dt'])} | "
                 f"{_fmt(max(r['peak_torque']))} |")
    L.append("")

    # 5. Bandwidth.
    L += ["## Bandwidth (sine sweep 1 -> 50 Hz: 0.2 mm on Z, 2 mrad on phi)", "",
          "-3 dB bandwidth of the pose's response to the reference, Hz (`> 50`: above the sweep), "
          "and the peak gain, dB.", "",
          "| controller | Z bandwidth | Z peak gain | phi bandwidth | phi peak gain |",
          "|---|---|---|---|---|"]
    for c in ctrls:
        rz, rp = by.get((c, "sweep_Z", "nominal")), by.get((c, "sweep_phi", "nominal"))
        if rz is None or rp is None:
            continue
        if "error" in rz or "error" in rp:
            L.append(errors_row(rz if "error" in rz else rp))
            continue

        def bw(r):
            return _fmt(r["bandwidth_hz"]) if r["bandwidth_hz"] is not None else "> 50"

        L.append(f"| {c} | {bw(rz)} | {_fmt(rz['peak_gain_db'], digits=2)} | {bw(rp)} | "
                 f"{_fmt(rp['peak_gain_db'], digits=2)} |")
    L.append("")

    # 6. Robustness.
    paper_conds = [k for k, (_, scen) in CONDITIONS.items() if scen in (None, "paper")]
    sat = next(k for k, (_, scen) in CONDITIONS.items() if scen == "step_Z")
    L += ["## Robustness", "",
          "On the paper manoeuvre: nRMS (and Sum T^2 dt) per condition. Payload: platform mass "
          "and inertia scaled, unknown to the controller. Noise: 1 sigma "
          f"{NOISE_STD[0] * 1e3:g} mrad, {NOISE_STD[3] * 1e3:g} mm, {NOISE_STD[6]:g} rad/s, "
          f"{NOISE_STD[9]:g} m/s on the measured pose and rate, white at 1 kHz. Saturation: "
          f"|T_i| <= {TORQUE_LIMIT_NM:g} N m on the 5 mm Z step (its settling time and overshoot; "
          "the unsaturated ones are in the step table). The paper manoeuvre needs 0.41 N m at "
          "most: below that the platform rolls past its reference and falls whatever the "
          "controller, above it the limit never acts.", "",
          "| controller | " + " | ".join(paper_conds) + " | worst phi RMS [mrad] | worst Z RMS "
          f"[mm] | {sat}: settling [s] | overshoot |",
          "|---|" + "---|" * (len(paper_conds) + 4)]
    for c in ctrls:
        rs = [by.get((c, "paper", k)) for k in paper_conds]
        rsat = by.get((c, "step_Z", sat))
        if any(r is None for r in rs) or rsat is None:
            continue
        cells = []
        for r in rs:
            cells.append("failed" if "error" in r else
                         f"{_fmt(r['normalized_rms'])} ({_fmt(r['sum_T2_dt'])})")
        ok = [r for r in rs if "error" not in r]
        worst_phi = max((r["rms_error"][0] for r in ok), default=None)
        worst_z = max((r["rms_error"][5] for r in ok), default=None)
        sat_cells = (["failed", "-"] if "error" in rsat else
                     [_fmt(rsat["settling_time_s"]), f"{_fmt(100 * rsat['overshoot'])} %"])
        L.append(f"| {c} | " + " | ".join(cells) + f" | {_fmt(worst_phi, 1e3)} | "
                 f"{_fmt(worst_z, 1e3)} | " + " | ".join(sat_cells) + " |")
    L.append("")
    # 7. Encoders.
    enc = [k for k in ENCODER_CONDITIONS]
    if any(key[2] in enc for key in by):
        L += ["## Encoder resolution (paper manoeuvre)", "",
              "RMS error per axis in urad and um, the feedback effort Sum (T - T_ff)^2 dt in "
              "N^2 m^2 s (what the controller adds to the gravity feed-forward) and the peak "
              "torque in N m, for each encoder resolution and the five distinct weight ratios "
              "omega_Q / omega_R (100, 10, 1, 0.1, 0.01).", "",
              "| encoder | controller | phi | theta | psi | X | Y | Z | feedback Sum dT^2 dt | "
              "peak T |", "|---|---|" + "---|" * 8]
        for condition in enc:
            for c in RATIO_LQI:
                r = by.get((c, "paper", condition))
                if r is None:
                    continue
                if "error" in r:
                    L.append(f"| {condition} | {c} | failed: {r['error'].splitlines()[0][:90]} |")
                    continue
                L.append(f"| {condition.split()[1]} | {c} | "
                         + " | ".join(_fmt(v, 1e6) for v in r["rms_error"])
                         + f" | {_fmt(r['sum_dT2_dt'])} | {_fmt(max(r['peak_torque']))} |")
        L.append("")
    # 8. Tool disturbances.
    if any(key[2] in DISTURBANCES for key in by):
        L += ["## Tool disturbances (holding home; from t = 1 s)", "",
              "Peak and RMS pose error over the second half of each run: angles in mrad, "
              "positions in mm. " + "; ".join(
                  f"{name}: {d.kind} {d.magnitude:g} {'N m' if d.kind == 'twist' else 'N'} along "
                  f"{d.direction}" + (f" at {d.frequency_hz:g} Hz" if d.kind == "contact" else "")
                  for name, d in DISTURBANCES.items()) + ".", "",
              _disturbance_statics(info.get("base", DEFAULT_BASE)), "",
              "| controller | " + " | ".join(f"{n}: peak angle | peak position | nRMS"
                                          for n in DISTURBANCES) + " |",
              "|---|" + "---|" * (3 * len(DISTURBANCES))]
        for c in ctrls:
            cells = []
            for name in DISTURBANCES:
                r = by.get((c, "home", name))
                cells += (["-"] * 3 if r is None else ["failed", "-", "-"] if "error" in r else
                          [_fmt(max(r["peak_error"][:3]), 1e3), _fmt(max(r["peak_error"][3:]), 1e3),
                           _fmt(r["normalized_rms"])])
            L.append(f"| {c} | " + " | ".join(cells) + " |")
        L.append("")
    failed = [r for r in rows if "error" in r]
    L += ["## Runs that failed", ""]
    L += ([f"- {r['case']['controller']} / {r['case']['scenario']} / {r['case']['condition']}: "
           f"{r['error'].splitlines()[0]}" for r in failed] or ["None."])
    L += ["", "## Pictures", "",
          "![tracking vs effort](results_tradeoff.png)", "",
          "![frequency responses](results_bandwidth.png)", "",
          "![step responses](results_steps.png)", ""]
    return "\n".join(L)


def _ratio(controller: str) -> float | None:
    """omega_Q / omega_R of a fixed LQI name (``lqi_10_1`` -> 10), None for the others."""
    if not controller.startswith("lqi_"):
        return None
    _, q, r = controller.split("_")
    return float(q) / float(r)


#: How the controllers that are not a fixed LQI are drawn in the plots: label, marker, colour.
_OTHERS = {"pd": ("crank-space PD", "s", "C3"),
           "ann_best_cost": ("ANN tuner, best-cost labels", "*", "C1"),
           "ann_paper": ("ANN tuner, paper labels", "D", "C6")}


def _ratio_colors(ratios) -> dict:
    """One colour per omega_Q / omega_R, soft (yellow) to stiff (purple): viridis, which the
    red, orange and pink of the other controllers do not resemble."""
    import matplotlib

    ratios = sorted(set(ratios))
    shades = matplotlib.colormaps["viridis"](np.linspace(0.9, 0.05, max(len(ratios), 2)))
    return {r: shades[k] for k, r in enumerate(ratios)}


def _by_ratio(by: dict, scenario: str, condition: str) -> dict:
    """{ratio: row} of the fixed LQIs that ran (scenario, condition); pairs of one ratio are one
    controller (only the ratio sets the gain), the first one stands for them."""
    out = {}
    for c in FIXED_LQI:
        r = by.get((c, scenario, condition))
        if r is not None and "error" not in r:
            out.setdefault(_ratio(c), r)
    return dict(sorted(out.items()))


def plot_results(rows, out_dir: str | Path) -> list[Path]:
    """Three PNGs in out_dir: tracking vs feedback effort (paper manoeuvre, nominal and with
    noise), frequency responses (Z and phi sweeps), step responses (Z step). Fixed LQIs are one
    line or point per weight ratio omega_Q / omega_R (the nine pairs are five controllers).
    Returns their paths."""
    import matplotlib.ticker
    from matplotlib.figure import Figure  # no pyplot: no global backend switch

    out_dir = Path(out_dir)
    by = _index(rows)
    paths = []
    colors = _ratio_colors(_ratio(c) for c in FIXED_LQI)

    def save(fig, name):
        path = out_dir / name
        atomic_write(path, lambda f: fig.savefig(f, dpi=100, format="png"))
        paths.append(path)

    # 1. Tracking against the feedback effort, the figure of the ANN verdict.
    fig = Figure(figsize=(12, 5.2))
    axes = fig.subplots(1, 2)
    for ax, condition, title in ((axes[0], "nominal", "nominal"),
                                 (axes[1], "noise", "with sensor noise")):
        fixed = _by_ratio(by, "paper", condition)
        if fixed:
            x = [r["sum_dT2_dt"] for r in fixed.values()]
            y = [r["normalized_rms"] for r in fixed.values()]
            ax.plot(x, y, "-", color="0.75", lw=1, zorder=1)
            ax.scatter(x, y, s=60, c=[colors[k] for k in fixed], edgecolors="k", lw=0.5,
                       zorder=2, label=r"fixed LQI, labelled by $\omega_Q/\omega_R$")
            for ratio, xi, yi in zip(fixed, x, y):
                ax.annotate(f"{ratio:g}", (xi, yi), xytext=(6, -3), textcoords="offset points",
                            fontsize=8, color="0.25")
        for c, (label, marker, color) in _OTHERS.items():
            r = by.get((c, "paper", condition))
            if r is None or "error" in r:
                continue
            # hollow, drawn on top: a point under it stays visible
            ax.plot(r["sum_dT2_dt"], r["normalized_rms"], marker, mfc="none", mec=color,
                    mew=1.8, ms=15 if marker == "*" else 10, ls="none", zorder=3, label=label)
        ax.set_xscale("log")
        ax.set_yscale("log")
        for axis in (ax.xaxis, ax.yaxis):             # 0.02, not 2 x 10^-2
            axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(matplotlib.ticker.FuncFormatter(
                lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""))
        ax.set_xlabel(r"feedback effort $\sum (T - T_{ff})^2 \Delta t$ [N$^2$ m$^2$ s]")
        ax.set_title(f"paper manoeuvre, {title}", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper left")
    axes[0].set_ylabel("normalized RMS tracking error (1 = 1 mrad | 1 mm)")
    fig.suptitle("Tracking against feedback effort: lower left is better", fontsize=11)
    fig.tight_layout()
    save(fig, "results_tradeoff.png")

    # 2. Frequency responses.
    fig = Figure(figsize=(12, 4.8))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, scen in zip(axes, ("sweep_Z", "sweep_phi")):
        for ratio, r in _by_ratio(by, scen, "nominal").items():
            if r["response"]["f"]:
                ax.semilogx(r["response"]["f"], 20 * np.log10(r["response"]["gain"]),
                            color=colors[ratio], lw=1.2,
                            label=rf"LQI $\omega_Q/\omega_R$ = {ratio:g}")
        for c, (label, _, color) in _OTHERS.items():
            r = by.get((c, scen, "nominal"))
            if r is None or "error" in r or not r["response"]["f"]:
                continue
            ax.semilogx(r["response"]["f"], 20 * np.log10(r["response"]["gain"]), color=color,
                        lw=1.2, ls="--", label=label)
        ax.axhline(-3, color="k", ls=":", lw=1)
        ax.annotate("-3 dB: the bandwidth is where a gain crosses it", (0.01, -3),
                    xycoords=("axes fraction", "data"), xytext=(0, -10),
                    textcoords="offset points", fontsize=8, ha="left")
        ax.xaxis.set_major_locator(matplotlib.ticker.FixedLocator([1, 2, 5, 10, 20, 50]))
        ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("frequency [Hz]")
        axis = scen.replace("sweep_", "")
        ax.set_title(f"reference to pose, {axis}: sine sweep 1 to 50 Hz", fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("gain [dB]")
    axes[1].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    save(fig, "results_bandwidth.png")

    # 3. Step responses.
    fig = Figure(figsize=(9, 4.8))
    ax = fig.subplots()
    for ratio, r in _by_ratio(by, "step_Z", "nominal").items():
        ax.plot(r["trace"]["t"], 1e3 * np.asarray(r["trace"]["y"]), color=colors[ratio], lw=1,
                label=rf"LQI $\omega_Q/\omega_R$ = {ratio:g}")
    for c, (label, _, color) in _OTHERS.items():
        r = by.get((c, "step_Z", "nominal"))
        if r is None or "error" in r:
            continue
        ax.plot(r["trace"]["t"], 1e3 * np.asarray(r["trace"]["y"]), color=color, lw=1.5,
                label=label)
    for c in ("lqi_1_1", "pd", "ann_best_cost"):
        rs = next((v for k, v in by.items() if k[0] == c and k[1] == "step_Z"
                   and k[2] != "nominal" and "error" not in v), None)
        if rs is not None:
            ax.plot(rs["trace"]["t"], 1e3 * np.asarray(rs["trace"]["y"]), ls="--", lw=1,
                    color=_OTHERS.get(c, (None, None, colors[1.0]))[2],
                    label=f"{_OTHERS.get(c, ('LQI ratio 1',))[0]}, |T| <= "
                          f"{TORQUE_LIMIT_NM:g} N m")
    ax.set_xlim(0.4, 1.2)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("Z - Z_home [mm]")
    ax.set_title("5 mm step on Z at t = 0.5 s")
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, "results_steps.png")
    return paths


def evaluation_settings(quick: bool, base: str = DEFAULT_BASE) -> dict:
    """What decides every row (hashed by the store; the controller subset is not part of it:
    rows of a subset are reused by a run of the whole grid): the base scenario (as YAML),
    durations, conditions, and the bytes of the ANN tuners' weights."""
    from ..control.tuner import DEFAULT_TUNER_PATH, PAPER_LABEL_TUNER_PATH

    return {"quick": bool(quick), "scenario_duration_s": SCENARIO_DURATION_S,
            "base": dump_scenario(load_scenario(base)),
            "conditions": sorted({**CONDITIONS, **ENCODER_CONDITIONS}),
            "tuner_weights": {p.name: file_digest(p)
                              for p in (DEFAULT_TUNER_PATH, PAPER_LABEL_TUNER_PATH)}}


def evaluate(docs_dir: str | Path = "docs", out_dir: str | Path = "results/evaluation",
             runner=None, progress: bool = True, quick: bool = False,
             controllers=CONTROLLERS, base: str = DEFAULT_BASE,
             tuner_study: bool = False) -> dict:
    """Run the tuner study and the grid, keeping each result on disk as it arrives, then write
    the report, which leads with the tuner study's verdict (:mod:`.tuner_study`).

    Rows go to ``out_dir/rows/<case_id>.json`` the moment a case finishes (a failed case is a
    row with ``error`` and ``traceback``; a divergence dump goes to ``out_dir/diverged/``), with
    ``out_dir/manifest.json`` (:mod:`.store`); run again with the same settings, only missing
    cases run. Once every row of the grid is on disk, ``rows.json`` and the report are built
    from them (see module docstring), so a report that fails to write loses no row.

    Args:
        docs_dir: where results.md and the PNGs go. out_dir: rows, manifest, rows.json.
        runner: :class:`~.runners.ProcessRunner` (default) or any runner of :mod:`.runners`.
        quick: 1-2 s runs (smoke test), flagged in the report (other settings than a full run).
        controllers: subset of :data:`CONTROLLERS`.
        base: the scenario every case starts from (a shipped name or a .yaml path; default the
            robot as built, ``paper_hardware``).
        tuner_study: run the tuner study into ``out_dir/tuner_study`` first and lead
            the report with it (``stewart-drake evaluate`` does, unless ``--no-tuner-study``).
    Returns:
        dict with ``rows`` (grid order), ``wall_s`` (this call), ``paths``, ``verdict``,
        ``info`` (``ran`` and ``reused`` count the cases run now and found on disk) and
        ``tuner`` (the tuner study's summary, or None).
    Raises:
        InvalidConfigError: an unknown controller (before any run).
        ResultsMismatchError: ``out_dir`` holds rows of other settings (e.g. ``--quick``).
        IncompleteResultsError: cases were lost with their worker (the others are on disk), or
            every case failed (rows.json is written, the report in ``docs_dir`` is left as it
            was).
        Interrupted: Ctrl-C, SIGTERM or SIGHUP; the finished rows are on disk.
    """
    for c in controllers:
        controller_settings(c)                        # unknown names fail before any run
    grid = cases(quick, controllers, base)
    grid.sort(key=lambda c: -c.duration_s)            # longest first: better load balance
    jobs = {case_id(c): c for c in grid}
    runner = runner or ProcessRunner()
    out_dir, docs_dir = Path(out_dir), Path(docs_dir)
    check_base = load_scenario(base)                  # a bad base fails before any run
    del check_base
    tuner = None
    if tuner_study:
        from .tuner_study import run_tuner_study

        tuner = run_tuner_study(out_dir / "tuner_study", runner, base=base, quick=quick,
                                progress=progress)
    store = ResultStore(out_dir, "evaluate", evaluation_settings(quick, base),
                        pattern="rows/*.json")

    def save(job_id, row):
        if isinstance(row, JobFailure):
            row = {"case": asdict(jobs[job_id]), "error": str(row), "traceback": row.traceback}
        store.put_json(job_id, f"rows/{job_id}.json", row, wall_s=row.get("wall_s"),
                       failed="error" in row)

    fn = functools.partial(run_case, divergence_dir=str(out_dir / "diverged"))
    ran = run_jobs(store, runner, fn, jobs, save, progress, "evaluation runs", "cases")
    rows = [load_row(store, k, jobs[k]) for k in jobs]
    info = {"n_cases": len(grid), "wall_s": ran["wall_s"], "workers": runner.n_workers,
            "quick": quick, "ran": len(ran["ran"]), "reused": len(ran["reused"]),
            "base": str(base)}
    store.finish(True, info=info)
    payload = json.dumps({"info": info, "rows": rows}, indent=1, default=float)
    atomic_write(out_dir / "rows.json", lambda f: f.write(payload.encode()))
    if rows and all("error" in r for r in rows):
        first = rows[0]["error"].splitlines()[0]
        raise IncompleteResultsError(
            f"all {len(rows)} cases failed (first: {first:.200}); the report in {docs_dir} was "
            f"not replaced; the failures are in {out_dir / 'rows.json'} (delete {out_dir} to "
            f"run them again)")
    paths = plot_results(rows, docs_dir)
    if tuner is not None:
        from .tuner_study import plot_tuner_tradeoff

        paths.append(plot_tuner_tradeoff(tuner, docs_dir / "results_tuner.png"))
    text = render_markdown(rows, info, tuner)
    md = docs_dir / "results.md"
    atomic_write(md, lambda f: f.write(text.encode()))
    paths = [md, out_dir / "rows.json"] + paths
    return {"rows": rows, "wall_s": ran["wall_s"], "paths": paths, "verdict": ann_verdict(rows),
            "info": info, "tuner": tuner}
