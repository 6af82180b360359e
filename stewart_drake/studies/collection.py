"""Data collection for the ANN tuner (paper section III.D): the nine closed-loop runs.

:func:`collect` runs the paper's 9 experiments, (omega_Q, omega_R) in {0.1, 1, 10}^2, over a
runner and writes one record per run (features and normalized cost parts) plus a manifest;
:func:`load_records` reads them back for :mod:`.training`.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from ..control.features import density_features_series
from ..errors import InvalidConfigError
from ..fileio import atomic_write, save_npz
from ..simulation.scenario import AnnTunerDriver, DataCollectionReference, LqiDriver, Scenario
from ..simulation.trajectories import data_collection_trajectory
from .experiments import RunResult, run_experiment
from .runners import ProcessRunner

PAPER_WEIGHTS = (0.1, 1.0, 10.0)


def run_record(result: RunResult, scales, sample_period_s: float, window: int) -> dict:
    """A run as a training record: features and normalized cost parts at ``sample_period_s``.

    The features are those the tuner would see in the loop: of the error the controller acted
    on (``result.e_bar``: its estimate, on the hardware; the true error when not logged) and of
    the applied torques, sample for sample as :class:`~stewart_drake.control.features.DensityFeatures`
    takes them. The cost parts use the true error.

    Returns:
        dict with omega_Q, omega_R, t (N,), rho (N, 12) (density features over ``window``
        samples of the 1 kHz log, eqs. 35-36), cost_e (N,) = sum (e_x/s_e)^2 + (e_v/s_v)^2 and
        cost_u (N,) = sum (T/s_T)^2 (eq. 26 on normalized units, unit weights), metrics.
    """
    e = result.x[:, :6] - result.x_d[:, :6]
    e_v = result.x[:, 6:12] - result.x_d[:, 6:12]
    seen = result.e_bar if result.e_bar is not None else e
    rho = density_features_series(seen, result.T, window=window)
    cost_e = np.sum((e / np.asarray(scales.pose)) ** 2 + (e_v / np.asarray(scales.rate)) ** 2, 1)
    cost_u = np.sum((result.T / scales.torque) ** 2, axis=1)
    step = max(1, int(round(sample_period_s / np.median(np.diff(result.t)))))
    keep = slice(0, None, step)
    return {"omega_Q": float(result.config_summary["omega_Q"]),
            "omega_R": float(result.config_summary["omega_R"]),
            "t": result.t[keep], "rho": rho[keep], "cost_e": cost_e[keep],
            "cost_u": cost_u[keep], "metrics": result.metrics}


def job_config(base: Scenario | None, seed: int, duration_s: float, omega_Q: float,
               omega_R: float) -> Scenario:
    """The scenario of one collection run: ``base`` (default: the ideal paper scenario) tracking
    the seeded excitation for ``duration_s`` with the LQI at fixed (omega_Q, omega_R)."""
    scenario = copy.deepcopy(base) if base is not None else Scenario()
    scenario.reference = DataCollectionReference(seed=seed)
    scenario.duration_s = duration_s
    scenario.tuner = None
    driver = scenario.controller if isinstance(scenario.controller, LqiDriver) else LqiDriver()
    scenario.controller = dataclasses.replace(driver, omega_Q=omega_Q, omega_R=omega_R)
    return scenario.validate()


def _collect_job(job: dict) -> dict:
    config = job["config"]
    t0 = time.perf_counter()
    result = run_experiment(config)
    record = run_record(result, config.controller.scales.build(), job["sample_period_s"],
                        job["feature_window"])
    record["wall_s"] = time.perf_counter() - t0
    return record


def collect(out_dir: str | Path = "results/collect", seed: int = 0, duration_s: float = 10.0,
            sample_period_s: float = 5e-3, runner=None, progress: bool = True,
            base: Scenario | None = None) -> dict:
    """The paper's 9 closed-loop experiments, (omega_Q, omega_R) in {0.1, 1, 10}^2, on the plant.

    All runs track the same :func:`~.trajectories.data_collection_trajectory` (seeded), so the
    best-cost labels can compare them window by window. 10 s at 5 ms gives 9 x 2000 = 18000
    samples (the paper used 14400).

    Args:
        out_dir: folder for ``run_<i>.npz`` records and ``manifest.json`` (config + metrics).
        runner: :class:`ProcessRunner` (default, one process per core) or anything with ``map``.
        base: the scenario the nine runs share (robot, hardware, noise...); its reference,
            duration, controller weights and tuner are set here. Default: the ideal paper one.
    Returns:
        the manifest dict (also written), with ``speedup`` = sum of job times / wall time.
    """
    from tqdm import tqdm

    out = Path(out_dir)
    runner = runner or ProcessRunner()
    trajectory = data_collection_trajectory(seed, duration_s=duration_s)
    window = AnnTunerDriver().feature_window
    jobs = [{"config": job_config(base, seed, duration_s, q, r),
             "sample_period_s": sample_period_s, "feature_window": window}
            for q in PAPER_WEIGHTS for r in PAPER_WEIGHTS]
    wall0 = time.perf_counter()
    records = []
    for record in tqdm(runner.map(_collect_job, jobs), total=len(jobs), desc="closed-loop runs",
                       unit="run", disable=not progress):
        records.append(record)
    wall = time.perf_counter() - wall0
    files = []
    for i, record in enumerate(records):
        path = out / f"run_{i}.npz"
        arrays = {k: np.asarray(v) for k, v in record.items() if k not in ("metrics",)}
        arrays["metrics"] = np.array(json.dumps(record["metrics"]))
        save_npz(path, arrays)
        files.append(path.name)
    job_time = sum(r["wall_s"] for r in records)
    manifest = {"seed": seed, "duration_s": duration_s, "sample_period_s": sample_period_s,
                "trajectory": {"amplitude": trajectory.amplitude,
                               "frequency_hz": trajectory.frequency_hz,
                               "phase": trajectory.phase},
                "runs": [{"file": f, "omega_Q": r["omega_Q"], "omega_R": r["omega_R"],
                          "rms_error": r["metrics"]["rms_error"],
                          "sum_T2_dt": r["metrics"]["sum_T2_dt"],
                          "max_closure_m": r["metrics"]["max_closure_m"]}
                         for f, r in zip(files, records)],
                "n_samples": int(sum(len(r["t"]) for r in records)),
                "workers": runner.n_workers, "wall_s": wall, "sum_job_s": job_time,
                "speedup": job_time / wall if wall > 0 else float("nan")}
    atomic_write(out / "manifest.json", lambda f: f.write(json.dumps(manifest, indent=2).encode()))
    return manifest


def load_records(data_dir: str | Path) -> list[dict]:
    """The run records written by :func:`collect` (manifest order).

    Raises:
        InvalidConfigError: no manifest in ``data_dir`` (run ``stewart-drake collect`` first).
    """
    data_dir = Path(data_dir)
    manifest = data_dir / "manifest.json"
    if not manifest.exists():
        raise InvalidConfigError(
            f"no collected runs in {data_dir}: run `stewart-drake collect --out {data_dir}` first")
    records = []
    for run in json.loads(manifest.read_text())["runs"]:
        with np.load(data_dir / run["file"]) as data:
            records.append({k: (float(data[k]) if k in ("omega_Q", "omega_R") else data[k])
                            for k in ("omega_Q", "omega_R", "t", "rho", "cost_e", "cost_u")})
    return records
