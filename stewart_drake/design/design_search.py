"""Design search: what a candidate robot needs for a task, and the best design an optimizer finds.

A design (:class:`~stewart_drake.design.variables.Design`) is judged against a task
(:class:`~stewart_drake.design.requirements.DesignRequirements`) by :func:`evaluate`: the
task is sampled once (:func:`task_samples`: the motions' poses, rates and accelerations at
:data:`MOTION_RATE_HZ`, the required box at :data:`BOX_POINTS` points per side each tilted by
the cone's angle about :data:`TILT_DIRECTIONS` horizontal axes), and every candidate is then one
vectorized pass over those poses: the admissible set of the robot (:func:`~stewart_drake.robot.
admissible.classify`: reach, joint and ball-cone limits, conditioning, clearance), the motors'
torque by the closed-form inverse dynamics with the payload, the motors' reflected inertia and
friction (:func:`~stewart_drake.robot.statics.motor_effort`), and the crank speeds. Each
requirement is a **margin** (>= 0: met), so a failed task names its binding constraint.

:func:`search` minimizes one objective (:data:`OBJECTIVES`) over the design's numbers with a
fixed motor, using scipy's ``differential_evolution``: a population method that needs no
gradient (the admissible set's edges are not smooth), is seeded and deterministic (``rng``, the
population evaluated a generation at a time), and lets us evaluate each generation with the
project's runners (local processes, Ray or Dask). pymoo's NSGA-II would give a Pareto front of
several objectives, but the task's acceptance is one objective under constraints per motor, the
motor is a choice among five, and scipy is already a dependency: :func:`cheapest_motor` runs one
search per catalogue motor, cheapest first, and the set of (motor price, least torque share)
pairs is the front between cost and reserve. Constraints are handled by Deb's feasibility rule
(any design that meets every margin beats any that does not; of two that do not, the smaller
total shortfall wins), as a penalty on the objective.

A search persists through the project's :class:`~stewart_drake.execution.store.ResultStore`: each
generation's evaluations are one job, keyed by the generation's candidates; a search killed and
run again replays the finished generations from disk (the optimizer is deterministic, so it asks
for the same candidates) and continues. The same seed gives the same design.

Not judged here (:mod:`~.design_confirm` runs the best designs in closed loop): the feedback's
tracking, the current loop's lag, encoder resolution; the continuous-torque margin is the RMS of
each motion's torque against the motor's continuous rating, and holding a workspace pose is
judged against the peak (a pose is not held for a known time).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.errors import CorruptFileError, InvalidConfigError, InvalidGeometryError, StewartError
from ..plant import admissible
from ..plant.clearance import ClearanceModel
from ..robot import limits, statics
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import DEFAULT_COND_THRESHOLD
from ..robot.motor_catalogue import MOTOR_CATALOGUE, REFERENCE_MOTOR, catalogue_motor
from .requirements import DesignRequirements
from .variables import DESIGN_BOUNDS, Design, reference_design

#: Sample rate of the motions, Hz: 100 samples a second resolve the torque peaks of the library's
#: motions (heartbeat harmonics to 6 Hz) to within 1 %.
MOTION_RATE_HZ = 100.0
#: Longest stretch of a motion sampled, s (a periodic motion: one period, at most this).
MAX_MOTION_S = 60.0
#: Points per side of the required box (3: corners, edge midpoints, faces and centre).
BOX_POINTS = 3
#: Horizontal axes the platform is tilted about at each point of the box (evenly spread).
TILT_DIRECTIONS = 8
#: Clearance is measured at every this-many-th motion sample (0.2 s at 100 Hz) and at every
#: workspace pose; parts move < 3 mm in 0.2 s along the library's motions.
CLEARANCE_STRIDE = 20
#: The design's variables the search varies, in order; ``rod_length`` is drawn within the
#: lengths that close every leg at home (:meth:`Design.rod_length_range`), so every candidate
#: whose other variables allow a rod builds.
SEARCH_VARIABLES = tuple(name for name in DESIGN_BOUNDS if name != "rod_length") + ("rod_length",)
#: What a search may minimize: {name: (unit, meaning)}.
OBJECTIVES = {
    "peak_torque": ("N m", "largest motor torque the task needs (motions and holding)"),
    "torque_share": ("1", "that torque over the motor's allowed share of its peak"),
    "price": ("USD", "the six motors' price, ties broken by torque_share"),
}
#: Every margin :func:`evaluate` reports: {name: meaning}. >= 0: met.
MARGINS = {
    "build": "a rod length closes every leg at home (closing range over rod length)",
    "reach": "every task pose inside closure, motor travel and ball cones "
    "(-share of poses outside; else the smallest normalized limit margin)",
    "conditioning": "cond(J) and 1/sigma_max(J) within the guard's thresholds (relative)",
    "clearance": "no two parts closer than the guard's clearance, the pairs the design fixes "
    "(rod ends on the platform) included (relative)",
    "torque": "peak motor torque within the share of the motor's peak the margins leave",
    "speed": "peak crank speed within the share of the no-load speed the margins leave",
    "continuous_torque": "each motion's RMS torque within the motor's continuous torque",
    "resolution": "the pose error of half an encoder count at every crank within the "
    "requirement (relative; inf: not asked)",
}
#: Version of :func:`evaluate`'s rules, part of a search's settings: a store written under other
#: rules is refused rather than replayed.
EVALUATION_VERSION = 2
#: Penalty added to the objective of a design that misses a margin (Deb's rule, module
#: docstring): larger than any objective a feasible design reaches.
INFEASIBLE = 1e6


@dataclass(frozen=True)
class TaskSamples:
    """What a task asks of any design, sampled once (:func:`task_samples`).

    Attributes:
        labels: each motion's name.
        x, x_dot, x_ddot: (n, 6) the motions' poses [rad, m], rates and accelerations, one after
            the other.
        motion: (n,) int, the motion each sample belongs to (an index of ``labels``).
        workspace_x: (m, 6) the required workspace's poses, held (m = 0: none).
        payload_kg: mass at the platform frame's origin, kg.
        torque_share, speed_share: what the motions may use of the motor's peak torque and
            no-load speed (1 - the requirements' margins).
        resolution: (2,) the largest pose error the encoders may leave, [m, rad]
            (:class:`~stewart_drake.design.requirements.Resolution`); inf: not judged.
    """

    labels: tuple
    x: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    motion: np.ndarray
    workspace_x: np.ndarray
    payload_kg: float
    torque_share: float
    speed_share: float
    resolution: tuple = (float("inf"), float("inf"))

    @property
    def clearance_x(self) -> np.ndarray:
        """(k, 6) the poses at which clearance is measured (module docstring)."""
        return np.concatenate([self.x[::CLEARANCE_STRIDE], self.workspace_x])

    def digest(self) -> str:
        """16 hex digits identifying the samples (a search's settings)."""
        h = hashlib.sha256()
        for a in (self.x, self.x_dot, self.x_ddot, self.motion, self.workspace_x):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        h.update(
            json.dumps(
                [self.labels, self.payload_kg, self.torque_share, self.speed_share]
                + [str(v) for v in self.resolution]
            ).encode()
        )
        return h.hexdigest()[:16]

    def save(self, path) -> None:
        """Write the samples to ``path`` (.npz, arrays only, atomically: a search killed while
        it writes leaves no half file for the next one to resume from; read back with
        :meth:`load`)."""
        from ..base.fileio import save_npz

        save_npz(
            path,
            {
                "labels": np.array(self.labels, dtype=str),
                "x": self.x,
                "x_dot": self.x_dot,
                "x_ddot": self.x_ddot,
                "motion": self.motion,
                "workspace_x": self.workspace_x,
                "scalars": np.array([self.payload_kg, self.torque_share, self.speed_share]),
                "resolution": np.array(self.resolution, dtype=float),
            },
        )

    @classmethod
    def load(cls, path) -> TaskSamples:
        """Read what :meth:`save` wrote, through :class:`~stewart_drake.base.fileio.CheckedNpz`
        (numbers and text only, each entry's header checked before it is loaded).

        Raises:
            CorruptFileError: not such a file (names it and the entry at fault).
            OSError: the file cannot be read.
        """
        from ..base.fileio import CheckedNpz

        f = CheckedNpz(path, "design task samples (.npz)", "run the design search again")
        scalars, resolution = f.array("scalars"), f.array("resolution")
        if scalars.shape != (3,):
            raise f.corrupt(f"the entry 'scalars' must hold 3 numbers, has {scalars.shape}")
        payload, torque_share, speed_share = (float(v) for v in scalars)
        return cls(
            f.texts("labels"),
            f.array("x"),
            f.array("x_dot"),
            f.array("x_ddot"),
            f.integers("motion"),
            f.array("workspace_x"),
            payload,
            torque_share,
            speed_share,
            tuple(float(v) for v in resolution.ravel()),
        )


def tilted_box_poses(box_m, tilt_deg: float, centre_m, points: int = BOX_POINTS) -> np.ndarray:
    """Poses of a required workspace: a grid of the box, each untilted and tilted by
    ``tilt_deg`` about :data:`TILT_DIRECTIONS` horizontal axes, (points^3 (1 + directions), 6).

    The platform's normal then sweeps the cone's rim; yaw stays 0 (the task's cone is about
    tilt). Poses are [roll, pitch, yaw, X, Y, Z] as everywhere (R = Rz Ry Rx).
    """
    from scipy.spatial.transform import Rotation

    axes = [np.linspace(-s / 2, s / 2, points) if s > 0 else np.zeros(1) for s in box_m]
    p = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + np.asarray(centre_m)
    a = 2 * np.pi * np.arange(TILT_DIRECTIONS) / TILT_DIRECTIONS
    rotvec = np.deg2rad(tilt_deg) * np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    rpy = np.concatenate([np.zeros((1, 3)), Rotation.from_rotvec(rotvec).as_euler("xyz")])
    if tilt_deg == 0:
        rpy = rpy[:1]
    rpy_all = np.repeat(rpy[None], len(p), axis=0).reshape(-1, 3)
    p_all = np.repeat(p, len(rpy), axis=0)
    return np.concatenate([rpy_all, p_all], axis=1)


def task_samples(requirements: DesignRequirements) -> TaskSamples:
    """Sample a task once for every candidate (module docstring).

    Each motion is built for the reference robot (only the data-collection excitation uses the
    robot, and a task names its motions) and sampled over its length: the paper manoeuvre and
    the sine references over their period (at most :data:`MAX_MOTION_S`), a periodic library
    motion over one repeat period, a trace over its recording.

    Raises:
        InvalidConfigError, MissingFileError, CorruptFileError: a motion that cannot be built.
    """
    requirements.validate()
    geometry = reference_design().geometry()
    labels, xs, xds, xdds, which = [], [], [], [], []
    for i, choice in enumerate(requirements.motions):
        reference = choice.make(geometry, MAX_MOTION_S, None)
        start, duration = _motion_span(reference)
        t = start + np.arange(0.0, duration + 0.5 / MOTION_RATE_HZ, 1.0 / MOTION_RATE_HZ)
        x, xd, xdd = reference.evaluate(t)
        labels.append(choice.label)
        xs.append(x)
        xds.append(xd)
        xdds.append(xdd)
        which.append(np.full(len(t), i))
    workspace = requirements.workspace
    ws_x = (
        np.zeros((0, 6))
        if workspace is None
        else tilted_box_poses(workspace.box_m, workspace.tilt_deg, workspace.centre_m)
    )
    empty = np.zeros((0, 6))
    return TaskSamples(
        tuple(labels),
        np.concatenate(xs) if xs else empty,
        np.concatenate(xds) if xs else empty,
        np.concatenate(xdds) if xs else empty,
        np.concatenate(which) if xs else np.zeros(0, dtype=int),
        ws_x,
        float(requirements.payload_kg),
        1.0 - requirements.margins.torque,
        1.0 - requirements.margins.speed,
        (float("inf"), float("inf"))
        if requirements.resolution is None
        else (requirements.resolution.translation_m, requirements.resolution.rotation_rad),
    )


def _motion_span(reference) -> tuple[float, float]:
    """(start, length) of a motion to sample, s: a recording from its first sample over its
    length, a periodic motion over one repeat period (at least 10 s), else 10 s (the paper
    manoeuvre's run); at most :data:`MAX_MOTION_S`."""
    end = getattr(reference, "end_time", None)
    if end is not None:
        start = float(getattr(reference, "start_time", 0.0))
        return start, min(float(end) - start, MAX_MOTION_S)
    period = getattr(reference, "repeat_period_s", None)
    if isinstance(period, (int, float)) and period > 0:
        return 0.0, float(min(max(period, 10.0), MAX_MOTION_S))
    return 0.0, 10.0


@dataclass
class Evaluation:
    """What a design needs for a task, against what its motor gives (:func:`evaluate`).

    Attributes:
        design: the candidate.
        margins: {name in :data:`MARGINS`: margin}, >= 0 met; a margin not computed because an
            earlier one failed (clearance of poses not reached) is absent.
        figures: peak_torque_Nm (motions and holding), holding_torque_Nm, motion_torque_Nm,
            rms_torque_Nm (largest over motions and motors), peak_speed_rad_s, min_clearance_m,
            max_cond, min_sigma_min_inv, motor_peak_Nm, motor_continuous_Nm,
            motor_no_load_rad_s, price_usd (six motors), per_motion (label: peak N m, RMS N m,
            peak rad/s), reason (why it does not build, else "").
    """

    design: Design
    margins: dict = field(default_factory=dict)
    figures: dict = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        """Every margin computed and >= 0."""
        return len(self.margins) == len(MARGINS) and all(m >= 0 for m in self.margins.values())

    @property
    def binding(self) -> tuple[str, float]:
        """(name, margin) of the smallest margin: the constraint that stops a better design (or
        the first that fails)."""
        name = min(self.margins, key=self.margins.__getitem__)
        return name, self.margins[name]

    @property
    def shortfall(self) -> float:
        """How far from meeting the task, >= 0 (0: feasible): each missed margin m counts
        -m / (1 - m), in (0, 1), and a margin not computed (an earlier one failed) counts 1, so
        a candidate that gets further through the checks ranks better."""
        missed = sum(-m / (1.0 - m) for m in self.margins.values() if m < 0)
        return float(missed + (len(MARGINS) - len(self.margins)))

    def objective(self, name: str) -> float:
        """The objective ``name`` of :data:`OBJECTIVES` (inf where it is not computed)."""
        f = self.figures
        if "peak_torque_Nm" not in f:
            return float("inf")
        share = f["peak_torque_Nm"] / (f["motor_peak_Nm"] * f["torque_share"])
        if name == "peak_torque":
            return float(f["peak_torque_Nm"])
        if name == "torque_share":
            return float(share)
        if name == "price":
            return float(f["price_usd"] + min(share, 10.0))
        raise InvalidConfigError(f"objective {name!r} is not one of {', '.join(OBJECTIVES)}")

    def penalized(self, name: str) -> float:
        """The objective under Deb's feasibility rule (module docstring)."""
        if self.feasible:
            return self.objective(name)
        return INFEASIBLE * (1.0 + self.shortfall)

    def to_json(self) -> dict:
        """A JSON document of the evaluation (:meth:`from_json` reads it back)."""
        return {
            "design": dataclasses.asdict(self.design),
            "margins": self.margins,
            "figures": self.figures,
        }

    @classmethod
    def from_json(cls, value: dict) -> Evaluation:
        return cls(Design(**value["design"]), dict(value["margins"]), dict(value["figures"]))


def design_geometry(design: Design, payload_kg: float = 0.0) -> StewartGeometry:
    """The design's robot as the task sees it: the payload on the platform (at the platform
    frame's origin, its centre of mass: the mass adds, the inertia about it does not) and the
    motors' reflected inertia at the cranks.

    Raises:
        InvalidConfigError, InvalidGeometryError: as :meth:`Design.geometry`.
    """
    geometry = design.geometry()
    return dataclasses.replace(
        geometry,
        platform_mass=geometry.platform_mass + payload_kg,
        motor_reflected_inertia=design.servo().reflected_inertia,
    )


def evaluate(design: Design, task: TaskSamples, lazy: bool = True) -> Evaluation:
    """Judge ``design`` against ``task``: its margins and figures (:class:`Evaluation`).

    The margins are computed in stages, each over every pose at once (numpy): reach; then
    conditioning and encoder resolution; then the motors' torque, speed and continuous torque
    (the closed-form inverse dynamics); then clearance (Drake's signed distances). A stage runs
    only where every pose is reached (an unreached pose has no Jacobian or torque) and, when
    ``lazy``, only when the margins before it are met, so a failed candidate costs little. A
    report passes ``lazy=False`` to have every margin of a design that reaches every pose.

    Raises:
        InvalidConfigError: a variable outside its bounds, an unknown motor.
    """
    motor = catalogue_motor(design.motor)
    servo = motor.servo
    out = Evaluation(design)
    fig = out.figures
    fig.update(
        motor_peak_Nm=servo.peak_torque_Nm,
        motor_continuous_Nm=motor.continuous_torque_Nm,
        motor_no_load_rad_s=servo.no_load_speed_rad_s,
        price_usd=6 * motor.price_usd,
        torque_share=task.torque_share,
        reason="",
    )
    lo, hi = design.rod_length_range()
    out.margins["build"] = float(min(design.rod_length - lo, hi - design.rod_length, hi - lo))
    out.margins["build"] /= design.rod_length
    try:
        geometry = design_geometry(design, task.payload_kg)
    except InvalidGeometryError as err:
        fig["reason"] = str(err)
        out.margins["build"] = min(out.margins["build"], -1e-3)
        return out
    x_all = np.concatenate([task.x, task.workspace_x])
    limit_margins = limits.limit_margins_unchecked(geometry, x_all)
    reachable = limits.reachable_from_margins(limit_margins)
    if not np.all(reachable):  # most candidates of a search end here, in milliseconds
        out.margins["reach"] = -float(np.mean(~reachable))
        return out
    out.margins["reach"] = _limit_margin(geometry, limit_margins)
    c = admissible.classify(geometry, x_all, min_clearance_m=None)
    cond, inv = c["cond"], c["sigma_min_inv"]
    fig.update(max_cond=float(np.max(cond)), min_sigma_min_inv=float(np.min(inv)))
    out.margins["conditioning"] = float(
        min(
            1.0 - fig["max_cond"] / DEFAULT_COND_THRESHOLD,
            fig["min_sigma_min_inv"] / limits.DEFAULT_MIN_SIGMA_MIN_INV - 1.0,
        )
    )
    if not np.all(np.isfinite(cond)):
        return out
    fig["resolution_m"], fig["resolution_rad"] = encoder_resolution(
        geometry, x_all, motor.encoder_counts_per_rev
    )
    out.margins["resolution"] = float(
        min(
            1.0 - fig["resolution_m"] / task.resolution[0],
            1.0 - fig["resolution_rad"] / task.resolution[1],
        )
    )
    if lazy and min(out.margins.values()) < 0:  # the motors' effort is the costly part next
        return out
    holding = float(np.max(c["max_torque"][len(task.x) :], initial=0.0))
    motion_peak, rms, speed = 0.0, 0.0, 0.0
    per_motion = {}
    if len(task.x):
        try:
            T, theta_dot = statics.motor_effort(geometry, task.x, task.x_dot, task.x_ddot, servo)
        except StewartError as err:  # a singular pose between the thresholds' samples
            fig["reason"] = str(err)
            out.margins["conditioning"] = min(out.margins["conditioning"], -1e-3)
            return out
        for i, label in enumerate(task.labels):
            mine = task.motion == i
            Ti, wi = np.abs(T[mine]), np.abs(theta_dot[mine])
            per_motion[label] = {
                "peak_torque_Nm": float(Ti.max()),
                "rms_torque_Nm": float(np.sqrt(np.mean(Ti**2, axis=0)).max()),
                "peak_speed_rad_s": float(wi.max()),
            }
        motion_peak = max(v["peak_torque_Nm"] for v in per_motion.values())
        rms = max(v["rms_torque_Nm"] for v in per_motion.values())
        speed = max(v["peak_speed_rad_s"] for v in per_motion.values())
    peak = max(motion_peak, holding)
    fig.update(
        peak_torque_Nm=peak,
        holding_torque_Nm=holding,
        motion_torque_Nm=motion_peak,
        rms_torque_Nm=rms,
        peak_speed_rad_s=speed,
        per_motion=per_motion,
    )
    out.margins["torque"] = float(1.0 - peak / (task.torque_share * servo.peak_torque_Nm))
    out.margins["speed"] = float(1.0 - speed / (task.speed_share * servo.no_load_speed_rad_s))
    out.margins["continuous_torque"] = float(1.0 - rms / motor.continuous_torque_Nm)
    if lazy and min(out.margins.values()) < 0:
        return out
    model = ClearanceModel(geometry)
    distance = model.sweep(task.clearance_x, max_distance=admissible.CLEARANCE_CAP_M)[0]
    # The rod ends on the platform: a distance the design fixes, the same at every pose.
    fixed = model.fixed[0].distance if model.fixed else np.inf
    fig["design_clearance_m"] = float(fixed)
    fig["min_clearance_m"] = float(min(np.min(distance), fixed))
    out.margins["clearance"] = float(fig["min_clearance_m"] / limits.DEFAULT_MIN_CLEARANCE_M - 1.0)
    return out


#: The 64 sign patterns of six half-counts.
_SIGNS = np.array(np.meshgrid(*[[-1.0, 1.0]] * 6, indexing="ij")).reshape(6, -1).T


def encoder_resolution(geometry: StewartGeometry, x, counts_per_rev: int) -> tuple:
    """The largest pose error the encoders leave over poses x (n, 6): every crank read half a
    count off, the worst of the 64 sign patterns, dx = J^-1 dtheta (first order).

    Returns:
        (translation m, rotation rad): the largest norm of the position and of the
        roll-pitch-yaw parts of dx over poses and patterns.
    Raises:
        SingularPoseError: J is singular at a pose.
    """
    from ..robot.kinematics import jacobian

    J_inv = np.linalg.inv(jacobian(geometry, np.asarray(x, dtype=float)))
    dx = np.einsum("nij,sj->nsi", J_inv, _SIGNS) * (np.pi / counts_per_rev)
    return (
        float(np.linalg.norm(dx[..., 3:], axis=-1).max()),
        float(np.linalg.norm(dx[..., :3], axis=-1).max()),
    )


def _limit_margin(geometry: StewartGeometry, m: dict) -> float:
    """Smallest of the limit margins ``m`` (:func:`~.limits.limit_margins_unchecked`), each
    normalized (closure as is, angles over their range or cone), >= 0 where every pose is
    inside."""
    travel = np.deg2rad(geometry.motor_angle_max_deg - geometry.motor_angle_min_deg) / 2
    return float(
        min(
            np.min(m["closure"]),
            np.min(m["motor_angle"]) / travel,
            np.min(m["crank_joint"]) / np.deg2rad(geometry.crank_joint_cone_deg),
            np.min(m["platform_joint"]) / np.deg2rad(geometry.platform_joint_cone_deg),
        )
    )


# --- the search ---------------------------------------------------------------------------


def design_from_vector(u, motor: str) -> Design:
    """The design of a point u in [0, 1]^8 of the search (:data:`SEARCH_VARIABLES`): each
    variable at its share of its bounds, the rod at its share of the closing range (clipped to
    its bounds)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    values = {}
    for ui, name in zip(u, SEARCH_VARIABLES[:-1], strict=False):
        lo, hi = DESIGN_BOUNDS[name][:2]
        values[name] = float(lo + ui * (hi - lo))
    rlo, rhi = DESIGN_BOUNDS["rod_length"][:2]
    design = Design(**values, rod_length=0.5 * (rlo + rhi), motor=motor)
    lo, hi = design.rod_length_range()
    lo, hi = max(lo, rlo), min(hi, rhi)
    if lo > hi:  # no rod closes: the nearest bound, the build margin says by how much
        design.rod_length = float(np.clip(0.5 * (lo + hi), rlo, rhi))
    else:
        design.rod_length = float(lo + u[-1] * (hi - lo))
    return design


def vector_of(design: Design) -> np.ndarray:
    """Inverse of :func:`design_from_vector` for a design that builds, (8,)."""
    u = [
        (getattr(design, name) - DESIGN_BOUNDS[name][0])
        / (DESIGN_BOUNDS[name][1] - DESIGN_BOUNDS[name][0])
        for name in SEARCH_VARIABLES[:-1]
    ]
    lo, hi = design.rod_length_range()
    rlo, rhi = DESIGN_BOUNDS["rod_length"][:2]
    lo, hi = max(lo, rlo), min(hi, rhi)
    u.append((design.rod_length - lo) / (hi - lo) if hi > lo else 0.5)
    return np.clip(np.array(u), 0.0, 1.0)


@dataclass(frozen=True)
class _Job:
    """Candidates for a worker: the task's file and the designs' points (a share of a
    generation: one job per worker, so a generation costs a few submissions)."""

    task_file: str
    motor: str
    points: tuple


_TASKS: dict = {}


def _evaluate_job(job: _Job) -> list:
    """Worker side: load the task once per process, evaluate the job's candidates."""
    task = _TASKS.get(job.task_file)
    if task is None:
        task = _TASKS[job.task_file] = TaskSamples.load(job.task_file)
    return [evaluate(design_from_vector(u, job.motor), task).to_json() for u in job.points]


#: Defaults of a search: population per variable, generations (scipy's ``popsize`` and
#: ``maxiter``; 8 x 8 = 64 candidates a generation).
DEFAULT_POPSIZE, DEFAULT_MAXITER = 8, 30


@dataclass
class SearchResult:
    """What :func:`search` found.

    Attributes:
        motor, objective, seed: what was searched.
        best: the :class:`Evaluation` of the best design (feasible if any candidate was; a
            best that misses is evaluated again with every margin, ``lazy=False``).
        evaluations: candidates evaluated (the reference design among them), ``reused`` of them
            read back from an earlier, interrupted run.
        generations: per generation, [best penalized objective, feasible share].
        wall_s: this call's wall time, s.
        compute_s: the wall time the generations took when they were evaluated, s (this call's
            and, for those read back, the run's that evaluated them).
    """

    motor: str
    objective: str
    seed: int
    best: Evaluation
    evaluations: int
    reused: int
    generations: list
    wall_s: float
    compute_s: float = 0.0

    @property
    def feasible(self) -> bool:
        return self.best.feasible


class _Generations:
    """The map scipy's optimizer evaluates a generation with (its ``workers``): each generation
    is one job of the study's store, keyed by its candidates, run through the runner a candidate
    a process; a generation on disk is read back instead (kill and resume)."""

    def __init__(self, store, runner, task_file: Path, motor: str, objective: str, progress):
        self.store, self.runner, self.task_file = store, runner, str(task_file)
        self.motor, self.objective, self.progress = motor, objective, progress
        self.best: Evaluation | None = None
        self.evaluations = self.reused = 0
        self.compute_s = 0.0
        self.generations: list = []
        #: The typed error that ended a generation: scipy wraps a ValueError raised in its map
        #: (a CorruptFileError is one) in a RuntimeError of its own, which :func:`search` undoes.
        self.error: StewartError | None = None

    def __call__(self, func, population):
        try:
            return self._evaluate(population)
        except StewartError as err:
            self.error = err
            raise

    def _stored(self, job_id: str, size: int) -> list:
        """The ``size`` evaluations of a generation on disk, checked: a list of evaluations'
        JSON, one per candidate.

        Raises:
            CorruptFileError: the file is not JSON, or not evaluations (names it).
        """
        docs = self.store.load_json(job_id)
        try:
            evals = [Evaluation.from_json(d) for d in docs]
            for e in evals:  # each must give its objective, as a fresh evaluation does
                e.penalized(self.objective)
            if len(evals) != size:
                raise ValueError(f"{len(evals)} evaluations for {size} candidates")
        except (KeyError, TypeError, ValueError, AttributeError) as err:
            what = err if type(err) is ValueError else f"{type(err).__name__} {err}"
            path = self.store.folder / self.store.manifest["jobs"][job_id]["file"]
            raise CorruptFileError(
                path,
                "design generation",
                f"not the generation's evaluations ({what})",
                "delete it and run the same command again to redo that generation",
            ) from None
        return docs

    def _evaluate(self, population) -> list:
        rows = [np.asarray(u, dtype=float) for u in population]
        key = hashlib.sha256(b"".join(u.tobytes() for u in rows)).hexdigest()[:16]
        job_id = f"{self.motor}/{self.objective}/gen_{key}"
        if job_id in self.store.done():
            docs = self._stored(job_id, len(rows))
            self.reused += len(rows)
            self.compute_s += float(self.store.manifest["jobs"][job_id].get("wall_s", 0.0))
        else:
            shares = np.array_split(np.arange(len(rows)), max(1, self.runner.n_workers))
            jobs = {
                f"{i:02d}": _Job(self.task_file, self.motor, tuple(tuple(rows[k]) for k in share))
                for i, share in enumerate(shares)
                if len(share)
            }
            wall0 = time.perf_counter()
            outcomes = dict(self.runner.map(_evaluate_job, jobs))
            failed = [o for o in outcomes.values() if not isinstance(o, list)]
            if failed:  # evaluate() raises only on bad input, which search() checked
                raise StewartError(f"design candidates failed: {failed[0]}")
            docs = [doc for k in jobs for doc in outcomes[k]]
            wall = time.perf_counter() - wall0
            self.compute_s += wall
            self.store.put_json(
                job_id, f"{self.motor}_{self.objective}_gen_{key}.json", docs, wall_s=wall
            )
        evals = [Evaluation.from_json(d) for d in docs]
        values = [e.penalized(self.objective) for e in evals]
        self.evaluations += len(evals)
        for e, v in zip(evals, values, strict=True):
            if self.best is None or v < self.best.penalized(self.objective):
                self.best = e
        self.generations.append([float(min(values)), float(np.mean([e.feasible for e in evals]))])
        if self.progress is not None:
            self.progress.update()
            self.progress.set_postfix_str(self._status())
        return values

    def _status(self) -> str:
        if self.best is None:
            return ""
        if self.best.feasible:
            return f"best {self.objective} {self.best.objective(self.objective):.4g}"
        name, margin = self.best.binding
        return f"none feasible yet ({name} {margin:+.3g})"


def search(
    task: TaskSamples,
    motor: str = REFERENCE_MOTOR,
    objective: str = "peak_torque",
    out_dir="results/design",
    seed: int = 0,
    runner=None,
    popsize: int = DEFAULT_POPSIZE,
    maxiter: int = DEFAULT_MAXITER,
    progress: bool = True,
) -> SearchResult:
    """Minimize ``objective`` over the design's numbers with ``motor`` at every crank, subject to
    every margin of :data:`MARGINS` (module docstring: the optimizer, the constraints, resuming).

    The first generation holds the reference robot's numbers (scipy's ``x0``), so a task the
    reference robot meets returns a design at least as good.

    Args:
        task: :func:`task_samples` of the requirements.
        motor: a catalogue name. objective: one of :data:`OBJECTIVES`.
        out_dir: the study's folder (created); a search of other settings there is refused.
        seed: the optimizer's seed: the same seed and settings give the same design.
        runner: any runner of :mod:`~stewart_drake.execution.runners` (default: this process).
        popsize, maxiter: scipy's; evaluations <= popsize x 8 x (maxiter + 1).
        progress: a bar over the generations.
    Raises:
        InvalidConfigError: an unknown motor or objective, popsize < 2 or maxiter < 1.
        ResultsMismatchError, FolderInUseError: see :class:`~stewart_drake.execution.store.
            ResultStore`.
    """
    from scipy.optimize import differential_evolution
    from tqdm import tqdm

    from ..execution.runners import SerialRunner
    from ..execution.store import ResultStore

    catalogue_motor(motor)
    if objective not in OBJECTIVES:
        raise InvalidConfigError(f"objective {objective!r} is not one of {', '.join(OBJECTIVES)}")
    if int(popsize) < 2 or int(maxiter) < 1:
        raise InvalidConfigError(f"popsize must be >= 2 and maxiter >= 1, got {popsize}, {maxiter}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    settings = {
        "task": task.digest(),
        "evaluation": EVALUATION_VERSION,
        "variables": list(SEARCH_VARIABLES),
        "bounds": {k: list(v[:2]) for k, v in DESIGN_BOUNDS.items()},
        "catalogue": {k: dataclasses.asdict(v) for k, v in MOTOR_CATALOGUE.items()},
        "seed": int(seed),
        "popsize": int(popsize),
        "maxiter": int(maxiter),
    }
    store = ResultStore(out, "design", settings, "*_gen_*.json")
    wall0 = time.perf_counter()
    generations: _Generations | None = None
    try:
        task_file = out / "task.npz"
        if not task_file.exists():
            task.save(task_file)
        elif TaskSamples.load(task_file).digest() != task.digest():  # pragma: no cover - guarded
            raise InvalidConfigError(f"{task_file} holds another task: choose another --out")
        with tqdm(
            total=maxiter + 1, desc=f"design {motor}", unit="gen", disable=not progress
        ) as bar:
            generations = _Generations(
                store, runner or SerialRunner(), task_file, motor, objective, bar
            )
            reference = reference_design()
            reference.motor = motor
            differential_evolution(
                _unused_objective,
                [(0.0, 1.0)] * len(SEARCH_VARIABLES),
                popsize=popsize,
                maxiter=maxiter,
                polish=False,
                init="latinhypercube",
                x0=vector_of(reference),
                workers=generations,
                updating="deferred",
                tol=1e-6,
                **_seeded(seed),
            )
        store.close()
    except RuntimeError:
        store.close()
        # scipy wraps a typed error raised in its map in a RuntimeError of its own
        if generations is not None and generations.error is not None:
            raise generations.error from None
        raise
    except BaseException:
        store.close()
        raise
    assert generations is not None
    best = generations.best
    assert best is not None
    if not best.feasible:  # every margin of the best miss, for the report (one evaluation)
        best = evaluate(best.design, task, lazy=False)
    return SearchResult(
        motor,
        objective,
        int(seed),
        best,
        generations.evaluations,
        generations.reused,
        generations.generations,
        time.perf_counter() - wall0,
        generations.compute_s,
    )


def _unused_objective(u) -> float:  # pragma: no cover - the generations' map evaluates instead
    raise AssertionError("design candidates are evaluated by _Generations")


def _seeded(seed: int) -> dict:
    """scipy's seed argument: one Generator stream for every scipy the project supports
    (``rng`` from 1.15, ``seed`` before)."""
    import inspect

    from scipy.optimize import differential_evolution

    generator = np.random.default_rng(int(seed))
    if "rng" in inspect.signature(differential_evolution).parameters:
        return {"rng": generator}
    return {"seed": generator}


def cheapest_motor(
    task: TaskSamples,
    out_dir="results/design",
    seed: int = 0,
    runner=None,
    popsize: int = DEFAULT_POPSIZE,
    maxiter: int = DEFAULT_MAXITER,
    progress: bool = True,
) -> list[SearchResult]:
    """Search the catalogue's motors from the cheapest up for a design that meets the task with
    the most reserve (objective ``torque_share``); stops at the first motor that meets it.

    Returns:
        the searches run, cheapest motor first; the last is feasible unless no motor is (then
        each names its binding constraint).
    Raises:
        as :func:`search`.
    """
    results = []
    for motor in sorted(MOTOR_CATALOGUE, key=lambda m: MOTOR_CATALOGUE[m].price_usd):
        result = search(
            task, motor, "torque_share", out_dir, seed, runner, popsize, maxiter, progress
        )
        results.append(result)
        if result.feasible:
            break
    return results
