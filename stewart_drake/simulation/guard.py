"""Guards of a closed-loop run: the reference is checked before, the state during, nothing lost.

Before a run, :func:`check_reference` samples x_d(t) at the control period and refuses a path
that leaves the workspace (:class:`~stewart_drake.errors.UnreachablePoseError`), a joint range
(:class:`~stewart_drake.errors.JointLimitError`) or comes too close to a singularity
(:class:`~stewart_drake.errors.SingularPoseError`), naming the first time and the leg / measure.

During a run, :class:`DivergenceGuard` is the Simulator's monitor (``Simulator.set_monitor``,
called after every step). Every ``check_period_s`` it checks that the plant state and the motor
torques are finite and that the loop-closure error and the tracking error are within
:class:`~.scenario.GuardConfig`'s bounds; between checks it costs one time comparison. (A NaN
torque does not reach the plant in between: Drake refuses a NaN actuation at the step that would
use it, and :func:`advance` reports that as a divergence.) On the first failure the Simulator stops, :func:`advance` saves the
logs up to then and the last full plant state to ``GuardConfig.divergence_dir`` (an ``.npz``,
written atomically) and raises :class:`~stewart_drake.errors.SimulationDivergedError` naming the
file. A run that ends normally therefore has finite logs: a NaN cannot reach a plot or the
metrics silently.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from pathlib import Path

import numpy as np
from pydrake.systems.framework import EventStatus

from ..errors import FeasibilityWarning, SimulationDivergedError, StewartError
from ..fileio import save_npz
from ..model import limits
from ..model.plant import loop_closure_errors
from .scenario import GuardConfig, dump_scenario

def check_reference(scenario, trajectory=None,
                    raise_refused: bool = True) -> limits.TrajectoryReport:
    """Refuse a reference the robot cannot follow, before anything is simulated.

    Samples x_d(t) on [0, duration_s] at the control period and checks finiteness, loop closure,
    motor travel, ball-joint cones, both singularity measures, the clearance between the robot's
    parts and the torque and speed each motor must give (``scenario.guard`` thresholds, the
    motors of ``scenario.motor_limits()``), with :func:`~.trajectories.validate`, on the robot
    that is simulated (its payload included).

    Args:
        scenario: the :class:`~.scenario.Scenario`.
        trajectory: the reference object (default: the one the scenario names).
        raise_refused: False reports every refusal in the report instead of raising the first
            (``stewart-drake check``).
    Returns:
        the :class:`~stewart_drake.model.limits.TrajectoryReport` (``summary()`` prints it).
    Raises:
        InvalidConfigError: a non-finite sample (pose, rate or acceleration), first time named,
            or a run longer than a bounded reference.
        UnreachablePoseError: first time, leg and ratio |L|/sqrt(M^2+N^2) > 1.
        JointLimitError: first time, leg and limit (motor_angle, crank_joint, platform_joint).
        SingularPoseError: first time with cond(J) > cond_threshold or 1/sigma_max(J) <
            min_sigma_min_inv.
        InterferenceError: first time two parts come closer than ``guard.min_clearance_m``.
        MotorLimitError: first time a motor needs more torque or speed than it may use, unless
            ``guard.allow_infeasible`` (then a :class:`~stewart_drake.errors.FeasibilityWarning`).
    """
    from ..model.clearance import clearance_model
    from .trajectories import validate

    trajectory = scenario.make_reference() if trajectory is None else trajectory
    geometry, guard = scenario.plant_geometry(), scenario.guard
    report = validate(trajectory, geometry, scenario.duration_s,
                      dt=scenario.control_period_s, cond_threshold=guard.cond_threshold,
                      min_sigma_min_inv=guard.min_sigma_min_inv, raise_refused=raise_refused,
                      clearance=clearance_model(geometry), min_clearance_m=guard.min_clearance_m,
                      motor_limits=scenario.motor_limits(),
                      allow_infeasible=guard.allow_infeasible)
    if raise_refused and not report.feasible:
        e = report.first_effort_violation
        unit = "N m" if e.quantity == "torque" else "rad/s"
        warnings.warn(FeasibilityWarning(
            f"running a reference the motors cannot follow (guard.allow_infeasible): motor "
            f"{e.motor} needs {e.required:.3g} {unit} of {e.quantity} at t = {e.t:.4g} s, over "
            f"the {e.limit:.3g} {unit} it may use; expect saturation"), stacklevel=2)
    return report


class DivergenceGuard:
    """Simulator monitor that stops a run leaving its safe envelope (see module docstring).

    Args:
        sd: the built :class:`~.diagram.StewartDiagram`.
        config: the bounds (default ``sd.scenario.guard``).
    Attributes:
        reason: why the run was stopped (None while it is fine).  t_failed: when, s.
        checks: how many closure/tracking checks ran (for tests and benchmarks).
        first_contact: with ``scenario.contact``, (t s, part_a, part_b, normal force N) of the
            first contact between two parts the checks saw, else None. Without contact, two
            parts that overlap stop the run instead (they would pass through each other).
    """

    def __init__(self, sd, config: GuardConfig | None = None):
        self.sd = sd
        self.config = config or sd.scenario.guard
        self.reason: str | None = None
        self.t_failed: float | None = None
        self.checks = 0
        self.first_contact: tuple | None = None
        self._next_check_t = 0.0
        self._last_t = -math.inf           # the monitor's last call (a reset time re-checks)
        self._contexts = None

    def attach(self, simulator) -> "DivergenceGuard":
        """Install as ``simulator``'s monitor (replacing any other); returns self."""
        self._bind(simulator.get_context())
        simulator.set_monitor(self)
        return self

    def _bind(self, root):
        sd = self.sd
        self._root_id = id(root)
        self._contexts = tuple(s.GetMyContextFromRoot(root) for s in (
            sd.plant, sd.controller, sd.station, sd.reference.x_d))
        self._T_port = sd.controller.GetOutputPort("T")
        self._pose_port = sd.station.GetOutputPort("platform_state")
        if sd.scenario.contact:
            inspector = sd.station.scene_graph.model_inspector()
            self._part_names = {}
            for index in sd.plant.GetBodyIndices(sd.handles.model_instance):
                body = sd.plant.get_body(index)
                for gid in sd.plant.GetCollisionGeometriesForBody(body):
                    self._part_names[gid] = (f"{body.name()}/"
                                             f"{inspector.GetName(gid).split('::')[-1]}")
        else:
            from ..model.clearance import clearance_model

            self._clearance = clearance_model(sd.scenario.plant_geometry())

    def __call__(self, root) -> EventStatus | None:
        """The monitor: None (go on) or ``EventStatus.Failed`` with :attr:`reason`.

        The Simulator calls it after every step (twice per millisecond: the plant's updates and
        the controller's); between checks it returns after one time comparison (the monitor is
        the hottest Python call of a run).
        """
        t = root.get_time()
        if self._last_t <= t < self._next_check_t:
            self._last_t = t
            return None
        self._last_t = t
        reason = self.check(root)
        if reason is None:
            return None
        self.reason, self.t_failed = reason, t
        # Failed(...) must name a System: the Diagram (a LeafSystem defined in Python crashes
        # pydrake 1.51 when its name is formatted into the Simulator's message).
        return EventStatus.Failed(self.sd.diagram, reason)

    def check(self, root) -> str | None:
        """Run every check now; the first failure's description, or None. The next check of the
        monitor is ``check_period_s`` later."""
        if self._contexts is None or id(root) != self._root_id:
            self._bind(root)
        plant_ctx, ctrl_ctx, station_ctx, ref_ctx = self._contexts
        t = root.get_time()
        self._next_check_t = t + self.config.check_period_s * (1 - 1e-6)
        self.checks += 1
        state = plant_ctx.get_discrete_state_vector().value()
        if not math.isfinite(state.sum()):
            k = int(np.argmax(~np.isfinite(state)))
            return (f"the plant state is not finite (entry {k} of {state.size} = {state[k]}); "
                    f"the loop lost its stability")
        T = self._T_port.Eval(ctrl_ctx)
        if not math.isfinite(T.sum()):
            return (f"the motor torques are not finite, T = {np.array2string(T, precision=4)} "
                    f"N m: the controller received or produced NaN")
        cfg = self.config
        if cfg.max_closure_error_m is not None:
            closure = loop_closure_errors(self.sd.plant, plant_ctx, self.sd.handles)
            leg = int(np.argmax(closure))
            if not closure[leg] <= cfg.max_closure_error_m:
                return (f"loop-closure error {closure[leg]:.3g} m at rod {leg} exceeds "
                        f"GuardConfig.max_closure_error_m = {cfg.max_closure_error_m:g} m")
        if cfg.max_tracking_error is not None:
            x = self._pose_port.Eval(station_ctx)
            x_d = self.sd.reference.x_d.get_output_port().Eval(ref_ctx)
            e = np.abs(x[:6] - x_d[:6])
            for part, bound, unit in ((slice(0, 3), cfg.max_tracking_error[0], "rad"),
                                      (slice(3, 6), cfg.max_tracking_error[1], "m")):
                k = int(np.argmax(e[part])) + part.start
                if not e[k] <= bound:
                    axis = ("phi", "theta", "psi", "X", "Y", "Z")[k]
                    return (f"tracking error |{axis} - {axis}_d| = {e[k]:.3g} {unit} exceeds "
                            f"GuardConfig.max_tracking_error = {bound:g} {unit}")
        return self._check_parts(t, plant_ctx, station_ctx)

    def _check_parts(self, t: float, plant_ctx, station_ctx) -> str | None:
        """With contact: note the first contact between two parts. Without: a failure when two
        parts overlap (nothing in the plant keeps them apart)."""
        if self.sd.scenario.contact:
            if self.first_contact is None:
                results = self.sd.plant.get_contact_results_output_port().Eval(plant_ctx)
                if results.num_point_pair_contacts():
                    info = max((results.point_pair_contact_info(i)
                                for i in range(results.num_point_pair_contacts())),
                               key=lambda c: np.linalg.norm(c.contact_force()))
                    pair = info.point_pair()
                    names = sorted(self._part_names.get(g, "?") for g in (pair.id_A, pair.id_B))
                    self.first_contact = (t, *names, float(np.linalg.norm(info.contact_force())))
            return None
        x = self._pose_port.Eval(station_ctx)[:6]
        try:
            overlaps = self._clearance.contacts(x, max_distance=0.0)
        except StewartError:             # a pose no leg closes at: the closure check's to report
            return None
        if overlaps and overlaps[0].distance < 0:
            return (f"{overlaps[0]}: parts pass through each other in a plant without contact; "
                    f"simulate the collision with `contact: true`")
        return None

    def save(self, root, reason: str) -> Path:
        """Write the logs up to now and the last plant state to ``divergence_dir``.

        The ``.npz`` holds: t (N,), x (N, 12) true pose and rate, T (N, 6) applied torques
        (after the torque limit), the controller's other logs (status, integral) and rho when
        tuned, state (N, n) logged plant states, x_d (N, 18) the reference at t (when it can be
        evaluated), t_last (s) and state_last (n,) the plant state when the run stopped, T_last
        (6,) the last command and T_applied_last (6,) what the motors applied, reason (str) and
        scenario (the whole scenario as YAML: robot, payload, torque limit, feed-forward,
        controller, noise...).
        Returns:
            the path written.
        """
        sd = self.sd
        logs = {name: logger.FindLog(root) for name, logger in sd.loggers.items()}
        t = logs["state"].sample_times().copy()
        arrays = {"t": t, "t_last": np.float64(root.get_time()),
                  "state_last": sd.plant.GetMyContextFromRoot(root)
                  .get_discrete_state_vector().CopyToVector(),
                  "T_last": sd.controller.GetOutputPort("T").Eval(
                      sd.controller.GetMyContextFromRoot(root)).copy(),
                  "T_applied_last": sd.station.GetOutputPort("motor_torque_applied").Eval(
                      sd.station.GetMyContextFromRoot(root)).copy(),
                  "reason": np.str_(reason),
                  "scenario": np.str_(dump_scenario(sd.scenario))}
        for name, log in logs.items():
            arrays[name] = log.data().T.copy()
        try:
            arrays["x"] = sd.sensor.poses_from_states(arrays["state"])   # true pose, as metrics
        except Exception:               # noqa: BLE001 - a NaN quaternion must not lose the file
            arrays["x"] = np.full((len(t), 12), np.nan)
        try:
            arrays["x_d"] = np.concatenate(sd.trajectory.evaluate(t), axis=1)
        except Exception:               # noqa: BLE001 - the reference itself may be the fault
            pass
        name = getattr(sd.trajectory, "name", "custom")
        stamp = time.strftime("%Y%m%d-%H%M%S")
        path = Path(self.config.divergence_dir) / (
            f"diverged_{name}_t{root.get_time():.4f}s_{stamp}_{os.getpid()}"
            f"_{time.perf_counter_ns() % 1_000_000:06d}.npz")
        return save_npz(path, arrays)


def advance(sd, simulator, step) -> None:
    """Call ``step()`` (which advances ``simulator``); on a divergence save and raise.

    After ``step()`` the guard checks once more (the monitor checks every ``check_period_s``, so
    a fault in the last period would otherwise end a run). Drake refuses a NaN actuation itself
    at the plant step that would use it; such a failure is diagnosed by the guard's checks (the
    motor torques are not finite) and reported as a divergence.

    Args:
        sd: the Diagram; ``sd.guard`` is its :class:`DivergenceGuard` (None: no guard).
        simulator: the Simulator ``step`` advances.
        step: a callable that advances the simulator (e.g. ``AdvanceTo`` in chunks).
    Raises:
        SimulationDivergedError: the guard stopped the run, or a system raised one (the
            features of a diverged signal); the logs up to then are saved and named (or, when
            ``divergence_dir`` cannot be written, the message says why they are not).
        RuntimeError: any other failure inside Drake; the logs are saved all the same and the
            error carries a note with the path.
    """
    guard = getattr(sd, "guard", None)
    try:
        step()
    except SimulationDivergedError as err:
        if guard is None or err.path:
            raise
        path, unsaved = _save(guard, simulator.get_context(), str(err))
        raise SimulationDivergedError(err.message + unsaved, err.t, path) from err
    except RuntimeError as err:
        if guard is None:
            raise
        root = simulator.get_context()
        if guard.reason is None:
            reason = guard.check(root)             # a diverged signal Drake refused to use?
            if reason is None:
                path, unsaved = _save(guard, root, f"{type(err).__name__}: {err}")
                err.add_note(f"stewart-drake: the logs up to t = {root.get_time():.4g} s are "
                             f"saved in {path}" if path else f"stewart-drake:{unsaved}")
                raise
            guard.reason, guard.t_failed = f"{reason} (Drake: {err})", root.get_time()
        path, unsaved = _save(guard, root, guard.reason)
        raise SimulationDivergedError(guard.reason + unsaved, guard.t_failed, path) from None
    if guard is not None:
        root = simulator.get_context()
        reason = guard.check(root)
        if reason is not None:
            guard.reason, guard.t_failed = reason, root.get_time()
            path, unsaved = _save(guard, root, reason)
            raise SimulationDivergedError(reason + unsaved, guard.t_failed, path)


def _save(guard: DivergenceGuard, root, reason: str) -> tuple[str | None, str]:
    """(path, "") of the saved logs, or (None, " (the logs could not be saved ...: why)"): a
    divergence folder that cannot be written (a file in its place, a full disk) must not turn
    the divergence into an OSError."""
    try:
        return str(guard.save(root, reason)), ""
    except OSError as err:
        return None, (f" (the logs could not be saved in {guard.config.divergence_dir}: "
                      f"{err.strerror or err}; set guard.divergence_dir to a writable folder)")
