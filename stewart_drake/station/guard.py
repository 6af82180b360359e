"""The guard of a closed-loop run: the state is checked as it runs, nothing is lost.

Before a run, the plan's check refuses a reference the robot cannot follow
(:func:`~stewart_drake.run.plan.check_reference`, with :class:`GuardConfig`'s thresholds),
naming the first time and the leg, measure, parts or motor.

During a run, :class:`DivergenceGuard`, a system of the Diagram, checks every
``check_period_s`` (a periodic publish event: one Python call per check, none in between) that
the plant state and the motor torques are finite and that the loop-closure error and the
tracking error are within :class:`GuardConfig`'s bounds. (A NaN torque does not reach
the plant in between: Drake refuses a NaN actuation at the step that would use it, and
:func:`advance` reports that as a divergence.) On the first failure the check raises
:class:`~.errors.SimulationDivergedError`, which stops the Simulator;
:func:`advance` saves the logs up to then and the last full plant state to
``GuardConfig.divergence_dir`` (an ``.npz``, written atomically) and raises it again naming the
file. A run that ends normally therefore has finite logs: a NaN cannot reach a plot or the
metrics silently.
"""

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_number
from ..base.errors import InvalidConfigError, SimulationDivergedError
from ..base.fileio import save_npz
from ..plant.backlash import crank_coordinates
from ..references.motion import Reference
from ..robot.kinematics import AXIS_NAMES
from ..robot.limits import (
    DEFAULT_CLEARANCE_RESOLUTION_M,
    DEFAULT_COND_THRESHOLD,
    DEFAULT_EFFORT_MARGIN,
    DEFAULT_MIN_CLEARANCE_M,
    DEFAULT_MIN_SIGMA_MIN_INV,
)


# Drake's YAML loader reads GuardConfig's field annotations: this module must not use
# ``from __future__ import annotations``.
@dataclass
class GuardConfig:
    """Bounds of a guarded run (:mod:`~stewart_drake.station.guard`); SI units.

    Attributes:
        max_closure_error_m: largest distance between a rod's top end and its platform joint, m
            (the paper run stays below 1e-6 m); None disables the check.
        max_tracking_error: [rad, m]: largest |x - x_d| over the three angles and over the three
            positions. Loose by default (0.2 rad, 0.05 m): it catches a lost platform, not a
            poorly tuned one. None disables the check.
        check_period_s: the state's and torques' finiteness, closure and tracking are checked
            this often, s (a whole multiple of the plant step; Drake itself refuses a NaN
            actuation at the plant step that would use it).
        divergence_dir: folder of the saved ``.npz`` when a run diverges.
        cond_threshold: largest cond(J) along the reference (limits.DEFAULT_COND_THRESHOLD).
        min_sigma_min_inv: smallest 1/sigma_max(J) along the reference, (rad or m) per rad.
        min_clearance_m: smallest distance two parts of the robot may come to along the
            reference, m (collision geometry, :mod:`~stewart_drake.plant.clearance`).
        effort_margin: the share of the motors' peak torque and no-load speed the reference may
            need (inverse dynamics with the reflected inertia and friction), in (0, 1]; the
            rest is the feedback's.
        allow_infeasible: run a reference that needs more than that anyway, with a warning (the
            motors saturate), instead of refusing it.
    Raises:
        InvalidConfigError: a bound that is not a finite positive number (or None), at
            construction and in :meth:`validate`.
    """

    max_closure_error_m: float | None = 1e-3
    max_tracking_error: list[float] | None = field(default_factory=lambda: [0.2, 0.05])
    check_period_s: float = 0.01
    divergence_dir: str = "results/diverged"
    cond_threshold: float = DEFAULT_COND_THRESHOLD
    min_sigma_min_inv: float = DEFAULT_MIN_SIGMA_MIN_INV
    min_clearance_m: float = DEFAULT_MIN_CLEARANCE_M
    effort_margin: float = DEFAULT_EFFORT_MARGIN
    allow_infeasible: bool = False

    def __post_init__(self):
        self.validate()

    def validate(self, prefix: str = "guard.") -> None:
        """Check every field; raises InvalidConfigError naming it."""
        if self.max_closure_error_m is not None:
            as_number(f"{prefix}max_closure_error_m", self.max_closure_error_m, 0.0, lo_open=True)
        if self.max_tracking_error is not None:
            bounds = self.max_tracking_error
            if isinstance(bounds, (str, bytes)) or np.ndim(bounds) != 1 or len(bounds) != 2:
                raise InvalidConfigError(
                    f"{prefix}max_tracking_error must be [rad, m], got {bounds!r}"
                )
            self.max_tracking_error = [
                as_number(f"{prefix}max_tracking_error[{k}]", v, 0.0, lo_open=True)
                for k, v in enumerate(bounds)
            ]
        as_number(f"{prefix}check_period_s", self.check_period_s, 0.0, lo_open=True)
        as_number(f"{prefix}cond_threshold", self.cond_threshold, 1.0, lo_open=True)
        as_number(f"{prefix}min_sigma_min_inv", self.min_sigma_min_inv, 0.0)
        as_number(f"{prefix}min_clearance_m", self.min_clearance_m, 0.0, 0.05)
        as_number(f"{prefix}effort_margin", self.effort_margin, 0.0, 1.0, lo_open=True)
        if not isinstance(self.allow_infeasible, bool):
            raise InvalidConfigError(
                f"{prefix}allow_infeasible must be true or false, got {self.allow_infeasible!r}"
            )
        if isinstance(self.divergence_dir, Path):
            self.divergence_dir = str(self.divergence_dir)
        if not isinstance(self.divergence_dir, str) or not self.divergence_dir:
            raise InvalidConfigError(
                f"{prefix}divergence_dir must be a folder path, got {self.divergence_dir!r}"
            )


#: Without contact, the guard asks SceneGraph whether parts overlap at every this many checks,
#: and at every check where a part may have strayed far enough (:meth:`DivergenceGuard.check`).
INTERFERENCE_EVERY = 10


class DivergenceGuard(LeafSystem):
    """The check of a running closed loop (module docstring), as a system of the Diagram.

    Input ports: ``plant_state`` (nq + nv,) the MultibodyPlant's state; ``T`` (6,) the
    controller's torque command, N m; ``x_d`` (18,) the reference the controller reads; with
    ``contact``, ``contact_results`` (the plant's ``ContactResults``).
    Every ``config.check_period_s`` (first at t = 0) a publish event runs :meth:`check` and
    raises :class:`~.errors.SimulationDivergedError` with its reason. Without
    contact, two parts that overlap are a failure (nothing in the plant keeps them apart; the
    SceneGraph check runs when a part may have strayed far enough from the validated
    reference, and at every tenth check: :data:`INTERFERENCE_EVERY`); with
    contact, a discrete update at the same period keeps the first contact in the guard's state
    (:meth:`first_contact`).

    Args:
        station: the :class:`~.station.StewartStation` (its plant, handles and pose sensor).
        plan: the run's :class:`~stewart_drake.run.plan.RunPlan`: its scenario's ``guard`` (the
            bounds) and ``contact`` (whether the plant simulates contact between the robot's
            parts), and the robot that is simulated (``plant_geometry``), for the clearance
            check.
    """

    def __init__(self, station, plan):
        super().__init__()
        config, geometry = plan.scenario.guard, plan.plant_geometry
        self.config = config
        self._plant, self._handles, self._sensor = station.plant, station.handles, station.sensor
        plant = station.plant
        self._state = self.DeclareVectorInputPort(
            "plant_state", plant.num_positions() + plant.num_velocities()
        )
        self._T = self.DeclareVectorInputPort("T", 6)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        # The loop closure from the positions alone (no context of the plant, no kinematics);
        # none to measure where the station assembles its state at a pose (the robot's).
        closed = getattr(station, "loops_closed_by_construction", False)
        self._closure = None if closed else station.loop_closure
        self.DeclarePeriodicPublishEvent(
            period_sec=self.config.check_period_s, offset_sec=0.0, publish=self._Check
        )
        self.contact = plan.scenario.contact
        if self.contact:
            # The first contact the checks see, kept in the guard's state: [seen (0 or 1), t s,
            # normal force N, index of part a, index of part b] (indices into part_names).
            self._contact_results = self.DeclareAbstractInputPort(
                "contact_results", AbstractValue.Make(ContactResults())
            )
            self._first_contact = self.DeclareDiscreteState(5)
            self.DeclarePeriodicDiscreteUpdateEvent(
                self.config.check_period_s, 0.0, self._NoteContact
            )
            inspector = station.scene_graph.model_inspector()
            ids = [
                gid
                for index in plant.GetBodyIndices(station.handles.model_instance)
                for gid in plant.GetCollisionGeometriesForBody(plant.get_body(index))
            ]
            self.part_names = tuple(
                f"{plant.GetBodyFromFrameId(inspector.GetFrameId(gid)).name()}/"
                f"{inspector.GetName(gid).split('::')[-1]}"
                for gid in ids
            )
            # Keyed by the ids' integer values: a pydrake GeometryId from the plant keeps the
            # plant (and the Diagram around it) alive, a reference the garbage collector
            # cannot see through.
            self._part_index = {gid.get_value(): k for k, gid in enumerate(ids)}
        else:
            from ..control.lqi.step import ik_compiled
            from ..plant.clearance import clearance_model
            from ..robot.single_pose import leg_constants

            self._clearance = clearance_model(geometry)
            self._legs = np.array(leg_constants(geometry))
            self._legs.setflags(write=False)  # as the LQI's step compiled the IK for
            self._ik = ik_compiled
            self._ik(self._legs, np.zeros(6))  # compiled (or loaded) now, not in a check
            self._crank_m = float(np.max(geometry.crank_lengths))  # the longest crank
            # Each crank's angle in q: its motor joint's, plus its gear play's if it has one.
            motor_q = crank_coordinates(station.handles)[0]
            self._motor_q = np.array([ks[0] for ks in motor_q], dtype=np.int64)
            self._play_q = np.array([ks[1] for ks in motor_q if len(ks) > 1], dtype=np.int64)
            # The reference keeps guard.min_clearance_m between the parts (the run's check,
            # sampled within DEFAULT_CLEARANCE_RESOLUTION_M); two parts that each stray less
            # than half of what is left from where the reference puts them cannot overlap.
            self._stray_m = 0.5 * (config.min_clearance_m - DEFAULT_CLEARANCE_RESOLUTION_M)
            # Where the check measured the reference's own clearance, what it keeps there.
            profile = getattr(plan.report, "clearance_profile", ())
            self._profile = profile if len(profile) == 3 and len(profile[0]) > 1 else None

    def _Check(self, context):
        reason = self.check(context)
        if reason is not None:
            raise SimulationDivergedError(reason, t=context.get_time())

    def check_root(self, root) -> str | None:
        """:meth:`check` in the Diagram's context ``root``."""
        return self.check(self.GetMyContextFromRoot(root))

    def check(self, context) -> str | None:
        """Run every check on the guard's inputs; the first failure's description, or None."""
        state = np.asarray(self._state.Eval(context))
        if not math.isfinite(state.sum()):
            k = int(np.argmax(~np.isfinite(state)))
            return (
                f"the plant state is not finite (entry {k} of {state.size} = {state[k]}); "
                f"the loop lost its stability"
            )
        T = np.asarray(self._T.Eval(context))
        if not math.isfinite(T.sum()):
            return (
                f"the motor torques are not finite, T = {np.array2string(T, precision=4)} "
                f"N m: the controller received or produced NaN"
            )
        cfg, plant = self.config, self._plant
        if cfg.max_closure_error_m is not None and self._closure is not None:
            closure = self._closure(state[: plant.num_positions()])
            leg = int(np.argmax(closure))
            if not closure[leg] <= cfg.max_closure_error_m:
                return (
                    f"loop-closure error {closure[leg]:.3g} m at rod {leg} exceeds "
                    f"GuardConfig.max_closure_error_m = {cfg.max_closure_error_m:g} m"
                )
        pose = self._sensor.pose_from_state(state)[:6]
        x_d = np.asarray(self._x_d.Eval(context))[:6]
        if cfg.max_tracking_error is not None:
            e = np.abs(pose - x_d)
            for part, bound, unit in (
                (slice(0, 3), cfg.max_tracking_error[0], "rad"),
                (slice(3, 6), cfg.max_tracking_error[1], "m"),
            ):
                k = int(np.argmax(e[part])) + part.start
                if not e[k] <= bound:
                    axis = AXIS_NAMES[k]
                    return (
                        f"tracking error |{axis} - {axis}_d| = {e[k]:.3g} {unit} exceeds "
                        f"GuardConfig.max_tracking_error = {bound:g} {unit}"
                    )
        if self.contact or not self._may_overlap(context, state, pose, x_d):
            return None
        # Without contact nothing in the plant keeps two parts apart: overlapping is a failure.
        # Rods as distance constraints or gear play (another layout of q): the clearance
        # model's plant (rods as bodies) posed at the measured pose; the loops are closed, so
        # its IK gives the cranks' angles.
        q = (
            state[: plant.num_positions()]
            if self._handles.rod_indices and not self._handles.play_indices
            else self._clearance.positions(pose)
        )
        overlaps = self._clearance.overlaps(q)
        if overlaps:
            return (
                f"{overlaps[0]}: parts pass through each other in a plant without contact; "
                f"simulate the collision with `contact: true`"
            )
        return None

    def stray_allowed(self, t: float) -> float:
        """How far, m, every part may stray from where the reference puts it at time ``t``
        (s) without two of them overlapping: half the clearance the reference keeps there less
        the check's resolution. Where the run's check measured the reference's clearance (the
        plan's report, ``clearance_profile``), the smaller of the two measures about ``t``
        (between them the parts are at least that less the resolution apart); elsewhere, and
        never less than, the clearance every reference keeps (``guard.min_clearance_m``)."""
        if self._profile is None:
            return self._stray_m
        t_p, c_p, resolution = self._profile
        j = int(np.searchsorted(t_p, t, side="left"))
        if j >= len(t_p) or (j == 0 and t < t_p[0]):
            return self._stray_m  # outside what was checked
        c = c_p[j] if t == t_p[j] else min(c_p[j - 1], c_p[j])
        allowed = 0.5 * (c - resolution)
        return allowed if allowed > self._stray_m else self._stray_m  # NaN: the floor

    def _may_overlap(self, context, state, pose, x_d) -> bool:
        """Whether two parts may overlap, so that the SceneGraph check is worth its cost: at
        every tenth check, and whenever a part may have strayed from where the reference puts it
        by more than :meth:`stray_allowed`. A crank's points stray at most (a + 1 cm) |theta -
        theta_d| (IK of the reference), the platform's |p - p_d| + 0.2 m x 2 |rpy - rpy_d| (its
        parts lie within 0.15 m of E; |E(rpy)| < 2 in the workspace), a rod's the more of its two
        ends (it is rigid)."""
        checks = round(context.get_time() / self.config.check_period_s)
        if checks % INTERFERENCE_EVERY == 0:
            return True
        theta = state[self._motor_q]
        if self._play_q.size:
            theta = theta + state[self._play_q]
        crank = np.abs(theta - np.asarray(self._ik(self._legs, x_d))).max()
        platform = np.abs(pose[3:] - x_d[3:]).max() + 0.4 * np.abs(pose[:3] - x_d[:3]).max()
        stray = max((self._crank_m + 0.01) * crank, float(platform))
        return not stray < self.stray_allowed(context.get_time())  # NaN included

    def _NoteContact(self, context, discrete_state):
        """With contact: keep the first contact between two parts (the strongest one then)."""
        if context.get_discrete_state_vector().GetAtIndex(0):
            return
        results = self._contact_results.Eval(context)
        if not results.num_point_pair_contacts():
            return
        info = max(
            (results.point_pair_contact_info(i) for i in range(results.num_point_pair_contacts())),
            key=lambda c: np.linalg.norm(c.contact_force()),
        )
        pair = info.point_pair()
        a, b = sorted(self._part_index.get(g.get_value(), -1) for g in (pair.id_A, pair.id_B))
        discrete_state.set_value(
            0, [1.0, context.get_time(), float(np.linalg.norm(info.contact_force())), a, b]
        )

    def first_contact(self, root) -> tuple | None:
        """(t s, part_a, part_b, normal force N) of the first contact between two parts the
        checks saw in the Diagram's context ``root``, or None (and None without contact)."""
        if not self.contact:
            return None
        seen, t, force, a, b = self.GetMyContextFromRoot(root).get_discrete_state_vector().value()
        if not seen:
            return None
        return (float(t), self.part_names[int(a)], self.part_names[int(b)], float(force))


def add_divergence_guard(builder, station, T, x_d, plan) -> DivergenceGuard:
    """The :class:`DivergenceGuard` of the run of ``plan`` (a
    :class:`~stewart_drake.run.plan.RunPlan`), in its Diagram (``builder``), on the station's
    plant state, the controller's torque command ``T`` (an output port, (6,) N m), the reference
    ``x_d`` (an output port, (18,)) and, with contact, the station's contact results."""
    contact = plan.scenario.contact
    guard = builder.AddNamedSystem("guard", DivergenceGuard(station, plan))
    builder.Connect(station.GetOutputPort("plant_state"), guard.GetInputPort("plant_state"))
    builder.Connect(T, guard.GetInputPort("T"))
    builder.Connect(x_d, guard.GetInputPort("x_d"))
    if contact:
        builder.Connect(
            station.GetOutputPort("contact_results"), guard.GetInputPort("contact_results")
        )
    return guard


def save_divergence(sd, root, reason: str) -> Path:
    """Write the logs of ``sd`` up to now and the last plant state to its guard's
    ``divergence_dir``.

    The ``.npz`` holds: t (N,), x (N, 12) true pose and rate, T (N, 6) applied torques
    (after the torque limit), the controller's other logs (status, integral) and rho when
    tuned, t_state (M,) and state (M, n) the plant states logged every ``state_log_period_s``,
    x_d (N, 18) the reference at t (when it can be evaluated), t_last (s) and state_last (n,)
    the plant state when the run stopped, T_last (6,) the last command and T_applied_last (6,)
    what the motors applied, reason (str) and
    scenario (the whole scenario as YAML, ``sd.scenario_yaml()``: robot, payload, torque limit,
    feed-forward, controller, noise...).
    Returns:
        the path written.
    """
    logs = {name: logger.FindLog(root) for name, logger in sd.loggers.items()}
    t = logs["x"].sample_times().copy()
    arrays = {
        "t": t,
        "t_state": logs["state"].sample_times().copy(),
        "t_last": np.float64(root.get_time()),
        # The station's port, not the plant's context: on the servo bus the plant is a
        # kinematic model outside the run's Diagram, its state assembled at the measured pose.
        "state_last": sd.station.GetOutputPort("plant_state")
        .Eval(sd.station.GetMyContextFromRoot(root))
        .copy(),
        "T_last": sd.controller.GetOutputPort("T")
        .Eval(sd.controller.GetMyContextFromRoot(root))
        .copy(),
        "T_applied_last": sd.station.GetOutputPort("motor_torque_applied")
        .Eval(sd.station.GetMyContextFromRoot(root))
        .copy(),
        "reason": np.str_(reason),
        "scenario": np.str_(sd.scenario_yaml()),
    }
    for name, log in logs.items():
        arrays[name] = log.data().T.copy()
    trajectory: Reference | None = sd.trajectory  # None: a live reference
    if trajectory is not None:
        try:
            arrays["x_d"] = np.concatenate(trajectory.evaluate(t), axis=1)
        except Exception:  # noqa: BLE001 - the reference itself may be the fault
            pass
    name = getattr(trajectory, "name", "custom")
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = Path(sd.guard.config.divergence_dir) / (
        f"diverged_{name}_t{root.get_time():.4f}s_{stamp}_{os.getpid()}"
        f"_{time.perf_counter_ns() % 1_000_000:06d}.npz"
    )
    return save_npz(path, arrays)


def advance(sd, simulator, step) -> None:
    """Call ``step()`` (which advances ``simulator``); on a divergence save and raise.

    After ``step()`` the guard checks once more (it checks every ``check_period_s``, so a fault
    in the last period would otherwise end a run). Drake refuses a NaN actuation itself at the
    plant step that would use it; such a failure is diagnosed by the guard's checks (the motor
    torques are not finite) and reported as a divergence.

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
        path, unsaved = _save(sd, simulator.get_context(), str(err))
        raise SimulationDivergedError(err.message + unsaved, err.t, path) from err
    except RuntimeError as err:
        if guard is None:
            raise
        root = simulator.get_context()
        reason = guard.check_root(root)  # a diverged signal Drake refused to use?
        if reason is None:
            path, unsaved = _save(sd, root, f"{type(err).__name__}: {err}")
            err.add_note(
                f"stewart-drake: the logs up to t = {root.get_time():.4g} s are saved in {path}"
                if path
                else f"stewart-drake:{unsaved}"
            )
            raise
        reason = f"{reason} (Drake: {err})"
        path, unsaved = _save(sd, root, reason)
        raise SimulationDivergedError(reason + unsaved, root.get_time(), path) from None
    if guard is not None:
        root = simulator.get_context()
        reason = guard.check_root(root)
        if reason is not None:
            path, unsaved = _save(sd, root, reason)
            raise SimulationDivergedError(reason + unsaved, root.get_time(), path)


def _save(sd, root, reason: str) -> tuple[str | None, str]:
    """(path, "") of the saved logs, or (None, " (the logs could not be saved ...: why)"): a
    divergence folder that cannot be written (a file in its place, a full disk) must not turn
    the divergence into an OSError."""
    try:
        return str(save_divergence(sd, root, reason)), ""
    except OSError as err:
        return None, (
            f" (the logs could not be saved in {sd.guard.config.divergence_dir}: "
            f"{err.strerror or err}; set guard.divergence_dir to a writable folder)"
        )
