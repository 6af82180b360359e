"""Closed-loop runs: simulate a :class:`~stewart_drake.simulation.scenario.Scenario`, compute
metrics, save data and Fig. 7.

``run_experiment(scenario)`` returns a :class:`RunResult` (arrays + metrics); ``save_result``
writes ``<name>.npz`` (arrays, the metrics as JSON and the scenario as YAML) and ``plot_fig7`` the
paper's Fig. 7 panels.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

from ..fileio import CheckedNpz, atomic_write, save_npz
from ..model.plant import loop_closure_errors
from ..simulation import guard
from ..simulation.diagram import StewartDiagram, make_stewart_diagram
from ..simulation.scenario import CsvReference, LqiDriver, Scenario, dump_scenario
from ..simulation.trajectories import as_trajectory, csv_reference_bytes

AXES = ("phi", "theta", "psi", "X", "Y", "Z")
#: Where ``stewart-drake train`` writes the tuner and ``run --tuner ann`` looks first.
DEFAULT_TUNER_OUT = Path("results") / "tuner" / "ann_tuner.npz"
#: Display units per axis: mrad for angles, mm for positions.
AXIS_UNITS = ("mrad", "mrad", "mrad", "mm", "mm", "mm")


@dataclass
class RunResult:
    """Logged arrays of one run (SI units) and its metrics.

    Attributes:
        t: (N,) s.  x: (N, 12) true pose and rate (from the plant state, free of sensor noise).
        x_d: (N, 18) reference pose, rate, acceleration.  T: (N, 6) applied motor torques, N m.
        closure: (N,) max loop-closure error over the six rods, m.
        status: (N, k) the controller's ``status`` output, named by ``status_names`` (empty
            (N, 0) for a controller without one).
        omega: (N, 2) omega_Q, omega_R in use (from status), or None when the controller
            reports none.  integral: (N, 6) the controller's integral states, or None.
        rho: (M, 12) density features at the tuner's instants (every tuner period) or None.
        e_bar: (N, 6) the pose error the controller acted on (its estimate of x minus x_d: on
            the hardware, from the encoders), or None.
        T_ff: (N, 6) the feed-forward torques of the reference at each logged time, N m (T -
            T_ff is the feedback's share), or None.
        metrics: dict of the figures printed by the CLI (see :func:`compute_metrics`).
        config_summary: the run's settings (name, controller, weights, ...) and ``scenario``,
            the whole scenario as YAML.
    """

    t: np.ndarray
    x: np.ndarray
    x_d: np.ndarray
    T: np.ndarray
    closure: np.ndarray
    status: np.ndarray
    status_names: tuple = ()
    omega: np.ndarray | None = None
    integral: np.ndarray | None = None
    rho: np.ndarray | None = None
    e_bar: np.ndarray | None = None
    T_ff: np.ndarray | None = None
    metrics: dict = field(default_factory=dict)
    config_summary: dict = field(default_factory=dict)


def advance(simulator: Simulator, t_end: float, progress: bool, desc: str = "simulating"):
    """``simulator.AdvanceTo(t_end)``, in 200 chunks behind a tqdm bar when ``progress``."""
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


#: Memory a run holds, measured with ``stewart-drake run`` (paper_hardware, 1 s against 5 s and
#: 10 s against 110 s): about 3.3 kB per logged sample at the end of the run (the Simulator's
#: logs of 86 floats, which grow by doubling, the RunResult, the .npz and the plot), and
#: 3 kB per control-period sample while the reference is checked (``guard.check_reference``,
#: before the simulation). Upper bounds with some slack:
LOG_BYTES_PER_SAMPLE = 4.0e3
REFERENCE_CHECK_BYTES_PER_SAMPLE = 3.2e3


def run_memory_bytes(scenario: Scenario) -> float:
    """Estimated peak memory of one run of ``scenario``, bytes (inf-safe for huge durations):
    the larger of the reference check and the logs (see :data:`LOG_BYTES_PER_SAMPLE`), plus a
    CSV reference's spline (:func:`~stewart_drake.simulation.trajectories.csv_reference_bytes`,
    which counts the file's lines)."""
    d = float(scenario.duration_s)
    reference = (csv_reference_bytes(scenario.reference.path)
                 if isinstance(scenario.reference, CsvReference) else 0.0)
    return reference + max((d / scenario.control_period_s + 1) * REFERENCE_CHECK_BYTES_PER_SAMPLE,
                           (d / scenario.log_period_s + 1) * LOG_BYTES_PER_SAMPLE)


def check_run_memory(scenario: Scenario, runs_at_once: int = 1, change: str | None = None):
    """Refuse, before anything is allocated, runs that need more memory than the machine has.

    Args:
        scenario: the run.  runs_at_once: how many such runs are in memory together (workers).
        change: what the message tells to change (default: duration_s or log_period_s).
    Raises:
        InvalidConfigError: one line with the estimate and the memory available.
    """
    from ..checks import check_memory

    what = (f"{'a run of' if runs_at_once == 1 else f'{runs_at_once} runs at once, each of'} "
            f"{scenario.duration_s:g} s logged every {scenario.log_period_s:g} s"
            + (f" on the reference {scenario.reference.path}"
               if isinstance(scenario.reference, CsvReference) else ""))
    check_memory(what, runs_at_once * run_memory_bytes(scenario), change or (
        "shorten duration_s (--duration) or lengthen log_period_s"
        + (", and sample the reference CSV more coarsely"
           if isinstance(scenario.reference, CsvReference) else "")))


def build_simulator(scenario: Scenario | None = None, meshcat=None, *, reference=None,
                    controller=None):
    """(StewartDiagram, Simulator) with the loops assembled at x_d(0) moving at x_dot_d(0), guarded.

    The reference is checked first (:func:`guard.check_reference`); ``sd.guard``, the
    Diagram's :class:`guard.DivergenceGuard`, checks the run as it goes (advance with
    :func:`guard.advance` to get the logs saved when it trips). ``scenario.simulator`` is
    applied.

    Args:
        scenario, meshcat, reference, controller: as
            :func:`~stewart_drake.simulation.diagram.make_stewart_diagram`.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError: the reference leaves the
            workspace, a joint range or nears a singularity (first time, leg or measure),
            checked before anything is simulated. InvalidConfigError: a bad scenario field, or
            a run that needs more memory than the machine has (:func:`check_run_memory`).
    """
    scenario = (scenario or Scenario()).validate()
    check_run_memory(scenario)
    trajectory = as_trajectory(reference if reference is not None else scenario.make_reference())
    guard.check_reference(scenario, trajectory)
    sd = make_stewart_diagram(scenario, meshcat=meshcat, reference=trajectory,
                              controller=controller)
    simulator = Simulator(sd.diagram)
    ApplySimulatorConfig(scenario.simulator, simulator)
    context = simulator.get_mutable_context()
    sd.initialize(context)
    # Start on the reference, moving with it: a platform at rest under a reference that already
    # moves (eqs. 37-38 start at phi_dot = 2 pi/6 rad/s) makes a torque spike that is not
    # tracking (1.7 N m against 0.41 N m afterwards).
    x0, x_dot0, _ = sd.trajectory.evaluate(0.0)
    sd.station.assemble(context, x0, x_dot0)
    simulator.Initialize()
    return sd, simulator


def run_experiment(scenario: Scenario | None = None, progress: bool = False,
                   meshcat=None, *, reference=None, controller=None) -> RunResult:
    """Simulate one closed-loop run and collect its logs and metrics.

    Args:
        scenario: the run (default: the paper's experiment on the ideal robot, 10 s).
        progress: show a tqdm progress bar.
        meshcat: optional Meshcat to visualize the run.
        reference: optional reference object overriding ``scenario.reference`` (an object with
            ``evaluate(t)``, a Drake ``Trajectory``, a CSV path or a name).
        controller: optional controller factory or registered name (the controller contract,
            :mod:`~stewart_drake.control.contract`) overriding ``scenario.controller``.
    Returns:
        :class:`RunResult`.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError before simulating (see
        :func:`build_simulator`); SimulationDivergedError when the guard stops the run (the
        logs up to then are saved, the path is in the error).
    """
    sd, simulator = build_simulator(scenario, meshcat, reference=reference, controller=controller)
    wall0 = time.perf_counter()
    guard.advance(sd, simulator,
                  lambda: advance(simulator, sd.scenario.duration_s, progress))
    wall = time.perf_counter() - wall0
    return collect_result(sd, simulator.get_context(), wall)


def config_summary(sd: StewartDiagram) -> dict:
    """The settings of a run that results and records carry (plain JSON values)."""
    scenario, driver = sd.scenario, sd.scenario.controller
    summary = {"trajectory": getattr(sd.trajectory, "name", "custom"),
               "duration_s": scenario.duration_s,
               "plant_time_step_s": scenario.plant_time_step_s,
               "control_period_s": scenario.control_period_s,
               "controller": type(driver).__name__, "tuner": scenario.tuner is not None,
               "feedforward": scenario.feedforward, "payload_scale": scenario.payload_scale,
               "torque_limit_Nm": scenario.torque_limit_Nm,
               "motor_limit_Nm": scenario.torque_limit(),
               "sensor_noise": scenario.sensor_noise is not None,
               "hardware": scenario.hardware is not None,
               "scenario": dump_scenario(scenario)}
    if isinstance(driver, LqiDriver):
        summary.update(omega_Q=driver.omega_Q, omega_R=driver.omega_R,
                       schedule_period_s=driver.schedule_period_s)
    return summary


def collect_result(sd: StewartDiagram, root_context, wall_s: float) -> RunResult:
    """Pull the loggers of a simulated Diagram into a :class:`RunResult` with metrics."""
    logs = {name: logger.FindLog(root_context) for name, logger in sd.loggers.items()}
    t = logs["state"].sample_times()
    state = logs["state"].data().T
    closure = loop_closures_from_states(sd, state)
    names = tuple(getattr(sd.controller, "status_names", ())) if "status" in logs else ()
    status = logs["status"].data().T if "status" in logs else np.zeros((len(t), 0))
    omega = (status[:, [names.index("omega_Q"), names.index("omega_R")]]
             if {"omega_Q", "omega_R"} <= set(names) else None)
    # A logged sample at t_n is the state the plant computed for physical time t_n, so the
    # tracking error compares the true pose (from the state, free of sensor noise) with the
    # analytic reference at t_n (the controller's x_d leads by half a plant step).
    x_d = np.concatenate(sd.trajectory.evaluate(t), axis=1)
    result = RunResult(t=t, x=sd.sensor.poses_from_states(state), x_d=x_d,
                       T=logs["T"].data().T, closure=closure, status=status, status_names=names,
                       omega=omega,
                       integral=logs["integral"].data().T if "integral" in logs else None,
                       rho=logs["rho"].data().T if "rho" in logs else None,
                       e_bar=logs["e_bar"].data().T if "e_bar" in logs else None,
                       T_ff=feedforward_at(sd, t), config_summary=config_summary(sd))
    result.metrics = compute_metrics(result, wall_s)
    if sd.scenario.contact:
        first = sd.guard.first_contact(root_context) if sd.guard is not None else None
        result.metrics["first_contact"] = None if first is None else {
            "t": first[0], "parts": list(first[1:3]), "force_N": first[3]}
    return result


def feedforward_at(sd: StewartDiagram, t: np.ndarray) -> np.ndarray:
    """(N, 6) the feed-forward torques the reference asks for at times t (s), N m: the
    Diagram's feed-forward table, each row placed at the time it is meant to act (the sample's
    reference time plus the computation delay), linearly interpolated."""
    scenario = sd.scenario
    delay = scenario.hardware.computation_delay_periods if scenario.hardware else 0
    t_act = sd.reference.t_eval + delay * scenario.control_period_s
    table = sd.reference.T_ff_table
    return np.stack([np.interp(t, t_act, table[:, i]) for i in range(table.shape[1])], axis=1)


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
        (6,) N m, ``sum_T2_dt`` N^2 m^2 s, ``max_closure_m``, ``status`` (the controller's
        status at the end, by name), and for a controller that reports them ``gain_solves`` and
        ``gain_failures``; ``realtime_factor`` (if wall_s).
    Raises:
        InvalidConfigError: fewer than 2 samples in the window (nothing to average: simulate
            longer than one log period).
    """
    from ..errors import InvalidConfigError

    t = result.t
    start = t[-1] / 2 if window_start_s is None else window_start_s
    m = t >= start - 1e-9
    if np.count_nonzero(m) < 2:
        raise InvalidConfigError(f"a run of {t[-1]:g} s has {np.count_nonzero(m)} logged sample(s) "
                                 f"after t = {start:g} s: too short for metrics; simulate longer")
    err = result.x[:, :6] - result.x_d[:, :6]
    dt = np.diff(t, prepend=t[0])
    metrics = {
        "window_s": [float(start), float(t[-1])],
        "rms_error": np.sqrt(np.mean(err[m] ** 2, axis=0)).tolist(),
        "peak_error": np.abs(err[m]).max(axis=0).tolist(),
        "peak_torque": np.abs(result.T).max(axis=0).tolist(),
        "sum_T2_dt": float(np.sum(result.T ** 2 * dt[:, None])),
        "max_closure_m": float(result.closure.max()),
        "status": {name: float(v) for name, v in zip(result.status_names, result.status[-1])},
        "finite": bool(np.all(np.isfinite(result.x)) and np.all(np.isfinite(result.T))),
    }
    for name in ("gain_solves", "gain_failures"):
        if name in metrics["status"]:
            metrics[name] = int(metrics["status"][name])
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
    status = dict(metrics.get("status", {}))
    if "gain_solves" in status:
        lines.append(f"gain re-schedules: {int(status.pop('gain_solves'))} "
                     f"({int(status.pop('gain_failures', 0))} failed, last good gain kept)")
    counts = {k: v for k, v in status.items() if k not in ("omega_Q", "omega_R", "integral_norm")}
    if counts:
        lines.append("controller status: " + ", ".join(f"{k.replace('_', ' ')} {v:g}"
                                                       for k, v in counts.items()))
    if "first_contact" in metrics:
        c = metrics["first_contact"]
        lines.append("contact between parts: none" if c is None else
                     f"first contact between parts: {c['parts'][0]} and {c['parts'][1]} at "
                     f"t = {c['t']:.4g} s ({c['force_N']:.3g} N)")
    if "realtime_factor" in metrics:
        lines.append(f"real-time factor: {metrics['realtime_factor']:.2f} "
                     f"({metrics['window_s'][1]:.1f} s sim / {metrics['wall_s']:.2f} s wall)")
    return "\n".join(lines)


_OPTIONAL_ARRAYS = ("omega", "integral", "rho", "T_ff")


def save_result(result: RunResult, path: str | Path) -> Path:
    """Write the run to ``path``: an .npz of t, x, x_d, T, closure, status (+ omega, integral,
    rho, T_ff when present), status_names, metrics (JSON) and config (JSON, with the scenario
    YAML)."""
    arrays = dict(t=result.t, x=result.x, x_d=result.x_d, T=result.T, closure=result.closure,
                  status=result.status, status_names=np.array(result.status_names, dtype=str),
                  metrics=np.array(json.dumps(result.metrics)),
                  config=np.array(json.dumps(result.config_summary)))
    arrays.update({k: getattr(result, k) for k in _OPTIONAL_ARRAYS
                   if getattr(result, k) is not None})
    return save_npz(Path(path), arrays)


def load_result(path: str | Path) -> RunResult:
    """Read a file written by :func:`save_result`.

    Raises:
        CorruptFileError: not such a file (damaged archive, an entry missing or of the wrong
            type, metrics or config that are not JSON); names the file and the fault.
        OSError: the file cannot be read.
    """
    data = CheckedNpz(path, "run result file", "run it again with `stewart-drake run`")
    arrays = {k: data.array(k) for k in ("t", "x", "x_d", "T", "closure", "status")
              + tuple(k for k in _OPTIONAL_ARRAYS if k in data)}
    names = data.arrays.get("status_names")
    if names is None or names.dtype.kind != "U" or names.ndim != 1:
        raise data.corrupt("the entry 'status_names' must be a list of strings")
    return RunResult(**arrays, status_names=tuple(str(v) for v in names),
                     metrics=data.json("metrics"), config_summary=data.json("config"))


#: Window of the torque panel's means and of the feedback map, s.
TORQUE_WINDOW_S = 0.05


def _window_stats(t: np.ndarray, values: np.ndarray, window_s: float):
    """(t_w (W,), mean (W, k), rms (W, k)) of values (N, k) over consecutive windows of
    ``window_s``: the 1 kHz torque chatter of an encoder's quantum averaged out (mean) and
    measured (rms)."""
    index = ((t - t[0]) / window_s + 1e-9).astype(int)
    n = index[-1] + 1
    counts = np.maximum(np.bincount(index, minlength=n), 1)[:, None]
    mean = np.stack([np.bincount(index, weights=v, minlength=n) for v in values.T], 1) / counts
    square = np.stack([np.bincount(index, weights=v ** 2, minlength=n) for v in values.T], 1)
    t_w = t[0] + (np.arange(n) + 0.5) * window_s
    return t_w, mean, np.sqrt(square / counts)


def _zoom_window(t: np.ndarray, ref: np.ndarray, err: np.ndarray) -> slice:
    """Samples around the largest |err| over which the reference moves by about four times that
    error, so that reference and achieved value are told apart in a zoom (5 ms .. 1 s)."""
    k = int(np.argmax(np.abs(err)))
    peak = max(abs(err[k]), 1e-15)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    half = max(int(round(0.005 / dt)), 2)
    while half * dt < 1.0:
        window = ref[max(k - half, 0):k + half + 1]
        if np.ptp(window) > 4 * peak:
            break
        half = int(half * 1.5) + 1
    return slice(max(k - half, 0), min(k + half + 1, len(t)))


def plot_fig7(result: RunResult, path: str | Path) -> Path:
    """Paper Fig. 7 as a PNG, one quantity per panel, plain linear axes.

    Panels: phi and Z with their references, each with a zoom on the instant of its largest
    error where the two curves part (mrad, mm); the angle and position tracking errors (urad,
    um); the integral states z (eq. 23) when the controller has them; omega_Q and omega_R when
    tuned (log axis: they span decades); the motor torques as 20 ms means with the motors'
    limit; and, when the feed-forward is known, the feedback torque T - T_ff per motor as a map
    of its 20 ms RMS (the chatter of the encoders' quantum, which drawn raw hides the six
    motors in one band).
    Returns:
        the path written (atomically).
    """
    # A Figure without pyplot: no global backend switch (a notebook keeps its inline plots).
    from matplotlib.figure import Figure

    t = result.t
    err = result.x[:, :6] - result.x_d[:, :6]
    panels = ["phi", "Z", "angle_error", "position_error"]
    if result.integral is not None:
        panels.append("integral")
    if result.omega is not None and np.ptp(result.omega) > 0:
        panels.append("omega")
    panels.append("torque")
    if result.T_ff is not None:
        panels.append("feedback")
    heights = [1.2 if p in ("phi", "Z") else 0.8 if p == "feedback" else 1.0 for p in panels]
    fig = Figure(figsize=(10, 1.75 * sum(heights) + 0.8))
    # Left: the time series, one width, one time axis. Right: the zooms, legends, colour bar.
    grid = fig.add_gridspec(len(panels), 2, height_ratios=heights, width_ratios=(3.3, 1))
    axes, sides = [], []
    for row in range(len(panels)):
        axes.append(fig.add_subplot(grid[row, 0], sharex=axes[0] if axes else None))
        sides.append(fig.add_subplot(grid[row, 1]))
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    summary = result.config_summary

    def legend_beside(ax, side, loc="center left", **kwargs):
        side.set_axis_off()
        side.legend(*ax.get_legend_handles_labels(), loc=loc, fontsize=8, frameon=False,
                    **kwargs)

    for ax, side, panel in zip(axes, sides, panels):
        if panel in ("phi", "Z"):
            k, unit, scale, zoom_unit = ((0, "rad", 1e3, "mrad") if panel == "phi"
                                         else (5, "m", 1e3, "mm"))
            sym = r"\varphi" if panel == "phi" else "Z"
            color = "C0" if k == 0 else "C3"
            ax.plot(t, result.x_d[:, k], color="0.75", lw=3.5, label=f"${sym}_d$ reference")
            ax.plot(t, result.x[:, k], color, lw=1.0, label=f"${sym}$ achieved")
            ax.set_ylabel(f"${sym}$ [{unit}]")
            ax.legend(loc="upper left", fontsize=8, ncol=2)
            # The error is a thousandth of the motion: only a zoom shows both curves apart.
            w = _zoom_window(t, result.x_d[:, k], err[:, k])
            ax.axvspan(t[w][0], t[w][-1], color="k", alpha=0.3, lw=0)
            base = result.x_d[w, k][len(result.x_d[w, k]) // 2]
            side.plot(t[w], scale * (result.x_d[w, k] - base), color="0.75", lw=3.5)
            side.plot(t[w], scale * (result.x[w, k] - base), color, lw=1.0)
            side.set_title(f"zoom at the largest error (grey band),\naround ${sym}$ = {base:.4g} "
                           f"{unit}", fontsize=8)
            side.set_ylabel(f"[{zoom_unit}]", fontsize=8)
            side.set_xlabel("t [s]", fontsize=8, labelpad=1)
            side.tick_params(labelsize=7)
            side.grid(alpha=0.3)
        elif panel in ("angle_error", "position_error"):
            part = range(3) if panel == "angle_error" else range(3, 6)
            unit = "urad" if panel == "angle_error" else "um"
            for k in part:
                ax.plot(t, 1e6 * err[:, k], lw=0.8, label=AXES[k])
            ax.set_ylabel(f"{'angle' if k < 3 else 'position'} error\nx - x_d [{unit}]")
            legend_beside(ax, side, title="axis")
        elif panel == "integral":
            for k in range(6):
                ax.plot(t, 1e6 * result.integral[:, k], lw=0.8, label=AXES[k])
            ax.set_ylabel("integral states z\n[urad s | um s]")
            legend_beside(ax, side, ncol=2, title="axis")
        elif panel == "omega":
            ax.plot(t, result.omega[:, 0], label=r"$\omega_Q$")
            ax.plot(t, result.omega[:, 1], label=r"$\omega_R$")
            ax.set_yscale("log")
            ax.set_ylabel("tuner output")
            legend_beside(ax, side)
        elif panel == "torque":
            t_w, mean, _ = _window_stats(t, result.T, TORQUE_WINDOW_S)
            for i in range(6):
                ax.plot(t_w, mean[:, i], lw=1.2, label=f"$T_{i + 1}$")
            limit = summary.get("motor_limit_Nm")
            ax.set_ylabel(f"motor torque\n{1e3 * TORQUE_WINDOW_S:g} ms means [N m]")
            legend_beside(ax, side, loc="upper left", ncol=2, title="motor")
            side.text(0.0, 0.0, f"peak |T| {np.abs(result.T).max():.3g} N m in 1 ms samples"
                      + (f"\nmotors' limit {limit:.3g} N m" if limit else ""), fontsize=7,
                      transform=side.transAxes, va="bottom")
        else:
            t_w, _, rms = _window_stats(t, result.T - result.T_ff, TORQUE_WINDOW_S)
            image = ax.imshow(rms.T, aspect="auto", origin="lower", cmap="viridis",
                              extent=(t_w[0] - TORQUE_WINDOW_S / 2,
                                      t_w[-1] + TORQUE_WINDOW_S / 2, 0.5, 6.5),
                              interpolation="nearest")
            ax.set_yticks(range(1, 7))
            ax.set_ylabel("feedback T - T_ff\nper motor")
            side.set_axis_off()
            bar = fig.colorbar(image, cax=side.inset_axes([0.0, 0.05, 0.06, 0.9]))
            bar.set_label(f"{1e3 * TORQUE_WINDOW_S:g} ms RMS [N m]", fontsize=8)
            bar.ax.tick_params(labelsize=7)
        if panel != "feedback":
            ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(t[0], t[-1])
    name = summary.get("trajectory", "")
    robot = ("robot as built (encoders, servos, delay)" if summary.get("hardware")
             else "ideal robot")
    what = "Fig. 7: paper manoeuvre (eqs. 37-38)" if name == "paper" else f"{name} run"
    fig.suptitle(f"{what}, {robot}", fontsize=11)
    fig.tight_layout()
    path = Path(path)
    atomic_write(path, lambda f: fig.savefig(f, dpi=110, format="png"))
    return path
