"""Guards of a closed-loop run: the reference is checked before, the state during, nothing lost.

Before a run, :func:`check_reference` samples x_d(t) at the control period and refuses a path
that leaves the workspace (:class:`~stewart_drake.errors.UnreachablePoseError`), a joint range
(:class:`~stewart_drake.errors.JointLimitError`) or comes too close to a singularity
(:class:`~stewart_drake.errors.SingularPoseError`), naming the first time and the leg / measure.

During a run, :class:`DivergenceGuard` is the Simulator's monitor (``Simulator.set_monitor``,
called after every step). Every step it checks that the plant state and the motor torques are
finite; every ``check_period_s`` that the loop-closure error and the tracking error are within
:class:`GuardConfig`'s bounds. On the first failure the Simulator stops, :func:`advance` saves the
logs up to then and the last full plant state to ``GuardConfig.divergence_dir`` (an ``.npz``,
written atomically) and raises :class:`~stewart_drake.errors.SimulationDivergedError` naming the
file. A run that ends normally therefore has finite logs: a NaN cannot reach a plot or the
metrics silently.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.systems.framework import EventStatus

from ..checks import as_number
from ..errors import InvalidConfigError, SimulationDivergedError
from ..fileio import save_npz
from ..model import limits

#: Default folder of the files saved when a run diverges (relative to the working directory).
DEFAULT_DIVERGENCE_DIR = Path("results") / "diverged"


@dataclass(frozen=True)
class GuardConfig:
    """Bounds of a guarded run; SI units. A field of :class:`~stewart_drake.diagram.StewartConfig`.

    Attributes:
        max_closure_error_m: largest distance between a rod's top end and its platform joint, m
            (the paper run stays below 1e-6 m; SAP's constraint compliance is micrometres).
            None disables the check.
        max_tracking_error: (rad, m): largest |x - x_d| over the three angles and over the three
            positions. Loose by default (0.2 rad, 0.05 m): it catches a lost platform, not a
            poorly tuned one (the paper run tracks to micrometres). None disables the check.
        check_period_s: closure and tracking are checked this often, s (a whole multiple of the
            plant step; finiteness is checked every step).
        divergence_dir: folder of the saved ``.npz`` when a run diverges.
        cond_threshold: largest cond(J) along the reference (limits.DEFAULT_COND_THRESHOLD).
        min_sigma_min_inv: smallest 1/sigma_max(J) along the reference, (rad or m) per rad
            (limits.DEFAULT_MIN_SIGMA_MIN_INV).
    Raises:
        InvalidConfigError: a bound that is not a finite positive number (or None).
    """

    max_closure_error_m: float | None = 1e-3
    max_tracking_error: tuple | None = (0.2, 0.05)
    check_period_s: float = 0.01
    divergence_dir: str | Path = DEFAULT_DIVERGENCE_DIR
    cond_threshold: float = limits.DEFAULT_COND_THRESHOLD
    min_sigma_min_inv: float = limits.DEFAULT_MIN_SIGMA_MIN_INV

    def __post_init__(self):
        if self.max_closure_error_m is not None:
            as_number("guard.max_closure_error_m", self.max_closure_error_m, 0.0, lo_open=True)
        if self.max_tracking_error is not None:
            bounds = self.max_tracking_error
            if isinstance(bounds, (str, bytes)) or np.ndim(bounds) != 1 or len(bounds) != 2:
                raise InvalidConfigError(f"guard.max_tracking_error must be (rad, m), got "
                                         f"{bounds!r}")
            object.__setattr__(self, "max_tracking_error", tuple(
                as_number(f"guard.max_tracking_error[{k}]", v, 0.0, lo_open=True)
                for k, v in enumerate(bounds)))
        as_number("guard.check_period_s", self.check_period_s, 0.0, lo_open=True)
        as_number("guard.cond_threshold", self.cond_threshold, 1.0, lo_open=True)
        as_number("guard.min_sigma_min_inv", self.min_sigma_min_inv, 0.0)
        if not isinstance(self.divergence_dir, (str, os.PathLike)) or not str(self.divergence_dir):
            raise InvalidConfigError(f"guard.divergence_dir must be a folder path, got "
                                     f"{self.divergence_dir!r}")


def check_reference(config: "StewartConfig") -> limits.TrajectoryReport:
    """Refuse a reference the robot cannot follow, before anything is simulated.

    Samples x_d(t) on [0, duration_s] at the control period and checks finiteness, loop closure,
    motor travel, ball-joint cones and both singularity measures (``config.guard`` thresholds).

    Returns:
        the :class:`~stewart_drake.limits.TrajectoryReport` (``summary()`` prints it).
    Raises:
        InvalidConfigError: a non-finite sample (pose, rate or acceleration), first time named.
        UnreachablePoseError: first time, leg and ratio |L|/sqrt(M^2+N^2) > 1.
        JointLimitError: first time, leg and limit (motor_angle, crank_joint, platform_joint).
        SingularPoseError: first time with cond(J) > cond_threshold or 1/sigma_max(J) <
            min_sigma_min_inv.
    """
    from .trajectories import validate

    return validate(config.resolved_trajectory(), config.geometry, config.duration_s,
                    dt=config.control_period_s, cond_threshold=config.guard.cond_threshold,
                    min_sigma_min_inv=config.guard.min_sigma_min_inv)


class DivergenceGuard:
    """Simulator monitor that stops a run leaving its safe envelope (see module docstring).

    Args:
        sd: the built :class:`~stewart_drake.diagram.StewartDiagram`.
        config: the bounds (default ``sd.config.guard``).
    Attributes:
        reason: why the run was stopped (None while it is fine).  t_failed: when, s.
        checks: how many closure/tracking checks ran (for tests and benchmarks).
    """

    def __init__(self, sd: "StewartDiagram", config: GuardConfig | None = None):
        self.sd = sd
        self.config = config or sd.config.guard
        self.reason: str | None = None
        self.t_failed: float | None = None
        self.checks = 0
        self._next_check_t = 0.0
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
            sd.plant, sd.controller, sd.sensor, sd.reference.x_d))
        self._T_port = sd.controller.GetOutputPort("T")
        self._h = sd.config.plant_time_step_s

    def __call__(self, root) -> EventStatus | None:
        """The monitor: None (go on) or ``EventStatus.Failed`` with :attr:`reason`."""
        reason = self.check(root)
        if reason is None:
            return None
        self.reason, self.t_failed = reason, root.get_time()
        # Failed(...) must name a System: the Diagram (a LeafSystem defined in Python crashes
        # pydrake 1.51 when its name is formatted into the Simulator's message).
        return EventStatus.Failed(self.sd.diagram, reason)

    def check(self, root) -> str | None:
        """Run the checks due at ``root``'s time; the first failure's description, or None."""
        if self._contexts is None or id(root) != self._root_id:
            self._bind(root)
        plant_ctx, ctrl_ctx, sensor_ctx, ref_ctx = self._contexts
        t = root.get_time()
        # The monitor runs after every event time: the plant's (k h) and the controller's
        # (k h + h/2). The plant state changes only at the first, and a torque the controller
        # writes at the second is used from the next plant step on, which this check precedes:
        # checking at plant steps alone sees every fault as early, at half the cost.
        steps = t / self._h
        if abs(steps - round(steps)) > 1e-6 and t < self._next_check_t:
            return None
        state = plant_ctx.get_discrete_state_vector().value()
        if not math.isfinite(state.sum()):
            k = int(np.argmax(~np.isfinite(state)))
            return (f"the plant state is not finite (entry {k} of {state.size} = {state[k]}); "
                    f"the loop lost its stability")
        T = self._T_port.Eval(ctrl_ctx)
        if not math.isfinite(T.sum()):
            return (f"the motor torques are not finite, T = {np.array2string(T, precision=4)} "
                    f"N m: the controller received or produced NaN")
        if t < self._next_check_t:
            return None
        self._next_check_t = t + self.config.check_period_s * (1 - 1e-6)
        self.checks += 1
        cfg = self.config
        if cfg.max_closure_error_m is not None:
            from ..model.plant import loop_closure_errors

            closure = loop_closure_errors(self.sd.plant, plant_ctx, self.sd.handles)
            leg = int(np.argmax(closure))
            if not closure[leg] <= cfg.max_closure_error_m:
                return (f"loop-closure error {closure[leg]:.3g} m at rod {leg} exceeds "
                        f"GuardConfig.max_closure_error_m = {cfg.max_closure_error_m:g} m")
        if cfg.max_tracking_error is not None:
            x = self.sd.sensor.get_output_port().Eval(sensor_ctx)
            x_d = self.sd.reference.x_d.get_output_port().Eval(ref_ctx)
            e = np.abs(x[:6] - x_d[:6])
            for part, bound, unit in ((slice(0, 3), cfg.max_tracking_error[0], "rad"),
                                      (slice(3, 6), cfg.max_tracking_error[1], "m")):
                k = int(np.argmax(e[part])) + part.start
                if not e[k] <= bound:
                    axis = ("phi", "theta", "psi", "X", "Y", "Z")[k]
                    return (f"tracking error |{axis} - {axis}_d| = {e[k]:.3g} {unit} exceeds "
                            f"GuardConfig.max_tracking_error = {bound:g} {unit}")
        return None

    def save(self, root, reason: str) -> Path:
        """Write the logs up to now and the last plant state to ``divergence_dir``.

        The ``.npz`` holds: t (N,), x (N, 12), T (N, 6), status (N, 5), state (N, n) logged
        plant states, x_d (N, 18) the reference at t (when it can be evaluated), t_last (s) and
        state_last (n,) the plant state when the run stopped, T_last (6,), reason (str) and
        config (JSON).
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
                  "reason": np.str_(reason),
                  "config": np.str_(json.dumps(_config_summary(sd.config)))}
        for name, log in logs.items():
            arrays[name] = log.data().T.copy()
        try:
            arrays["x"] = sd.sensor.poses_from_states(arrays["state"])   # true pose, as metrics
        except Exception:               # noqa: BLE001 - a NaN quaternion must not lose the file
            arrays["x"] = np.full((len(t), 12), np.nan)
        try:
            arrays["x_d"] = np.concatenate(sd.config.resolved_trajectory().evaluate(t), axis=1)
        except Exception:               # noqa: BLE001 - the reference itself may be the fault
            pass
        name = getattr(sd.config.resolved_trajectory(), "name", "custom")
        stamp = time.strftime("%Y%m%d-%H%M%S")
        path = Path(self.config.divergence_dir) / (
            f"diverged_{name}_t{root.get_time():.4f}s_{stamp}_{os.getpid()}"
            f"_{time.perf_counter_ns() % 1_000_000:06d}.npz")
        return save_npz(path, arrays)


def _config_summary(config) -> dict:
    return {"trajectory": getattr(config.resolved_trajectory(), "name", "custom"),
            "duration_s": config.duration_s, "omega_Q": config.omega_Q,
            "omega_R": config.omega_R, "tuner": config.tuner,
            "guard": {"max_closure_error_m": config.guard.max_closure_error_m,
                      "max_tracking_error": config.guard.max_tracking_error,
                      "check_period_s": config.guard.check_period_s}}


def advance(sd: "StewartDiagram", simulator, step) -> None:
    """Call ``step()`` (which advances ``simulator``); on a divergence save and raise.

    Args:
        sd: the Diagram; ``sd.guard`` is its :class:`DivergenceGuard` (None: no guard).
        simulator: the Simulator ``step`` advances.
        step: a callable that advances the simulator (e.g. ``AdvanceTo`` in chunks).
    Raises:
        SimulationDivergedError: the guard stopped the run, or a system raised one (the
            features of a diverged signal); the logs up to then are saved and named.
        RuntimeError: any other failure inside Drake; the logs are saved all the same and the
            error carries a note with the path.
    """
    guard = getattr(sd, "guard", None)
    try:
        step()
    except SimulationDivergedError as err:
        if guard is None or err.path:
            raise
        path = guard.save(simulator.get_context(), str(err))
        raise SimulationDivergedError(err.message, err.t, str(path)) from err
    except RuntimeError as err:
        if guard is None:
            raise
        root = simulator.get_context()
        if guard.reason is None:
            path = guard.save(root, f"{type(err).__name__}: {err}")
            err.add_note(f"stewart-drake: the logs up to t = {root.get_time():.4g} s are "
                         f"saved in {path}")
            raise
        path = guard.save(root, guard.reason)
        raise SimulationDivergedError(guard.reason, guard.t_failed, str(path)) from None
