"""Closed-loop runs: simulate a :class:`StewartConfig`, compute metrics, save data and Fig. 7.

``run_experiment(config)`` returns a :class:`RunResult` (arrays + metrics); ``save_result`` writes
``<name>.npz`` (arrays and the metrics as JSON) and ``plot_fig7`` the paper's Fig. 7 panels.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator

from ..fileio import atomic_write, save_npz
from ..model.plant import assemble, loop_closure_errors
from ..simulation import guard
from ..simulation.diagram import StewartConfig, StewartDiagram, make_stewart_diagram

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


# -- data collection for the ANN tuner (paper section III.D) ------------------------------------


