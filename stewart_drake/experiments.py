"""Closed-loop runs: simulate a :class:`StewartConfig`, compute metrics, save data and Fig. 7.

``run_experiment(config)`` returns a :class:`RunResult` (arrays + metrics); ``save_result`` writes
``<name>.npz`` (arrays and the metrics as JSON) and ``plot_fig7`` the paper's Fig. 7 panels.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator

from . import guard
from .diagram import StewartConfig, StewartDiagram, make_stewart_diagram
from .fileio import atomic_write, save_npz
from .plant import assemble, loop_closure_errors

AXES = ("phi", "theta", "psi", "X", "Y", "Z")
#: Where ``stewart-drake train`` writes the tuner and ``run --tuner ann`` looks first.
DEFAULT_TUNER_OUT = Path("results") / "tuner" / "ann_tuner.npz"
#: Display units per axis: mrad for angles, mm for positions.
AXIS_UNITS = ("mrad", "mrad", "mrad", "mm", "mm", "mm")


@dataclass
class RunResult:
    """Logged arrays of one run (SI units) and its metrics.

    Attributes:
        t: (N,) s.  x: (N, 12) measured pose and rate.  x_d: (N, 18) reference pose, rate,
        acceleration.  T: (N, 6) motor torques, N m.  status: (N, 5) controller status.
        closure: (N,) max loop-closure error over the six rods, m.
        omega: (N, 2) omega_Q, omega_R in use.  rho: (M, 12) density features at the tuner's
        instants (every tuner period) or None.
        metrics: dict of the figures printed by the CLI (see :func:`compute_metrics`).
    """

    t: np.ndarray
    x: np.ndarray
    x_d: np.ndarray
    T: np.ndarray
    status: np.ndarray
    closure: np.ndarray
    omega: np.ndarray
    rho: np.ndarray | None = None
    metrics: dict = field(default_factory=dict)
    config_summary: dict = field(default_factory=dict)


def _advance(simulator: Simulator, t_end: float, progress: bool, desc: str):
    if not progress:
        simulator.AdvanceTo(t_end)
        return
    from tqdm import tqdm

    chunk = max(t_end / 200, 1e-3)
    with tqdm(total=round(t_end, 6), desc=desc, unit="sim s", bar_format=(
            "{l_bar}{bar}| {n:.2f}/{total:.2f} sim s [{elapsed}<{remaining}]")) as bar:
        t = simulator.get_context().get_time()
        while t < t_end - 1e-12:
            t_next = min(t + chunk, t_end)
            simulator.AdvanceTo(t_next)
            bar.update(t_next - t)
            t = t_next


def build_simulator(config: StewartConfig, meshcat=None):
    """(StewartDiagram, Simulator) with the loops assembled at x_d(0) moving at x_dot_d(0), guarded.

    The reference is checked first (:func:`guard.check_reference`); ``sd.guard``, a
    :class:`guard.DivergenceGuard`, is the Simulator's monitor (advance with :func:`guard.advance`
    to get the logs saved when it trips).
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError: the reference leaves the
            workspace, a joint range or nears a singularity (first time, leg or measure),
            checked before anything is simulated.
    """
    guard.check_reference(config)
    sd = make_stewart_diagram(config, meshcat=meshcat)
    simulator = Simulator(sd.diagram)
    context = simulator.get_mutable_context()
    sd.seed_noise(context)
    plant_context = sd.plant.GetMyMutableContextFromRoot(context)
    # Start on the reference, moving with it: a platform at rest under a reference that already
    # moves (eqs. 37-38 start at phi_dot = 2 pi/6 rad/s) makes a torque spike that is not
    # tracking (1.7 N m against 0.41 N m afterwards).
    x0, x_dot0, _ = config.resolved_trajectory().evaluate(0.0)
    assemble(sd.plant, plant_context, sd.handles, x0, x_dot0)
    sd.guard = guard.DivergenceGuard(sd).attach(simulator)
    simulator.Initialize()
    return sd, simulator


def run_experiment(config: StewartConfig | None = None, progress: bool = False,
                   meshcat=None) -> RunResult:
    """Simulate one closed-loop run and collect its logs and metrics.

    Args:
        config: the run (default: the paper's experiment, 10 s).
        progress: show a tqdm progress bar.
        meshcat: optional Meshcat to visualize (and record) the run.
    Returns:
        :class:`RunResult`.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError before simulating (see
        :func:`build_simulator`); SimulationDivergedError when the guard stops the run (the
        logs up to then are saved, the path is in the error).
    """
    config = config or StewartConfig()
    sd, simulator = build_simulator(config, meshcat)
    wall0 = time.perf_counter()
    guard.advance(sd, simulator,
                  lambda: _advance(simulator, config.duration_s, progress, desc="simulating"))
    wall = time.perf_counter() - wall0
    return collect_result(sd, simulator.get_context(), wall)


def collect_result(sd: StewartDiagram, root_context, wall_s: float) -> RunResult:
    """Pull the loggers of a simulated Diagram into a :class:`RunResult` with metrics."""
    logs = {name: logger.FindLog(root_context) for name, logger in sd.loggers.items()}
    t = logs["state"].sample_times()
    state = logs["state"].data().T
    closure = loop_closures_from_states(sd, state)
    status = logs["status"].data().T
    # A logged sample at t_n is the state the plant computed for physical time t_n, so the
    # tracking error compares the true pose (from the state, free of sensor noise) with the
    # analytic reference at t_n (the controller's x_d leads by half a plant step).
    x_d = np.concatenate(sd.config.resolved_trajectory().evaluate(t), axis=1)
    result = RunResult(t=t, x=sd.sensor.poses_from_states(state), x_d=x_d,
                       T=logs["T"].data().T, status=status, closure=closure,
                       omega=status[:, :2], rho=logs["rho"].data().T if "rho" in logs else None)
    config = sd.config
    result.config_summary = {
        "trajectory": getattr(config.resolved_trajectory(), "name", "custom"),
        "duration_s": config.duration_s, "plant_time_step_s": config.plant_time_step_s,
        "control_period_s": config.control_period_s, "schedule_period_s": config.schedule_period_s,
        "omega_Q": config.omega_Q, "omega_R": config.omega_R, "tuner": config.tuner,
        "feedforward": config.feedforward, "controller": config.controller,
        "payload_scale": config.payload_scale, "torque_limit_Nm": config.torque_limit_Nm,
        "sensor_noise": config.sensor_noise_std is not None}
    result.metrics = compute_metrics(result, wall_s)
    return result


def loop_closures_from_states(sd: StewartDiagram, states: np.ndarray) -> np.ndarray:
    """(N,) max loop-closure error in m at each logged plant state (N, nq + nv)."""
    plant = sd.plant
    context = plant.CreateDefaultContext()
    nq = plant.num_positions()
    out = np.empty(len(states))
    for k, s in enumerate(states):
        plant.SetPositions(context, s[:nq])
        out[k] = loop_closure_errors(plant, context, sd.handles).max()
    return out


def compute_metrics(result: RunResult, wall_s: float | None = None,
                    window_start_s: float | None = None) -> dict:
    """Figures of a run.

    Returns:
        dict: ``rms_error`` and ``peak_error`` per axis (rad and m) over t >= window_start_s
        (default: the second half of the run, i.e. [5, 10] s for the paper's 10 s), ``peak_torque``
        (6,) N m, ``sum_T2_dt`` N^2 m^2 s, ``max_closure_m``, ``gain_solves``, ``gain_failures``,
        ``realtime_factor`` (if wall_s).
    """
    t = result.t
    start = t[-1] / 2 if window_start_s is None else window_start_s
    m = t >= start - 1e-9
    err = result.x[:, :6] - result.x_d[:, :6]
    dt = np.diff(t, prepend=t[0])
    metrics = {
        "window_s": [float(start), float(t[-1])],
        "rms_error": np.sqrt(np.mean(err[m] ** 2, axis=0)).tolist(),
        "peak_error": np.abs(err[m]).max(axis=0).tolist(),
        "peak_torque": np.abs(result.T).max(axis=0).tolist(),
        "sum_T2_dt": float(np.sum(result.T ** 2 * dt[:, None])),
        "max_closure_m": float(result.closure.max()),
        "gain_solves": int(result.status[-1, 2]),
        "gain_failures": int(result.status[-1, 3]),
        "finite": bool(np.all(np.isfinite(result.x)) and np.all(np.isfinite(result.T))),
    }
    if wall_s is not None:
        metrics["wall_s"] = float(wall_s)
        metrics["realtime_factor"] = float(t[-1] / wall_s) if wall_s > 0 else float("inf")
    return metrics


def format_metrics(metrics: dict) -> str:
    """Human-readable summary (mrad / mm / N m)."""
    w0, w1 = metrics["window_s"]
    lines = [f"RMS tracking error over t in [{w0:g}, {w1:g}] s:"]
    for axis, unit, v, p in zip(AXES, AXIS_UNITS, metrics["rms_error"], metrics["peak_error"]):
        lines.append(f"  {axis:>5}: {1e3 * v:10.3g} {unit} RMS  (peak {1e3 * p:.3g} {unit})")
    lines.append("peak |T| per motor [N m]: "
                 + " ".join(f"{v:.3f}" for v in metrics["peak_torque"]))
    lines.append(f"sum T^2 dt: {metrics['sum_T2_dt']:.4g} N^2 m^2 s")
    lines.append(f"max loop-closure error: {metrics['max_closure_m']:.3g} m")
    lines.append(f"gain re-schedules: {metrics['gain_solves']} "
                 f"({metrics['gain_failures']} failed, last good gain kept)")
    if "realtime_factor" in metrics:
        lines.append(f"real-time factor: {metrics['realtime_factor']:.2f} "
                     f"({metrics['window_s'][1]:.1f} s sim / {metrics['wall_s']:.2f} s wall)")
    return "\n".join(lines)


def save_result(result: RunResult, path: str | Path) -> Path:
    """Write the run to ``path`` (.npz: t, x, x_d, T, status, closure, omega, rho, metrics JSON)."""
    path = Path(path)
    arrays = dict(t=result.t, x=result.x, x_d=result.x_d, T=result.T, status=result.status,
                  closure=result.closure, omega=result.omega,
                  metrics=np.array(json.dumps(result.metrics)),
                  config=np.array(json.dumps(result.config_summary)))
    if result.rho is not None:
        arrays["rho"] = result.rho
    return save_npz(path, arrays)


def load_result(path: str | Path) -> RunResult:
    """Read a file written by :func:`save_result`."""
    with np.load(path) as data:
        return RunResult(t=data["t"], x=data["x"], x_d=data["x_d"], T=data["T"],
                         status=data["status"], closure=data["closure"], omega=data["omega"],
                         rho=data["rho"] if "rho" in data else None,
                         metrics=json.loads(str(data["metrics"])),
                         config_summary=json.loads(str(data["config"])))


def plot_fig7(result: RunResult, path: str | Path) -> Path:
    """Paper Fig. 7 as a PNG: (a) main states vs reference (+ ANN outputs), (b) motor torques."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tuned = result.rho is not None
    fig, axes = plt.subplots(4 if tuned else 3, 1, figsize=(9, 10 if tuned else 8), sharex=True)
    t = result.t
    ax = axes[0]
    ax.plot(t, result.x_d[:, 0], "k--", lw=1, label=r"$\varphi_d$")
    ax.plot(t, result.x[:, 0], "C0", lw=1.2, label=r"$\varphi$")
    ax.set_ylabel(r"$\varphi$ [rad]")
    ax2 = ax.twinx()
    ax2.plot(t, result.x_d[:, 5], "k:", lw=1, label=r"$Z_d$")
    ax2.plot(t, result.x[:, 5], "C3", lw=1.2, label="$Z$")
    ax2.set_ylabel("$Z$ [m]")
    lines = ax.get_lines() + ax2.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], loc="upper right", ncol=4, fontsize=8)
    ax.set_title("(a) main states and reference (paper eqs. 37-38)")
    ax = axes[1]
    err = result.x[:, :6] - result.x_d[:, :6]
    for k, (axis, unit) in enumerate(zip(AXES, AXIS_UNITS)):
        ax.plot(t, 1e3 * err[:, k], lw=1, label=f"{axis} [{unit}]")
    ax.set_ylabel("tracking error\n[mrad | mm]")
    ax.set_yscale("symlog", linthresh=1e-2)
    ax.legend(loc="upper right", ncol=6, fontsize=8)
    ax.grid(alpha=0.3)
    k = 2
    if tuned:
        ax = axes[k]
        ax.plot(t, result.omega[:, 0], label=r"$\omega_Q$")
        ax.plot(t, result.omega[:, 1], label=r"$\omega_R$")
        ax.set_yscale("log")
        ax.set_ylabel("ANN output")
        ax.legend(loc="upper right", fontsize=8)
        k += 1
    ax = axes[k]
    for i in range(6):
        ax.plot(t, result.T[:, i], lw=1, label=f"$T_{i + 1}$")
    ax.set_ylabel("motor torque [N m]")
    ax.set_xlabel("t [s]")
    ax.legend(loc="upper right", ncol=6, fontsize=8)
    ax.set_title("(b) motor torques")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, dpi=110, format="png"))
    plt.close(fig)
    return path


def run_cli(args) -> int:
    """``stewart-drake run``: simulate, print the figures, write .npz and .png into args.out."""
    weights = args.tuner_weights
    if args.tuner == "ann" and weights is None and DEFAULT_TUNER_OUT.exists():
        weights = str(DEFAULT_TUNER_OUT)      # what `stewart-drake train` just wrote
    config = StewartConfig(trajectory=args.trajectory, duration_s=args.duration,
                           omega_Q=args.omega_q, omega_R=args.omega_r,
                           controller=getattr(args, "controller", "lqi"),
                           tuner=None if args.tuner == "none" else args.tuner,
                           tuner_weights=weights,
                           guard=guard.GuardConfig(divergence_dir=Path(args.out) / "diverged"))
    if config.tuner:
        from .tuner import DEFAULT_TUNER_PATH

        print(f"ANN tuner weights: {weights or DEFAULT_TUNER_PATH}")
    if getattr(args, "html", None):          # the same run, replayed into a standalone HTML
        from .visualize import record_html

        result, html = record_html(config, args.html, progress=not args.no_progress)
        print(f"wrote {html} (Meshcat replay, opens in any browser)")
    else:
        result = run_experiment(config, progress=not args.no_progress)
    out = Path(args.out)
    stem = (f"run_{config.resolved_trajectory().name}" + ("_ann" if config.tuner else "")
            + ("_pd" if config.controller == "pd" else ""))
    npz = save_result(result, out / f"{stem}.npz")
    png = plot_fig7(result, out / f"{stem}.png")
    print(format_metrics(result.metrics))
    print(f"wrote {npz} and {png}")
    return 0


# -- data collection for the ANN tuner (paper section III.D) ------------------------------------

PAPER_WEIGHTS = (0.1, 1.0, 10.0)


class SerialRunner:
    """Runs jobs one after the other in this process (``map`` like the builtin)."""

    n_workers = 1

    def map(self, fn, jobs):
        return map(fn, jobs)


class ProcessRunner:
    """Runs jobs over local processes; any object with the same ``map`` (a Ray or Dask
    executor's) can take its place, since jobs and results are plain picklable values."""

    def __init__(self, n_workers: int = 0):
        self.n_workers = n_workers or os.cpu_count() or 1

    def map(self, fn, jobs):
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=self.n_workers) as pool:
            yield from pool.map(fn, jobs)


def runner_for_jobs(jobs: int):
    """The runner for a ``--jobs`` value: 1 runs here (:class:`SerialRunner`), 0 one process per
    core, N that many processes (:class:`ProcessRunner`)."""
    return SerialRunner() if jobs == 1 else ProcessRunner(jobs)


def run_record(result: RunResult, scales, sample_period_s: float, window: int) -> dict:
    """A run as a training record: features and normalized cost parts at ``sample_period_s``.

    Returns:
        dict with omega_Q, omega_R, t (N,), rho (N, 12) (density features over ``window``
        samples of the 1 kHz log, eqs. 35-36), cost_e (N,) = sum (e_x/s_e)^2 + (e_v/s_v)^2 and
        cost_u (N,) = sum (T/s_T)^2 (eq. 26 on normalized units, unit weights), metrics.
    """
    from .features import density_features_series

    e = result.x[:, :6] - result.x_d[:, :6]
    e_v = result.x[:, 6:12] - result.x_d[:, 6:12]
    rho = density_features_series(e, result.T, window=window)
    cost_e = np.sum((e / np.asarray(scales.pose)) ** 2 + (e_v / np.asarray(scales.rate)) ** 2, 1)
    cost_u = np.sum((result.T / scales.torque) ** 2, axis=1)
    step = max(1, int(round(sample_period_s / np.median(np.diff(result.t)))))
    keep = slice(0, None, step)
    return {"omega_Q": float(result.config_summary["omega_Q"]),
            "omega_R": float(result.config_summary["omega_R"]),
            "t": result.t[keep], "rho": rho[keep], "cost_e": cost_e[keep],
            "cost_u": cost_u[keep], "metrics": result.metrics}


def _collect_job(job: dict) -> dict:
    config = job["config"]
    t0 = time.perf_counter()
    result = run_experiment(config)
    record = run_record(result, config.scales, job["sample_period_s"], config.feature_window)
    record["wall_s"] = time.perf_counter() - t0
    return record


def collect(out_dir: str | Path = "results/collect", seed: int = 0, duration_s: float = 10.0,
            sample_period_s: float = 5e-3, runner=None, progress: bool = True) -> dict:
    """The paper's 9 closed-loop experiments, (omega_Q, omega_R) in {0.1, 1, 10}^2, on the plant.

    All runs track the same :func:`~.trajectories.data_collection_trajectory` (seeded), so the
    best-cost labels can compare them window by window. 10 s at 5 ms gives 9 x 2000 = 18000
    samples (the paper used 14400).

    Args:
        out_dir: folder for ``run_<i>.npz`` records and ``manifest.json`` (config + metrics).
        runner: :class:`ProcessRunner` (default, one process per core) or anything with ``map``.
    Returns:
        the manifest dict (also written), with ``speedup`` = sum of job times / wall time.
    """
    from tqdm import tqdm

    from .trajectories import data_collection_trajectory

    out = Path(out_dir)
    runner = runner or ProcessRunner()
    trajectory = data_collection_trajectory(seed, duration_s=duration_s)
    jobs = [{"config": StewartConfig(trajectory=trajectory, duration_s=duration_s,
                                     omega_Q=q, omega_R=r),
             "sample_period_s": sample_period_s}
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
    from .errors import InvalidConfigError

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


def collect_cli(args) -> int:
    runner = runner_for_jobs(args.jobs)
    manifest = collect(args.out, seed=args.seed, duration_s=args.duration, runner=runner,
                       progress=not args.no_progress)
    print(f"{len(manifest['runs'])} runs, {manifest['n_samples']} samples in {args.out}")
    for run in manifest["runs"]:
        rms = run["rms_error"]
        print(f"  omega_Q={run['omega_Q']:<4g} omega_R={run['omega_R']:<4g} "
              f"RMS phi {1e3 * rms[0]:.3f} mrad, Z {1e3 * rms[5]:.3f} mm, "
              f"sum T^2 dt {run['sum_T2_dt']:.3g}")
    print(f"speedup over one process: {manifest['speedup']:.2f} "
          f"({manifest['sum_job_s']:.1f} s of runs in {manifest['wall_s']:.1f} s wall, "
          f"{manifest['workers']} workers)")
    return 0



def train_cli(args) -> int:
    from .training import build_dataset, train
    from .tuner import save_tuner

    records = load_records(args.data)
    reports = {}
    for mode in ("paper", "best_cost"):
        dataset = build_dataset(records, mode=mode)
        model, report = train(dataset, seed=args.seed,
                              metadata={"label_mode": mode, "data": str(args.data),
                                        "feature_window": StewartConfig().feature_window,
                                        "feature_period_s": StewartConfig().control_period_s})
        reports[mode] = (model, report)
        r2 = report["val_r2"]
        r2_text = ", ".join(f"{k} {v:.3f}" for k, v in r2.items()) if isinstance(r2, dict) else r2
        print(f"{mode:>9} labels: {dataset.info['n_samples']} samples, val loss "
              f"{report['val_loss']:.4f} (from {report['val_loss_initial']:.4f}), "
              f"validation R^2: {r2_text}")
    model, _ = reports[args.mode]
    out = Path(args.out)
    save_tuner(model, out)
    print(f"wrote {out} (label mode {args.mode})")
    return 0
