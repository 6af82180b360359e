"""A run's record: the result read back from what the Diagram logged (:mod:`.run_logs`), saved
and loaded.

After the run, :func:`read_run` and :func:`finish_result` make its :class:`RunResult` (arrays and
metrics, :func:`~.metrics.compute_metrics`); :func:`save_result` writes ``<name>.npz`` (arrays,
the metrics as JSON and the scenario as YAML), :func:`load_result` reads it back and
:func:`export_result` writes a table for spreadsheets and MATLAB. The functions that read a run
take its :class:`~.diagram.StewartDiagram` (``sd``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.columns import interp_columns
from ..base.fileio import save_npz
from ..base.npz import CheckedNpz
from ..references.motion import Reference
from .metrics import compute_metrics
from .reference import ReferenceSources


@dataclass
class RunResult:
    """Logged arrays of one run (SI units) and its metrics.

    Two time bases: ``t`` (every ``log_period_s``) for the signals, float32 (module docstring;
    about 0.2 kB a logged sample, :data:`~.memory.LOG_BYTES_PER_SAMPLE`), and ``t_state`` (every
    ``state_log_period_s``) for the plant's state, float64.

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
        metrics: dict of the figures printed by the CLI (:func:`~.metrics.compute_metrics`).
        config_summary: the run's settings (name, controller, weights, ...) and ``scenario``,
            the whole scenario as YAML.
        t_state: (M,) s, the times of ``state`` and ``closure`` (None: ``t``, an older file).
        state: (M, nq + nv) the plant's state at ``t_state`` (a replay's frames), or None.
        learner_status: (M + 1, k) a learner's status at ``t_state`` and at the run's end
            (a period after the loggers' last, which misses a cycle's last update), or None.
            learned: (p, 6) a feed-forward learner's weights at the end, or None. Neither is
            saved (:func:`save_result`).
        surrogate: (N, 5) the surrogate's stage at ``t`` with the scenario's ``surrogate``:
            [p m, v m/s, p_d m, v_d m/s, a_d m/s^2], the carriage and the goal it was given
            (docs/surrogate.md), or None. Not saved.
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
    learner_status: np.ndarray | None = None
    learned: np.ndarray | None = None
    surrogate: np.ndarray | None = None

    def __post_init__(self):
        if self.t_state is None:
            self.t_state = self.t

    def nbytes(self) -> int:
        """Bytes the result's arrays hold."""
        return sum(v.nbytes for v in vars(self).values() if isinstance(v, np.ndarray))


def config_summary(sd) -> dict:
    """The settings of a run that results and records carry (plain JSON values), with
    ``temperature_note`` when the run has one (:func:`~.plan.temperature_note`)."""
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
    from .plan import temperature_note

    note = temperature_note(plan)
    if note is not None:
        summary["temperature_note"] = note
    return summary


def collect_result(sd, root_context, wall_s: float) -> RunResult:
    """Pull the loggers of a simulated Diagram into a :class:`RunResult` with metrics (the
    signals at the log period, the plant state at its own period, :class:`RunResult`)."""
    return finish_result(read_run(sd, root_context), wall_s)


@dataclass
class RunLogs:
    """What :func:`read_run` takes from a simulated Diagram: the :class:`RunResult` without its
    reference and metrics, the reference object, the first contact (None without contact or
    with none seen), and how long before its log time each logged pose was measured, s (the
    station's ``logged_pose_lag_s``: 0 for the simulated plant, one control period on the servo
    bus). The reference's tables can go after it (:func:`release_reference`)."""

    result: RunResult
    trajectory: Reference
    contact: bool
    first_contact: tuple | None
    pose_lag_s: float = 0.0


def read_run(sd, root_context) -> RunLogs:
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
        surrogate=logs["surrogate"].data().T if "surrogate" in logs else None,
    )
    if getattr(sd, "learner", None) is not None:
        result.learner_status, result.learned = _learner_record(sd, root_context)
    contact = bool(sd.scenario.contact)
    first = sd.guard.first_contact(root_context) if contact and sd.guard is not None else None
    for logger in sd.loggers.values():  # read: the run's Context is not held for a drain
        logger.log.unbind()
    # A live reference that kept its record (``evaluate``, ``feedforward_at``) is its own.
    trajectory = sd.trajectory if sd.trajectory is not None else sd.reference
    lag = float(getattr(sd.station, "logged_pose_lag_s", 0.0))
    return RunLogs(result, trajectory, contact, first, lag)


def _learner_record(sd, root_context) -> tuple:
    """(status (M + 1, k), learned (p, 6) or None) of the Diagram's learner
    (:attr:`RunResult.learner_status`, :attr:`RunResult.learned`)."""
    learner = sd.learner
    context = learner.GetMyContextFromRoot(root_context)
    log = sd.loggers[learner.status_port].FindLog(root_context).data().T
    final = learner.GetOutputPort(learner.status_port).Eval(context)
    learned = None
    if learner.HasOutputPort("theta"):
        learned = np.asarray(learner.GetOutputPort("theta").Eval(context)).reshape(-1, 6)
    return np.vstack([log, final]), learned


def finish_result(logs: RunLogs, wall_s: float) -> RunResult:
    """The :class:`RunResult` of :func:`read_run`'s logs: the reference at the times the logged
    poses were measured (:func:`reference_at`: the log times, less the station's
    ``pose_lag_s``) and the metrics (:func:`~.metrics.compute_metrics`, with the run's
    ``temperature_note`` when it has one: :func:`~.plan.temperature_note`)."""
    result = logs.result
    t = result.t if logs.pose_lag_s == 0.0 else np.maximum(result.t - logs.pose_lag_s, 0.0)
    result.x_d = reference_at(logs.trajectory, t)
    result.metrics = compute_metrics(result, wall_s)
    if "temperature_note" in result.config_summary:
        result.metrics["temperature_note"] = result.config_summary["temperature_note"]
    if logs.contact:
        first = logs.first_contact
        result.metrics["first_contact"] = (
            None
            if first is None
            else {"t": first[0], "parts": list(first[1:3]), "force_N": first[3]}
        )
    return result


def release_reference(sd) -> None:
    """Drop a run's reference tables once it is read (:func:`read_run`), before its
    result's arrays are made (:meth:`~stewart_drake.run.reference.ReferenceSources.release`):
    the Diagram cannot run again."""
    if isinstance(sd.reference, ReferenceSources):
        sd.reference.release()


#: Samples :func:`reference_at` and :func:`feedforward_at` compute at once (their float64
#: intermediates, a stretch at a time).
RESULT_CHUNK = 20_000


def reference_at(trajectory: Reference, t: np.ndarray) -> np.ndarray:
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


def feedforward_at(sd, t: np.ndarray) -> np.ndarray:
    """(N, 6) float32 the feed-forward torques the reference asks for at times t (s), N m: the
    Diagram's feed-forward table, each row placed at the time it is meant to act (the sample's
    reference time plus the computation delay), linearly interpolated; of a live reference,
    its own record (``feedforward_at(t)``: :class:`~stewart_drake.live.follow.FollowReference`;
    one without, teleop's, keeps no logs)."""
    reference = sd.reference
    if not isinstance(reference, ReferenceSources):  # live: what it recorded, if it did
        return np.asarray(reference.feedforward_at(t), dtype=np.float32)
    t_act = reference.t_eval.values() + sd.plan.delay_periods * sd.plan.control_period_s
    table = reference.T_ff_table
    out = np.empty((len(t), table.shape[1]), dtype=np.float32)
    return interp_columns(t, t_act, table, out=out)


def loop_closures_from_states(sd, states: np.ndarray) -> np.ndarray:
    """(N,) max loop-closure error in m at each plant state (N, nq + nv), by the station's
    :class:`~stewart_drake.plant.closed_chain.LoopClosure` (held to the plant's kinematics at
    1e-12 m by a test)."""
    closure = sd.station.loop_closure
    nq = sd.plant.num_positions()
    return np.array([closure(s[:nq]).max() for s in states])


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
