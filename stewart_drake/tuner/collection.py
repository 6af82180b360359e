"""Data collection for the ANN tuner (paper section III.D): the nine closed-loop runs.

:func:`collect` runs the paper's 9 experiments, (omega_Q, omega_R) in {0.1, 1, 10}^2, over a
runner and writes one record per run (features and normalized cost parts) as it finishes, with
a manifest (:mod:`.store`: resume, settings hash); :func:`load_records` reads a complete
collection back for :mod:`.training` and refuses an incomplete or mixed one.
"""

from __future__ import annotations

import copy
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..base.errors import (
    CorruptFileError,
    IncompleteResultsError,
    InvalidConfigError,
    ResultsMismatchError,
)
from ..base.npz import CheckedNpz
from ..control.features import density_features_series
from ..control.tuning import AnnTunerDriver
from ..execution.runners import JobFailure, ProcessRunner
from ..execution.store import FORMAT, MANIFEST, ResultStore, read_manifest, run_jobs
from ..references.data_collection import DataCollectionReference
from ..references.trajectories import SineTrajectory
from ..run.memory import check_run_memory
from ..run.plan import run_reference
from ..run.result import RunResult
from ..run.scenario import Scenario
from ..run.simulate import run_experiment

PAPER_WEIGHTS = (0.1, 1.0, 10.0)
#: What the finished manifest's ``runs`` list keeps of each run's entry.
MANIFEST_RUN_KEYS = (
    "file",
    "omega_Q",
    "omega_R",
    "rms_error",
    "sum_T2_dt",
    "max_closure_m",
    "lost",
)


def run_record(result: RunResult, scales, sample_period_s: float, window: int) -> dict:
    """A run as a training record: features and normalized cost parts at ``sample_period_s``.

    The features are those the tuner would see in the loop: of the error the controller acted
    on (``result.e_bar``: its estimate, on the hardware; the true error when not logged) and of
    the applied torques, sample for sample as
    :class:`~stewart_drake.control.features.DensityFeatures` takes them. The cost parts use the
    true error.

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
    return {
        "omega_Q": float(result.config_summary["omega_Q"]),
        "omega_R": float(result.config_summary["omega_R"]),
        "t": result.t[keep],
        "rho": rho[keep],
        "cost_e": cost_e[keep],
        "cost_u": cost_u[keep],
        "metrics": result.metrics,
    }


def job_config(
    base: Scenario | None, seed: int, duration_s: float, omega_Q: float, omega_R: float
) -> Scenario:
    """The scenario of one collection run, the only place it is built: ``base`` (default: the
    robot as built, ``paper_hardware``) tracking the seeded excitation for ``duration_s`` with
    the base's LQI at fixed (omega_Q, omega_R) (:meth:`~.scenario.Scenario.lqi`)."""
    from ..run.scenario_io import load_scenario

    scenario = copy.deepcopy(base) if base is not None else load_scenario("paper_hardware")
    scenario.reference = DataCollectionReference(seed=seed)
    scenario.duration_s = duration_s
    scenario.use_controller(scenario.lqi(omega_Q=omega_Q, omega_R=omega_R))
    return scenario.validate()


@dataclass(frozen=True)
class CollectionRun:
    """One run of the collection: its scenario (the LQI at its weights, typed, on the seeded
    excitation), and how its record is sampled (every ``sample_period_s`` s, density features
    over ``feature_window`` samples)."""

    scenario: Scenario
    sample_period_s: float
    feature_window: int

    @property
    def weights(self) -> tuple:
        """(omega_Q, omega_R) of the run's LQI."""
        return self.scenario.controller.omega()


def _collect_job(run: CollectionRun) -> dict:
    t0 = time.perf_counter()
    result = run_experiment(run.scenario)
    scales = run.scenario.controller.scales.build()  # type: ignore[union-attr]  # an LQI
    record = run_record(result, scales, run.sample_period_s, run.feature_window)
    record["wall_s"] = time.perf_counter() - t0
    return record


def collection_jobs(
    seed: int = 0,
    duration_s: float = 10.0,
    sample_period_s: float = 5e-3,
    base: Scenario | None = None,
) -> tuple[dict, dict]:
    """The settings (what decides the data, hashed by the store) and the nine runs.

    Returns:
        (settings dict, {"q<omega_Q>_r<omega_R>": :class:`CollectionRun`}) in the paper's grid
        order.
    """
    from ..run.scenario import dump_scenario

    configs = {
        f"q{q:g}_r{r:g}": job_config(base, seed, duration_s, q, r)
        for q in PAPER_WEIGHTS
        for r in PAPER_WEIGHTS
    }
    trajectory = run_reference(next(iter(configs.values())))
    assert isinstance(trajectory, SineTrajectory)  # the collection's reference is a sine
    window = AnnTunerDriver().feature_window
    settings = {
        "seed": seed,
        "duration_s": duration_s,
        "sample_period_s": sample_period_s,
        "feature_window": window,
        "trajectory": {
            "amplitude": trajectory.amplitude,
            "frequency_hz": trajectory.frequency_hz,
            "phase": trajectory.phase,
        },
        "scenario": dump_scenario(next(iter(configs.values()))),
    }
    jobs = {k: CollectionRun(c, sample_period_s, window) for k, c in configs.items()}
    return settings, jobs


def collect(
    out_dir: str | Path = "results/collect",
    seed: int = 0,
    duration_s: float = 10.0,
    sample_period_s: float = 5e-3,
    runner=None,
    progress: bool = True,
    base: Scenario | None = None,
) -> dict:
    """The paper's 9 closed-loop experiments, (omega_Q, omega_R) in {0.1, 1, 10}^2, on the plant.

    All runs track the same :func:`~.data_collection.data_collection_trajectory` (seeded), so the
    best-cost labels can compare them window by window. 10 s at 5 ms gives 9 x 2000 = 18000
    samples (the paper used 14400). Each run is written to ``out_dir`` the moment it finishes
    (:class:`~.store.ResultStore`); run again with the same settings, only the missing runs run.

    Args:
        out_dir: folder of ``run_<job>.npz`` records and ``manifest.json``; the logs of a run
            that loses the platform go to ``out_dir/diverged/``.
        runner: :class:`~.runners.ProcessRunner` (default, one process per core) or any runner
            of :mod:`.runners`.
        base: the scenario the nine runs share (robot, hardware, noise...); its reference,
            duration, controller weights and tuner are set here. Default: ``paper_hardware``.
    Returns:
        the manifest dict (also written): per run its file, weights and figures in ``runs``,
        ``n_samples``, and for this call ``workers``, ``wall_s``, ``sum_job_s`` and
        ``speedup`` = sum of job times / wall time.
    Raises:
        InvalidConfigError: the runs at once need more memory than the machine has.
        ResultsMismatchError: ``out_dir`` holds runs of other settings, or not of collect.
        IncompleteResultsError: runs failed or were lost (named); the others are on disk.
        Interrupted: Ctrl-C, SIGTERM or SIGHUP; the finished runs are on disk.
    """
    out = Path(out_dir)
    runner = runner or ProcessRunner()
    n_runs = len(PAPER_WEIGHTS) ** 2  # before the reference is planned
    check_run_memory(
        job_config(base, seed, duration_s, 1.0, 1.0),
        max(1, min(runner.n_workers, n_runs)),
        "shorten --duration, or run fewer at once with --jobs",
    )
    settings, jobs = collection_jobs(seed, duration_s, sample_period_s, base)
    for job in jobs.values():  # not in the settings: a divergence is kept under out_dir
        job.scenario.guard.divergence_dir = str(out / "diverged")
    store = ResultStore(out, "collect", settings, pattern="run_*.npz")

    def save(job_id, record):
        _save_run(store, job_id, jobs[job_id], record)

    ran = run_jobs(store, runner, _collect_job, jobs, save, progress, "closed-loop runs", "runs")
    entries = [store.manifest["jobs"][k] for k in jobs]
    job_time = sum(store.manifest["jobs"][k]["wall_s"] for k in ran["ran"])
    wall = ran["wall_s"]
    return store.finish(
        True,
        runs=[{k: e.get(k) for k in MANIFEST_RUN_KEYS} for e in entries],
        n_samples=int(sum(e["n_samples"] for e in entries)),
        workers=runner.n_workers,
        ran=len(ran["ran"]),
        reused=len(ran["reused"]),
        wall_s=wall,
        sum_job_s=job_time,
        speedup=job_time / wall if ran["ran"] and wall > 0 else float("nan"),
    )


def _save_run(store: ResultStore, job_id: str, run: CollectionRun, record) -> None:
    """Keep one run's record (``run_<job>.npz``, with the settings' hash) as it arrives; a run
    that lost the platform is kept as such (``run_<job>.json``), any other failure marked."""
    if isinstance(record, JobFailure):
        if record.kind == "error" and record.error_type == "SimulationDivergedError":
            # The platform was lost at these weights: an outcome of the experiment (the
            # stiff ratios on the robot as built), kept as such, not a missing run.
            q, r = run.weights
            store.put_json(
                job_id,
                f"run_{job_id}.json",
                {"lost": record.message},
                omega_Q=q,
                omega_R=r,
                lost=record.message.splitlines()[0],
                rms_error=None,
                sum_T2_dt=None,
                max_closure_m=None,
                n_samples=0,
                wall_s=0.0,
            )
            return
        store.mark(record)
        return
    arrays: dict[str, Any] = {k: np.asarray(v) for k, v in record.items() if k != "metrics"}
    arrays["metrics"] = np.array(json.dumps(record["metrics"]))
    arrays["settings_hash"] = np.array(store.hash)
    m = record["metrics"]
    store.put(
        job_id,
        f"run_{job_id}.npz",
        lambda f: np.savez_compressed(f, **arrays),
        omega_Q=record["omega_Q"],
        omega_R=record["omega_R"],
        rms_error=m["rms_error"],
        sum_T2_dt=m["sum_T2_dt"],
        max_closure_m=m["max_closure_m"],
        n_samples=len(record["t"]),
        wall_s=record["wall_s"],
    )


def load_records(data_dir: str | Path) -> list[dict]:
    """The run records written by :func:`collect` (grid order), all of one collection; runs
    that lost the platform (``lost`` in the manifest) have no data and are left out.

    Returns:
        one dict per kept run: omega_Q, omega_R (floats), t (N,) s, rho (N, 12), cost_e (N,),
        cost_u (N,) (see :func:`run_record`).
    Raises:
        InvalidConfigError: no manifest in ``data_dir`` (run ``stewart-drake collect`` first).
        ResultsMismatchError: the folder was not written by ``collect`` (or by an older version),
            or holds a run file of other settings than its manifest (a mixed folder).
        IncompleteResultsError: the collection did not finish (runs lost, failed, interrupted),
            or a run file it lists is gone.
        CorruptFileError: a manifest or run file that is truncated, not JSON or not an ``.npz``,
            or lacks an entry or has one of the wrong type or shape (names the file and entry).
    """
    data_dir = Path(data_dir)
    again = f"run the same `stewart-drake collect --out {data_dir}` again to finish it"
    manifest = _finished_manifest(data_dir, again)
    runs = manifest["runs"]
    records: list = []
    seen: dict = {}
    for run in runs:
        if run.get("lost"):
            continue
        path = data_dir / run["file"]
        if not path.is_file():
            raise IncompleteResultsError(
                f"{path} is gone (listed in {data_dir / MANIFEST}): "
                f"{again}, which runs only the missing runs"
            )
        record = _read_record(path, manifest["settings_hash"], f"delete it and {again}")
        weights = (record["omega_Q"], record["omega_R"])
        if weights != (run.get("omega_Q"), run.get("omega_R")) or weights in seen:
            raise CorruptFileError(
                path,
                "collected run",
                f"it holds the run at omega_Q = {weights[0]:g}, omega_R = "
                f"{weights[1]:g}, "
                + (
                    f"which {seen[weights]} holds too"
                    if weights in seen
                    else f"not the one its manifest entry names (omega_Q = "
                    f"{run.get('omega_Q')}, omega_R = {run.get('omega_R')})"
                ),
                f"delete it and {again}",
            )
        seen[weights] = path.name
        records.append(record)
    return records


def _finished_manifest(data_dir: Path, again: str) -> dict:
    """The manifest of a finished collection in ``data_dir``, its ``runs`` list checked (the
    errors of :func:`load_records`; ``again`` says how to finish an unfinished one)."""
    manifest = read_manifest(data_dir)
    if manifest is None:
        raise InvalidConfigError(
            f"no collected runs in {data_dir}: run `stewart-drake collect --out {data_dir}` first"
        )
    if manifest.get("study") != "collect" or manifest.get("format") != FORMAT:
        raise ResultsMismatchError(
            f"{data_dir} was not written by this version of `stewart-drake collect`: collect "
            f"again into an empty folder"
        )
    if not manifest["complete"]:
        done = sum(v["status"] == "done" for v in manifest["jobs"].values())
        raise IncompleteResultsError(
            f"{data_dir} holds {done} of {len(PAPER_WEIGHTS) ** 2} runs (the collection did not "
            f"finish): {again}"
        )
    runs = manifest.get("runs")
    if not (
        isinstance(runs, list)
        and all(
            isinstance(r, dict) and (r.get("lost") or isinstance(r.get("file"), str)) for r in runs
        )
    ):
        raise CorruptFileError(
            data_dir / MANIFEST,
            "collect manifest",
            "it is complete but its 'runs' list is missing or a run names no file",
            "collect again into an empty folder",
        )
    return manifest


def _read_record(path: Path, settings_hash: str, remedy: str) -> dict:
    """One run file of :func:`collect`, checked entry by entry (see :func:`load_records`)."""
    data = CheckedNpz(path, "collected run", remedy)
    if "settings_hash" not in data or data.text("settings_hash") != settings_hash:
        raise ResultsMismatchError(
            f"{path} is not of the settings of {path.parent / MANIFEST}: the folder mixes runs "
            f"of two collections; collect again into an empty folder"
        )
    record: dict[str, Any] = {name: data.number(name) for name in ("omega_Q", "omega_R")}
    record.update({name: data.array(name) for name in ("t", "rho", "cost_e", "cost_u")})
    n = record["t"].shape[0] if record["t"].ndim == 1 else -1
    for name, shape in (("t", (n,)), ("rho", (n, 12)), ("cost_e", (n,)), ("cost_u", (n,))):
        if n < 1 or record[name].shape != shape:
            raise data.corrupt(
                f"the entry {name!r} has shape {record[name].shape}, expected "
                f"{shape} with N >= 1 samples"
            )
    return record
