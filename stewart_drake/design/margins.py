"""What a candidate robot needs for a task, against what its motors give: its margins.

A design (:class:`~stewart_drake.design.variables.Design`) is judged against a sampled task
(:class:`~.task_samples.TaskSamples`) by :func:`evaluate`, one vectorized pass over the task's
poses: the admissible set of the robot (:func:`~stewart_drake.plant.admissible.classify`: reach,
joint and ball-cone limits, conditioning, clearance), the motors' torque by the closed-form
inverse dynamics with the payload, the motors' reflected inertia and friction
(:func:`~stewart_drake.robot.statics.motor_effort`), and the crank speeds. Each requirement is a
**margin** (>= 0: met, :data:`MARGINS`), so a failed task names its binding constraint; an
:class:`Evaluation` gives the objectives a search minimizes (:data:`OBJECTIVES`) and the penalty
of Deb's feasibility rule (:meth:`Evaluation.penalized`, :mod:`~.design_search`).

Not judged here (:mod:`~.design_confirm` runs the best designs in closed loop): the feedback's
tracking, the current loop's lag, encoder resolution; the continuous-torque margin is the RMS of
each motion's torque against :data:`CONTINUOUS_SHARE` of the motor's continuous rating, and
holding a workspace pose is judged against the peak (a pose is not held for a known time).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InvalidConfigError, InvalidGeometryError, StewartError
from ..base.measures import rms_per_axis
from ..plant import admissible
from ..plant.clearance import ClearanceModel
from ..robot import limits, statics
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import DEFAULT_COND_THRESHOLD
from ..robot.motor_catalogue import catalogue_motor
from .task_samples import TaskSamples
from .variables import Design

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
    "continuous_torque": "each motion's RMS torque within CONTINUOUS_SHARE (80 %) of the "
    "motor's continuous torque",
    "resolution": "the pose error of half an encoder count at every crank within the "
    "requirement (relative; inf: not asked)",
    "accuracy": "the encoders' floor (RMS per axis) within its share of the accuracy asked "
    "(relative; inf: not asked)",
}
#: Version of :func:`evaluate`'s rules, part of a search's settings: a store written under other
#: rules is refused rather than replayed.
EVALUATION_VERSION = 4
#: The share of a motor's continuous torque a motion's RMS torque may use: a motor run at its
#: rating heats to its limit at the catalogue's ambient, with nothing left for a warm room, a
#: worn gear or a heavier payload; a design is never recommended above it.
CONTINUOUS_SHARE = 0.8
#: Penalty added to the objective of a design that misses a margin (Deb's rule,
#: :meth:`Evaluation.penalized`): larger than any objective a feasible design reaches.
INFEASIBLE = 1e6


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
        """The objective under Deb's feasibility rule (:mod:`~.design_search`): any design that
        meets every margin beats any that does not; of two that do not, the smaller
        :attr:`shortfall` wins."""
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
    out = Evaluation(design)
    geometry = _build_margin(out, motor, task)
    if geometry is None:
        return out
    x_all = np.concatenate([task.x, task.workspace_x])
    c = _reach_and_conditioning_margins(out, geometry, x_all)
    if c is None:
        return out
    fig = out.figures
    fig["resolution_m"], fig["resolution_rad"] = encoder_resolution(
        geometry, x_all, motor.encoder_counts_per_rev
    )
    out.margins["resolution"] = float(
        min(
            1.0 - fig["resolution_m"] / task.resolution[0],
            1.0 - fig["resolution_rad"] / task.resolution[1],
        )
    )
    fig["floor_m"], fig["floor_rad"] = encoder_floor(geometry, x_all, motor.encoder_counts_per_rev)
    out.margins["accuracy"] = float(
        min(1.0 - fig["floor_m"] / task.floor[0], 1.0 - fig["floor_rad"] / task.floor[1])
    )
    if lazy and min(out.margins.values()) < 0:  # the motors' effort is the costly part next
        return out
    if not _effort_margins(out, geometry, c, motor, task):
        return out
    if lazy and min(out.margins.values()) < 0:
        return out
    _clearance_margin(out, geometry, task)
    return out


def _build_margin(out: Evaluation, motor, task: TaskSamples) -> StewartGeometry | None:
    """The first stage of :func:`evaluate`: the motor's figures and the ``build`` margin of
    ``out``'s design; returns its robot with the task's payload, or None (the reason in the
    figures) when it does not build."""
    design, servo = out.design, motor.servo
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
        return design_geometry(design, task.payload_kg)
    except InvalidGeometryError as err:
        fig["reason"] = str(err)
        out.margins["build"] = min(out.margins["build"], -1e-3)
        return None


def _reach_and_conditioning_margins(out: Evaluation, geometry: StewartGeometry, x_all):
    """The ``reach`` and ``conditioning`` margins of :func:`evaluate` over the poses x_all
    (n, 6); returns the :func:`~stewart_drake.plant.admissible.classify` result, or None when
    a pose is not reached or J is singular at one (the later stages need every pose)."""
    fig = out.figures
    limit_margins = limits.limit_margins_unchecked(geometry, x_all)
    reachable = limits.reachable_from_margins(limit_margins)
    if not np.all(reachable):  # most candidates of a search end here, in milliseconds
        out.margins["reach"] = -float(np.mean(~reachable))
        return None
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
    return c if np.all(np.isfinite(cond)) else None


def _effort_margins(out: Evaluation, geometry: StewartGeometry, c: dict, motor, task) -> bool:
    """The motors' figures and the ``torque``, ``speed`` and ``continuous_torque`` margins of
    :func:`evaluate`: holding the workspace's poses (``c``: their classification) and the
    motions' inverse dynamics. False (the reason in the figures) when a motion's pose is
    singular between the thresholds' samples."""
    fig, servo = out.figures, motor.servo
    holding = float(np.max(c["max_torque"][len(task.x) :], initial=0.0))
    motion_peak, rms, speed = 0.0, 0.0, 0.0
    per_motion = {}
    if len(task.x):
        try:
            T, theta_dot = statics.motor_effort(geometry, task.x, task.x_dot, task.x_ddot, servo)
        except StewartError as err:  # a singular pose between the thresholds' samples
            fig["reason"] = str(err)
            out.margins["conditioning"] = min(out.margins["conditioning"], -1e-3)
            return False
        per_motion = _per_motion(task, T, theta_dot)
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
    out.margins["continuous_torque"] = float(
        1.0 - rms / (CONTINUOUS_SHARE * motor.continuous_torque_Nm)
    )
    return True


def _per_motion(task: TaskSamples, T, theta_dot) -> dict:
    """{motion label: peak and RMS motor torque, N m, and peak crank speed, rad/s} of the
    motors' torques T (n, 6) and crank speeds theta_dot (n, 6) along the task's motions."""
    per_motion = {}
    for i, label in enumerate(task.labels):
        mine = task.motion == i
        Ti, wi = np.abs(T[mine]), np.abs(theta_dot[mine])
        per_motion[label] = {
            "peak_torque_Nm": float(Ti.max()),
            "rms_torque_Nm": float(rms_per_axis(Ti).max()),
            "peak_speed_rad_s": float(wi.max()),
        }
    return per_motion


def _clearance_margin(out: Evaluation, geometry: StewartGeometry, task: TaskSamples) -> None:
    """The last stage of :func:`evaluate`: the smallest distance between the robot's parts at
    the task's clearance poses (Drake's signed distances) and the ``clearance`` margin."""
    fig = out.figures
    model = ClearanceModel(geometry)
    distance = model.sweep(task.clearance_x, max_distance=admissible.CLEARANCE_CAP_M)[0]
    # The rod ends on the platform: a distance the design fixes, the same at every pose.
    fixed = model.fixed[0].distance if model.fixed else np.inf
    fig["design_clearance_m"] = float(fixed)
    fig["min_clearance_m"] = float(min(np.min(distance), fixed))
    out.margins["clearance"] = float(fig["min_clearance_m"] / limits.DEFAULT_MIN_CLEARANCE_M - 1.0)


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


def encoder_floor(geometry: StewartGeometry, x, counts_per_rev: int) -> tuple:
    """The encoders' floor over poses x (n, 6), the largest over the poses of each kind of axis
    (:func:`~stewart_drake.robot.forward_kinematics.encoder_floor`: every crank within half a
    count, uniform and independent, RMS per axis through J^-1, first order).

    Returns:
        (translation m, rotation rad): the largest RMS of a position axis and of an
        orientation axis over the poses.
    Raises:
        SingularPoseError: J is singular at a pose.
    """
    from ..robot.forward_kinematics import encoder_floor as floor_per_axis

    rms = floor_per_axis(geometry, np.atleast_2d(x), 2 * np.pi / counts_per_rev)
    return float(rms[:, 3:].max()), float(rms[:, :3].max())


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
