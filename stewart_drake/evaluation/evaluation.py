"""The evaluation: every controller on every scenario, side by side.

``stewart-drake evaluate`` runs a grid of :class:`~.evaluation_grid.Case` (controller x
reference x condition) over a runner (:mod:`.runners`, local processes by default), keeps each
row on disk as it arrives (``results/evaluation/rows/``, resumable: :mod:`.store`), and once the
grid is complete writes the report (:mod:`.evaluation_report`):

- ``docs/results.md``: tables generated from the runs (never edited by hand), with the verdict
  on the ANN tuner computed from the numbers;
- ``docs/results_*.png``: the tracking-vs-effort map, frequency responses and step responses;
- ``results/evaluation/rows.json``: every row, for notebooks and further analysis.

Controllers (:func:`~.evaluation_grid.grid_controller`): the LQI at each of the paper's 9 fixed
(omega_Q, omega_R) pairs, the crank-space PD with gravity feed-forward, and the ANN-tuned LQI
with best-cost and with paper labels. References: the paper manoeuvre (eqs. 37-38), a step on
each axis, a helix, and sine sweeps of Z and phi for the -3 dB bandwidth. Conditions (on the
paper manoeuvre): nominal, +-20 % platform mass and inertia unknown to the controller, sensor
noise, motor torque saturation; tool disturbances while holding home; encoder resolutions on the
robot as built.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..base.errors import IncompleteResultsError
from ..base.fileio import atomic_write
from ..control.lqi.driver import LqiScales
from ..execution.runners import JobFailure, ProcessRunner
from ..execution.store import ResultStore, file_digest, run_jobs
from ..references.trajectories import ChirpTrajectory, StepTrajectory
from ..run import metrics
from ..run.plan import robot_geometry, run_reference
from ..run.scenario import dump_scenario
from ..run.scenario_io import load_scenario
from ..run.simulate import run_experiment
from .evaluation_grid import (
    CONDITIONS,
    CONTROLLERS,
    DEFAULT_BASE,
    ENCODER_CONDITIONS,
    SCENARIO_DURATION_S,
    Case,
    case_config,
    case_id,
    cases,
)


def run_case(case: Case, divergence_dir: str | None = None) -> dict:
    """Simulate one case and reduce it to a row of figures (a plain, picklable dict).

    Args:
        case: the case.  divergence_dir: where the logs of a diverged run go (default: the
            base scenario's ``guard.divergence_dir``).

    Returns:
        the row: ``case`` (:meth:`~.evaluation_grid.Case.record`), the run's metrics,
        ``normalized_rms``, the feedback effort ``sum_dT2_dt``
        (:func:`~.metrics.feedback_effort`), ``mean_omega``, ``wall_s`` (build and run, s) and
        per reference the settling time, overshoot and trace (steps) or the frequency response
        (sweeps).
    Raises:
        whatever the run raises (a refused reference, a diverged simulation); the runner turns
        it into a :class:`~.runners.JobFailure` and :func:`evaluate` into a row with ``error``.
    """
    t0 = time.perf_counter()
    row: dict[str, Any] = {"case": case.record()}
    config = case_config(case)
    if divergence_dir is not None:
        guard = dataclasses.replace(config.guard, divergence_dir=str(divergence_dir))
        config = dataclasses.replace(config, guard=guard)
    reference = run_reference(config)  # made once: the run's, and the response's figures'
    result = run_experiment(config, reference=reference)
    m = result.metrics
    row.update(
        {
            k: m[k]
            for k in (
                "rms_error",
                "peak_error",
                "peak_torque",
                "sum_T2_dt",
                "max_closure_m",
                "realtime_factor",
                "finite",
                "window_s",
                "status",
            )
        }
    )
    row["normalized_rms"] = metrics.normalized_rms(m["rms_error"], LqiScales().pose)
    row["sum_dT2_dt"] = metrics.feedback_effort(result, robot_geometry(config))
    row["mean_omega"] = (
        None if result.omega is None else [float(v) for v in np.mean(result.omega, axis=0)]
    )
    row.update(_response_figures(result, reference))
    row["wall_s"] = time.perf_counter() - t0
    return row


def _response_figures(result, trajectory) -> dict:
    """A step's settling time, overshoot and trace (400 samples at most), or a sweep's
    frequency response (gain and phase), -3 dB bandwidth (None with ``bandwidth_where`` "below
    the sweep" or "above the sweep" when the sweep does not bracket it, :class:`~.metrics.
    Bandwidth`) and peak gain; {} for other references."""
    if isinstance(trajectory, StepTrajectory):
        k = trajectory.axis
        err = result.x[:, k] - result.x_d[:, k]
        stride = max(1, len(result.t) // 400)
        return {
            "settling_time_s": metrics.settling_time(
                result.t, err, trajectory.size, trajectory.t_step
            ),
            "overshoot": metrics.overshoot(err, trajectory.size),
            "trace": {
                "t": result.t[::stride].tolist(),
                "y": (result.x[::stride, k] - trajectory.offset[k]).tolist(),
            },
        }
    if isinstance(trajectory, ChirpTrajectory):
        f, gain, phase = metrics.frequency_response(
            result.t, result.x[:, trajectory.axis], trajectory
        )
        bandwidth = metrics.bandwidth_hz(f, gain)
        return {
            "bandwidth_hz": bandwidth.hz,
            "bandwidth_where": bandwidth.where,
            "peak_gain_db": float(20 * np.log10(gain.max())) if len(gain) else None,
            "response": {"f": f.tolist(), "gain": gain.tolist(), "phase": phase.tolist()},
        }
    return {}


#: What a finished row holds (:func:`run_case`) and the report reads: name -> (JSON types,
#: or "6" for six numbers), per scenario prefix ("" for every row).
ROW_FIELDS: dict[str, dict[str, Any]] = {
    "": {
        "rms_error": "6",
        "peak_error": "6",
        "peak_torque": "6",
        "sum_T2_dt": (int, float),
        "normalized_rms": (int, float),
        "sum_dT2_dt": (int, float),
        "max_closure_m": (int, float),
    },
    "step_": {
        "settling_time_s": (int, float, type(None)),
        "overshoot": (int, float),
        "trace": dict,
    },
    "sweep_": {
        "bandwidth_hz": (int, float, type(None)),
        "peak_gain_db": (int, float, type(None)),
        "response": dict,
    },
}


def load_row(store: ResultStore, job_id: str, case: Case) -> dict:
    """The row :func:`evaluate` stored for ``case``, checked before it is reused: a JSON object
    that holds this very case (not another case's row a damaged manifest points at) and either
    its ``error`` or every figure of :data:`ROW_FIELDS`.

    Raises:
        CorruptFileError: names the file and what is wrong (delete it and run again).
    """
    from ..base.errors import CorruptFileError

    row = store.load_json(job_id)
    path = store.folder / store.manifest["jobs"][job_id]["file"]

    def bad(problem):
        return CorruptFileError(
            path,
            "evaluation row",
            problem,
            "delete it and run the same command again to redo that case",
        )

    if not isinstance(row, dict):
        raise bad(f"a JSON {type(row).__name__}, not an object")
    if "case" not in row:
        raise bad("the entry 'case' is missing")
    if row["case"] != json.loads(json.dumps(case.record())):
        other = row["case"]
        name = (
            " | ".join(str(other.get(k)) for k in ("controller", "scenario", "condition"))
            if isinstance(other, dict)
            else repr(other)[:80]
        )
        raise bad(f"it holds the row of another case ({name}), not of {case.key}")
    if "error" in row:
        if not isinstance(row["error"], str):
            raise bad("the entry 'error' must be a string")
        return row
    for prefix, fields in ROW_FIELDS.items():
        if not case.reference.startswith(prefix):
            continue
        for name, kind in fields.items():
            value = row.get(name)
            ok = (
                isinstance(value, list)
                and len(value) == 6
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
                if kind == "6"
                else isinstance(value, kind) and not isinstance(value, bool)
            )
            if not ok:
                what = "6 numbers" if kind == "6" else "an object" if kind is dict else "a number"
                raise bad(f"the entry {name!r} is missing or not {what}")
    return row


def evaluation_settings(quick: bool, base: str = DEFAULT_BASE) -> dict:
    """What decides every row (hashed by the store; the controller subset is not part of it:
    rows of a subset are reused by a run of the whole grid): the base scenario (as YAML),
    durations, conditions, and the bytes of the ANN tuners' weights."""
    from ..control.tuner.ann import DEFAULT_TUNER_PATH, PAPER_LABEL_TUNER_PATH

    return {
        "quick": bool(quick),
        "scenario_duration_s": SCENARIO_DURATION_S,
        "base": dump_scenario(load_scenario(base)),
        "conditions": sorted({**CONDITIONS, **ENCODER_CONDITIONS}),
        "tuner_weights": {
            p.name: file_digest(p) for p in (DEFAULT_TUNER_PATH, PAPER_LABEL_TUNER_PATH)
        },
    }


def evaluate(
    docs_dir: str | Path = "docs",
    out_dir: str | Path = "results/evaluation",
    runner=None,
    progress: bool = True,
    quick: bool = False,
    controllers=CONTROLLERS,
    base: str = DEFAULT_BASE,
    tuner_study: bool = False,
) -> dict:
    """Run the tuner study and the grid, keeping each result on disk as it arrives, then write
    the report, which leads with the tuner study's verdict (:mod:`.tuner_study`).

    Rows go to ``out_dir/rows/<case_id>.json`` as cases finish (a failed case is a row with
    ``error`` and ``traceback``; divergence dumps to ``out_dir/diverged/``), with
    ``out_dir/manifest.json`` (:mod:`.store`): run again, only missing cases run. ``rows.json``
    and the report are built from the rows on disk (docs/evaluation.md, "Studies").

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
    grid = cases(quick, controllers, base)  # unknown names and a bad base fail here
    grid.sort(key=lambda c: -c.duration_s)  # longest first: better load balance
    runner = runner or ProcessRunner()
    out_dir, docs_dir = Path(out_dir), Path(docs_dir)
    tuner = None
    if tuner_study:
        from ..tuner.tuner_study import run_tuner_study

        tuner = run_tuner_study(
            out_dir / "tuner_study", runner, base=base, quick=quick, progress=progress
        )
    rows, info = _run_grid(grid, out_dir, runner, progress, quick, base)
    if rows and all("error" in r for r in rows):
        first = rows[0]["error"].splitlines()[0]
        raise IncompleteResultsError(
            f"all {len(rows)} cases failed (first: {first:.200}); the report in {docs_dir} was "
            f"not replaced; the failures are in {out_dir / 'rows.json'} (delete {out_dir} to "
            f"run them again)"
        )
    from .evaluation_report import ann_verdict, write_report

    paths = write_report(rows, info, tuner, docs_dir)
    return {
        "rows": rows,
        "wall_s": info["wall_s"],
        "paths": [paths[0], out_dir / "rows.json"] + paths[1:],
        "verdict": ann_verdict(rows),
        "info": info,
        "tuner": tuner,
    }


def _run_grid(grid: list, out_dir: Path, runner, progress: bool, quick: bool, base: str) -> tuple:
    """Run the cases not on disk yet, keep each row as it arrives, and write ``rows.json``.
    Returns (rows in grid order, info)."""
    jobs = {case_id(c): c for c in grid}
    store = ResultStore(
        out_dir, "evaluate", evaluation_settings(quick, base), pattern="rows/*.json"
    )

    def save(job_id, row):
        if isinstance(row, JobFailure):
            row = {"case": jobs[job_id].record(), "error": str(row), "traceback": row.traceback}
        store.put_json(
            job_id, f"rows/{job_id}.json", row, wall_s=row.get("wall_s"), failed="error" in row
        )

    fn = functools.partial(run_case, divergence_dir=str(out_dir / "diverged"))
    ran = run_jobs(store, runner, fn, jobs, save, progress, "evaluation runs", "cases")
    rows = [load_row(store, k, jobs[k]) for k in jobs]
    info = {
        "n_cases": len(grid),
        "wall_s": ran["wall_s"],
        "workers": runner.n_workers,
        "quick": quick,
        "ran": len(ran["ran"]),
        "reused": len(ran["reused"]),
        "base": str(base),
    }
    store.finish(True, info=info)
    payload = json.dumps({"info": info, "rows": rows}, indent=1, default=float)
    atomic_write(out_dir / "rows.json", lambda f: f.write(payload.encode()))
    return rows, info
