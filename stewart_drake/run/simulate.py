"""Closed-loop runs: simulate a :class:`~stewart_drake.run.scenario.Scenario`, collect its
logs and metrics, save and load them.

``run_experiment(scenario)`` returns a :class:`RunResult` (arrays + metrics,
:func:`~.metrics.compute_metrics`); ``save_result`` writes ``<name>.npz`` (arrays, the metrics as
JSON and the scenario as YAML). The pictures and the printed summary are made apart, from a
result (:mod:`.run_report`: ``plot_fig7``, ``format_metrics``, importable from here too).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator

from ..base.fileio import CheckedNpz, save_npz
from ..plant.closed_chain import loop_closure_errors
from ..station import guard
from .diagram import StewartDiagram, make_stewart_diagram
from .metrics import compute_metrics
from .plan import RunPlan, check_reference, make_plan
from .reference import ReferenceSources
from .scenario import Scenario

#: Where ``stewart-drake train`` writes the tuner and ``run --tuner ann`` looks first.
DEFAULT_TUNER_OUT = Path("results") / "tuner" / "ann_tuner.npz"


@dataclass
class RunResult:
    """Logged arrays of one run (SI units) and its metrics.

    Two time bases: ``t`` (every ``log_period_s``) for the run's signals, ``t_state`` (every
    ``state_log_period_s``, 10 ms by default) for the plant's state and what is read from it.
    The signals at ``t`` are float32 (7 significant digits: 30 nm at the platform's 0.3 m, a
    thousandth of the smallest error a report resolves), so a long run holds about 0.2 kB per
    logged sample (:data:`LOG_BYTES_PER_SAMPLE`); times and the plant state are float64.

    Attributes:
        t: (N,) s.  x: (N, 12) true pose and rate (from the plant state, free of sensor noise).
        x_d: (N, 18) reference pose, rate, acceleration.  T: (N, 6) applied motor torques, N m.
        closure: (M,) max loop-closure error over the six rods at ``t_state``, m.
        status: (N, k) the controller's ``status`` output, named by ``status_names`` (empty
            (N, 0) for a controller without one).
        omega: (N, 2) omega_Q, omega_R in use (from status), or None when the controller
            reports none.  integral: (N, 6) the controller's integral states, or None.
        rho: (M, 12) density features at the tuner's instants (every tuner period) or None.
        e_bar: (N, 6) the pose error the controller acted on (its estimate of x minus x_d: on
            the hardware, from the encoders), or None.
        T_ff: (N, 6) the feed-forward torques of the reference at each logged time, N m (T -
            T_ff is the feedback's share), or None.
        metrics: dict of the figures printed by the CLI (see
            :func:`~.metrics.compute_metrics`).
        config_summary: the run's settings (name, controller, weights, ...) and ``scenario``,
            the whole scenario as YAML.
        t_state: (M,) s, the times of ``state`` and ``closure`` (None: ``t``, as in a file
            saved before the state had its own period).
        state: (M, nq + nv) the plant's state at ``t_state`` (a replay's frames), or None.
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
    t_state: np.ndarray | None = None
    state: np.ndarray | None = None

    def __post_init__(self):
        if self.t_state is None:
            self.t_state = self.t

    def nbytes(self) -> int:
        """Bytes the result's arrays hold."""
        return sum(v.nbytes for v in vars(self).values() if isinstance(v, np.ndarray))


def advance(simulator: Simulator, t_end: float, progress: bool, desc: str = "simulating"):
    """``simulator.AdvanceTo(t_end)``, in 200 chunks behind a tqdm bar when ``progress``."""
    if not progress:
        simulator.AdvanceTo(t_end)
        return
    from tqdm import tqdm

    chunk = max(t_end / 200, 1e-3)
    with tqdm(
        total=round(t_end, 6),
        desc=desc,
        unit="sim s",
        bar_format=("{l_bar}{bar}| {n:.2f}/{total:.2f} sim s [{elapsed}<{remaining}]"),
    ) as bar:
        t = simulator.get_context().get_time()
        while t < t_end - 1e-12:
            t_next = min(t + chunk, t_end)
            simulator.AdvanceTo(t_next)
            bar.update(t_next - t)
            t = t_next


#: Memory a run holds, bytes, measured as the peak RSS of ``stewart-drake reproduce`` on
#: synthetic phantom traces of 1 and 25 minutes at 1 kHz (the robot as built, logs every
#: millisecond): 0.40 GB before anything is logged (Python, Drake, the plant, the compiled
#: controller, the reference's check) and 0.44 kB per logged sample all told (1.06 GB for 25
#: minutes; 1.76 kB and 3.2 GB before the logs were sized for the run). Of a sample: the
#: float32 logs (0.16 kB: pose and rate, torques, the controller's status, integral and error),
#: the plant state every ``state_log_period_s`` (61 float64 every 10 ms: 0.05 kB a
#: millisecond), the feed-forward table and sample times (0.07 kB a control period: the
#: reference itself is evaluated a stretch at a time, and the tables are dropped once the run
#: is read), the result's reference and feed-forward (0.1 kB) and the report's intermediates
#: (0.08 kB). Upper bounds with some slack:
RUN_BASE_BYTES = 0.4e9
LOG_BYTES_PER_SAMPLE = 0.5e3
CONTROL_BYTES_PER_SAMPLE = 0.15e3
STATE_BYTES_PER_SAMPLE = 1.0e3
#: A learner's status log: up to 16 float64 per plant-state sample (it is logged with the
#: plant state, every ``state_log_period_s``), with slack.
LEARNER_BYTES_PER_SAMPLE = 0.2e3


def run_memory_bytes(scenario: Scenario) -> float:
    """Estimated peak memory of one run of ``scenario``, bytes (inf-safe for huge durations):
    :data:`RUN_BASE_BYTES`, its control-period samples, its logged samples and its plant-state
    samples (see :data:`LOG_BYTES_PER_SAMPLE`), a learner's status log
    (:data:`LEARNER_BYTES_PER_SAMPLE`), plus what the reference itself holds (a CSV
    reference's spline, :meth:`~stewart_drake.references.motion.ReferenceConfig.memory_bytes`)."""
    d = float(scenario.duration_s)
    return (
        RUN_BASE_BYTES
        + scenario.reference.memory_bytes()
        + (d / scenario.control_period_s + 1) * CONTROL_BYTES_PER_SAMPLE
        + (d / scenario.log_period_s + 1) * LOG_BYTES_PER_SAMPLE
        + (d / scenario.state_log_period_s + 1) * STATE_BYTES_PER_SAMPLE
        + (scenario.learning is not None)
        * (d / scenario.state_log_period_s + 1)
        * LEARNER_BYTES_PER_SAMPLE
    )


def check_run_memory(scenario: Scenario, runs_at_once: int = 1, change: str | None = None):
    """Refuse, before anything is allocated, runs that need more memory than the machine has.

    Args:
        scenario: the run.  runs_at_once: how many such runs are in memory together (workers).
        change: what the message tells to change (default: duration_s or log_period_s).
    Raises:
        InvalidConfigError: one line with the estimate and the memory available.
    """
    from ..base.checks import check_memory

    on_reference, coarser = scenario.reference.memory_note()
    what = (
        f"{'a run of' if runs_at_once == 1 else f'{runs_at_once} runs at once, each of'} "
        f"{scenario.duration_s:g} s logged every {scenario.log_period_s:g} s{on_reference}"
    )
    check_memory(
        what,
        runs_at_once * run_memory_bytes(scenario),
        change or ("shorten duration_s (--duration) or lengthen log_period_s" + coarser),
    )


#: Control-period samples above which a shown check has a bar (a minute at 1 kHz: the check
#: takes about 3 s; a 20-minute trace checks for about a minute).
CHECK_BAR_SAMPLES = 60_000


def check_reference_shown(plan: RunPlan, reference=None, progress: bool = False, **kwargs):
    """:func:`~stewart_drake.run.plan.check_reference` of ``plan`` (and ``reference``),
    behind a tqdm bar ("checking") when ``progress`` and the check has more than
    :data:`CHECK_BAR_SAMPLES` samples.

    Args:
        plan: the run. reference: the reference (default: the plan's). progress: show the bar.
        kwargs: ``raise_refused``, ``keep_series`` of ``check_reference``.
    Returns:
        the :class:`~stewart_drake.robot.limits.TrajectoryReport`.
    """
    from tqdm import tqdm

    samples = int(plan.duration_s / plan.control_period_s) + 1
    shown = progress and samples > CHECK_BAR_SAMPLES
    with tqdm(total=samples, desc="checking", unit=" samples", disable=not shown) as bar:
        return check_reference(plan, reference, progress=bar if shown else None, **kwargs)


def build_simulator(
    scenario: Scenario | RunPlan | None = None,
    meshcat=None,
    *,
    reference=None,
    controller=None,
    progress: bool = False,
    report=None,
    controller_logs: bool = True,
    on_checked=None,
):
    """(StewartDiagram, Simulator) with the loops assembled at x_d(0) moving at x_dot_d(0), guarded.

    The run's memory is checked first (:func:`check_run_memory`), then the reference
    (:func:`~stewart_drake.run.plan.check_reference`); ``sd.guard``, the
    Diagram's :class:`guard.DivergenceGuard`, checks the run as it goes (advance with
    :func:`guard.advance` to get the logs saved when it trips). ``scenario.simulator`` is
    applied.

    Args:
        scenario, meshcat, reference, controller, controller_logs: as
            :func:`~stewart_drake.run.diagram.make_stewart_diagram`.
        progress: show a bar while a long reference is checked (:func:`check_reference_shown`).
        report: the check's report when the caller has already checked this plan's reference
            (it is then not checked again).
        on_checked: called (no arguments) once the checks pass, before the Diagram is built.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError: the reference leaves the
            workspace, a joint range or nears a singularity (first time, leg or measure),
            checked before anything is simulated. InvalidConfigError: a bad scenario field, or
            a run that needs more memory than the machine has (:func:`check_run_memory`), or
            an ``lcm.url`` on which nothing published arrives
            (:func:`~stewart_drake.station.lcm_publish.make_lcm`).
    """
    plan = make_plan(scenario, with_reference=False)  # validated once, here
    check_run_memory(plan.scenario)
    plan = make_plan(plan, reference=reference, controller=controller)
    if report is None:
        check_reference_shown(plan, progress=progress, keep_series=False)
    if plan.scenario.lcm is not None:  # a dead URL is a refusal: before the Diagram is built
        from ..station.lcm_publish import make_lcm

        make_lcm(plan.scenario.lcm.url)
    if on_checked is not None:
        on_checked()
    sd = make_stewart_diagram(plan, meshcat=meshcat, controller_logs=controller_logs)
    simulator = Simulator(sd.diagram)
    ApplySimulatorConfig(plan.scenario.simulator, simulator)
    context = simulator.get_mutable_context()
    sd.initialize(context)
    # Start on the reference, moving with it: a platform at rest under a reference that already
    # moves (eqs. 37-38 start at phi_dot = 2 pi/6 rad/s) makes a torque spike that is not
    # tracking (1.7 N m against 0.41 N m afterwards).
    x0, x_dot0, _ = sd.trajectory.evaluate(0.0)
    sd.station.assemble(context, x0, x_dot0)
    simulator.Initialize()
    return sd, simulator


def run_experiment(
    scenario: Scenario | RunPlan | None = None,
    progress: bool = False,
    meshcat=None,
    *,
    reference=None,
    controller=None,
    on_checked=None,
) -> RunResult:
    """Simulate one closed-loop run and collect its logs and metrics.

    Args:
        scenario: the run, a scenario or a :class:`~stewart_drake.run.plan.RunPlan`
            (default: the paper's experiment on the ideal robot, 10 s).
        progress: show a tqdm progress bar.
        meshcat: optional Meshcat to visualize the run.
        reference: optional reference object overriding ``scenario.reference`` (an object with
            ``evaluate(t)``, a Drake ``Trajectory``, a CSV path or a name).
        controller: optional controller factory or registered name (the controller contract,
            :mod:`~stewart_drake.control.contract`) overriding ``scenario.controller``.
        on_checked: called (no arguments) once the run's checks pass, before the Diagram is
            built: the command line says there what the next seconds do.
    Returns:
        :class:`RunResult`.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError before simulating (see
        :func:`build_simulator`); SimulationDivergedError when the guard stops the run (the
        logs up to then are saved, the path is in the error).
    """
    sd, simulator = build_simulator(
        scenario,
        meshcat,
        reference=reference,
        controller=controller,
        progress=progress,
        on_checked=on_checked,
    )
    logs, wall = simulate(sd, simulator, progress)
    release_reference(sd)
    return finish_result(logs, wall)


def config_summary(sd: StewartDiagram) -> dict:
    """The settings of a run that results and records carry (plain JSON values)."""
    plan, scenario = sd.plan, sd.scenario
    summary = {
        "trajectory": getattr(sd.trajectory, "name", "custom"),
        "duration_s": scenario.duration_s,
        "plant_time_step_s": plan.plant_time_step_s,
        "control_period_s": scenario.control_period_s,
        "controller": type(scenario.controller).__name__,
        "tuner": scenario.tuner is not None,
        "feedforward": scenario.feedforward,
        "payload_scale": scenario.payload_scale,
        "torque_limit_Nm": scenario.torque_limit_Nm,
        "motor_limit_Nm": plan.torque_limit_Nm,
        "sensor_noise": scenario.sensor_noise is not None,
        "hardware": scenario.hardware is not None,
        "scenario": sd.scenario_yaml(),
        **scenario.controller.summary(),
    }
    return summary


def collect_result(sd: StewartDiagram, root_context, wall_s: float) -> RunResult:
    """Pull the loggers of a simulated Diagram into a :class:`RunResult` with metrics (the
    signals at the log period, the plant state at its own period, :class:`RunResult`)."""
    return finish_result(read_run(sd, root_context), wall_s)


@dataclass
class RunLogs:
    """What :func:`read_run` takes from a simulated Diagram: the :class:`RunResult` without its
    reference and metrics, the reference object, and the first contact (None without contact
    or with none seen). The reference's tables can go after it (:func:`release_reference`)."""

    result: RunResult
    trajectory: object
    contact: bool
    first_contact: tuple | None


def read_run(sd: StewartDiagram, root_context) -> RunLogs:
    """The logs of a simulated Diagram as a :class:`RunLogs`: the signals are views of the logs
    (no copy), the feed-forward is read from the reference's table, the loop closure from the
    logged plant states; the reference's pose at the log times is left to
    :func:`finish_result`, so that a caller can drop the reference's tables
    (:func:`release_reference`, 0.1 kB per control period) before that array is made."""
    logs = {name: logger.FindLog(root_context) for name, logger in sd.loggers.items()}
    t = logs["x"].sample_times()
    state = logs["state"].data().T
    names = tuple(getattr(sd.controller, "status_names", ())) if "status" in logs else ()
    status = logs["status"].data().T if "status" in logs else np.zeros((len(t), 0), np.float32)
    omega = (
        status[:, [names.index("omega_Q"), names.index("omega_R")]]
        if {"omega_Q", "omega_R"} <= set(names)
        else None
    )
    result = RunResult(
        t=t,
        x=logs["x"].data().T,
        x_d=np.zeros((0, 18), np.float32),  # finish_result
        T=logs["T"].data().T,
        closure=loop_closures_from_states(sd, state),
        status=status,
        status_names=names,
        omega=omega,
        integral=logs["integral"].data().T if "integral" in logs else None,
        rho=logs["rho"].data().T.copy() if "rho" in logs else None,
        e_bar=logs["e_bar"].data().T if "e_bar" in logs else None,
        T_ff=feedforward_at(sd, t),
        config_summary=config_summary(sd),
        t_state=logs["state"].sample_times(),
        state=state,
    )
    contact = bool(sd.scenario.contact)
    first = sd.guard.first_contact(root_context) if contact and sd.guard is not None else None
    return RunLogs(result, sd.trajectory, contact, first)


def finish_result(logs: RunLogs, wall_s: float) -> RunResult:
    """The :class:`RunResult` of :func:`read_run`'s logs: the reference at the log times
    (:func:`reference_at`) and the metrics (:func:`~.metrics.compute_metrics`)."""
    result = logs.result
    result.x_d = reference_at(logs.trajectory, result.t)
    result.metrics = compute_metrics(result, wall_s)
    if logs.contact:
        first = logs.first_contact
        result.metrics["first_contact"] = (
            None
            if first is None
            else {"t": first[0], "parts": list(first[1:3]), "force_N": first[3]}
        )
    return result


def release_reference(sd: StewartDiagram) -> None:
    """Drop a run's reference tables once it is read (:func:`read_run`), before its result's
    arrays are made (:meth:`~stewart_drake.run.reference.ReferenceSources.release`):
    the Diagram cannot run again."""
    if isinstance(sd.reference, ReferenceSources):
        sd.reference.release()


def simulate(
    sd: StewartDiagram, simulator: Simulator, progress: bool = False, desc: str = "simulating"
) -> tuple[RunLogs, float]:
    """Advance a built run to its end through the guard (:func:`guard.advance`) and read it
    (:func:`read_run`). Returns (logs, wall time of the simulation, s)."""
    wall0 = time.perf_counter()
    guard.advance(sd, simulator, lambda: advance(simulator, sd.plan.duration_s, progress, desc))
    wall = time.perf_counter() - wall0
    return read_run(sd, simulator.get_context()), wall


#: Samples :func:`reference_at` and :func:`feedforward_at` compute at once (their float64
#: intermediates, a stretch at a time).
RESULT_CHUNK = 20_000


def reference_at(trajectory, t: np.ndarray) -> np.ndarray:
    """(N, 18) float32 the reference's pose, rate and acceleration at times t (s): the
    analytic reference a logged sample at t_n is compared with (a logged sample is the state the
    plant computed for physical time t_n; the controller's x_d leads by half a plant step),
    evaluated a stretch at a time."""
    out = np.empty((len(t), 18), dtype=np.float32)
    for a in range(0, len(t), RESULT_CHUNK):
        out[a : a + RESULT_CHUNK] = np.concatenate(
            trajectory.evaluate(t[a : a + RESULT_CHUNK]), axis=1
        )
    return out


def feedforward_at(sd: StewartDiagram, t: np.ndarray) -> np.ndarray:
    """(N, 6) float32 the feed-forward torques the reference asks for at times t (s), N m: the
    Diagram's feed-forward table, each row placed at the time it is meant to act (the sample's
    reference time plus the computation delay), linearly interpolated."""
    reference = sd.reference
    # A run's reference is precomputed (ReferenceSources); a live one has no table.
    assert isinstance(reference, ReferenceSources)
    t_act = reference.t_eval + sd.plan.delay_periods * sd.plan.control_period_s
    table = reference.T_ff_table
    out = np.empty((len(t), table.shape[1]), dtype=np.float32)
    for i in range(table.shape[1]):
        out[:, i] = np.interp(t, t_act, table[:, i])
    return out


def loop_closures_from_states(sd: StewartDiagram, states: np.ndarray) -> np.ndarray:
    """(N,) max loop-closure error in m at each plant state (N, nq + nv)."""
    plant = sd.plant
    context = plant.CreateDefaultContext()
    nq = plant.num_positions()
    out = np.empty(len(states))
    for k, s in enumerate(states):
        plant.SetPositions(context, s[:nq])
        out[k] = loop_closure_errors(plant, context, sd.handles).max()
    return out


_OPTIONAL_ARRAYS = ("omega", "integral", "rho", "T_ff", "t_state", "state")


def save_result(result: RunResult, path: str | Path) -> Path:
    """Write the run to ``path``: an .npz of t, x, x_d, T, closure, status (+ omega, integral,
    rho, T_ff, t_state and state when present), status_names, metrics (JSON) and config (JSON,
    with the scenario YAML)."""
    arrays = dict(
        t=result.t,
        x=result.x,
        x_d=result.x_d,
        T=result.T,
        closure=result.closure,
        status=result.status,
        status_names=np.array(result.status_names, dtype=str),
        metrics=np.array(json.dumps(result.metrics)),
        config=np.array(json.dumps(result.config_summary)),
    )
    arrays.update(
        {k: getattr(result, k) for k in _OPTIONAL_ARRAYS if getattr(result, k) is not None}
    )
    return save_npz(Path(path), arrays)


#: The pose's and its rate's names and units, in the order of RunResult.x.
_POSE_COLUMNS = (
    ("phi", "rad"),
    ("theta", "rad"),
    ("psi", "rad"),
    ("X", "m"),
    ("Y", "m"),
    ("Z", "m"),
)


def result_columns(result: RunResult) -> tuple[list[str], list[str], np.ndarray]:
    """(names, units, (N, k) values) of a run's logs as one table: t; the true pose and rate;
    the reference's pose, rate and acceleration (``_d``); the applied motor torques T0..T5 (motor
    i is leg i of docs/reference_geometry.md and the paper's T_{i+1}); the largest loop-closure
    error (logged with the plant state, every ``state_log_period_s``, joined linearly); omega_Q
    and omega_R when the controller reports them."""
    names, units, columns = ["t"], ["s"], [result.t[:, None]]
    for suffix, per in (("", ""), ("_dot", "/s")):
        names += [f"{n}{suffix}" for n, _ in _POSE_COLUMNS]
        units += [f"{u}{per}" for _, u in _POSE_COLUMNS]
    columns.append(result.x)
    for suffix, per in (("_d", ""), ("_dot_d", "/s"), ("_ddot_d", "/s^2")):
        names += [f"{n}{suffix}" for n, _ in _POSE_COLUMNS]
        units += [f"{u}{per}" for _, u in _POSE_COLUMNS]
    columns.append(result.x_d)
    names += [f"T{i}" for i in range(6)] + ["closure"]
    units += ["N m"] * 6 + ["m"]
    t_state = result.t if result.t_state is None else result.t_state  # an older file: t
    closure = np.interp(result.t, t_state, result.closure)  # every state log period
    columns += [result.T, closure[:, None]]
    if result.omega is not None:
        names += ["omega_Q", "omega_R"]
        units += ["1", "1"]
        columns.append(result.omega)
    return names, units, np.hstack(columns)


def export_result(result: RunResult, stem: str | Path) -> list[Path]:
    """Write a run's logs as a table with named columns and units, for spreadsheets and MATLAB:
    ``<stem>.csv`` (a header ``name [unit]`` per column, :func:`result_columns`) and
    ``<stem>.mat`` (one variable per column, plus ``columns`` and ``units``, cell arrays of
    the names and units), each written atomically.

    Returns:
        [the .csv path, the .mat path].
    """
    import io

    from scipy.io import savemat

    from ..base.fileio import atomic_write

    names, units, table = result_columns(result)
    stem = Path(stem)
    text = io.StringIO()
    text.write(",".join(f"{n} [{u}]" for n, u in zip(names, units, strict=True)) + "\n")
    np.savetxt(text, table, delimiter=",", fmt="%.17g")
    csv, mat = stem.with_suffix(".csv"), stem.with_suffix(".mat")
    atomic_write(csv, lambda f: f.write(text.getvalue().encode()))
    variables = {n: table[:, k] for k, n in enumerate(names)}
    variables["columns"] = np.array(names, dtype=object)
    variables["units"] = np.array(units, dtype=object)
    atomic_write(mat, lambda f: savemat(f, variables))
    return [csv, mat]


def load_result(path: str | Path) -> RunResult:
    """Read a file written by :func:`save_result`.

    Raises:
        CorruptFileError: not such a file (damaged archive, an entry missing or of the wrong
            type, metrics or config that are not JSON); names the file and the fault.
        OSError: the file cannot be read.
    """
    data = CheckedNpz(path, "run result file", "run it again with `stewart-drake run`")
    arrays = {
        k: data.array(k)
        for k in ("t", "x", "x_d", "T", "closure", "status")
        + tuple(k for k in _OPTIONAL_ARRAYS if k in data)
    }
    names = data.arrays.get("status_names")
    if names is None or names.dtype.kind != "U" or names.ndim != 1:
        raise data.corrupt("the entry 'status_names' must be a list of strings")
    return RunResult(
        **arrays,
        status_names=tuple(str(v) for v in names),
        metrics=data.json("metrics"),
        config_summary=data.json("config"),
    )
