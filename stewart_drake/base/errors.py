"""Typed errors of stewart-drake; every message says what to change.

All inherit from :class:`StewartError` so callers can catch the family at once. Every one
pickles with its attributes and message (a refusal inside a worker process comes back to the
parent as itself): a class whose ``__init__`` takes other arguments than the message says which
in :meth:`StewartError._init_args`.
"""

from __future__ import annotations

import math


class StewartError(Exception):
    """Base class of every error raised on purpose by stewart-drake."""

    def _init_args(self) -> tuple:
        """The arguments that rebuild this error through ``type(self)(*args)``."""
        return self.args

    def __reduce__(self):
        # Exception's own reduce calls type(self)(*self.args) with the formatted message, which
        # a custom __init__ (leg, ratio, ...) refuses: unpickling in the parent would fail and a
        # process pool would report BrokenProcessPool instead of the refusal. The instance
        # dict restores the attributes, ``__notes__`` included.
        return type(self), self._init_args(), self.__dict__


class InvalidGeometryError(StewartError, ValueError):
    """A geometry (lengths, anchors, inertias) that cannot describe a real robot."""


class InvalidConfigError(StewartError, ValueError):
    """A simulation or controller setting out of its valid range."""


class CorruptFileError(InvalidConfigError):
    """A file that is not a valid X: truncated, random bytes, empty, an entry missing or of the
    wrong type, another format version, bad JSON or YAML, a failed CRC.

    One class for every file stewart-drake reads (tuner weights, collected runs and their
    manifest, evaluation rows, scenario YAML, run results). An :class:`InvalidConfigError` (and
    so a ``ValueError``): a bad file is bad input.

    Attributes:
        path: the file (str).  kind: what it should have been ("ANN tuner weights file", ...).
        problem: what is wrong with it.  remedy: what to do about it ("" if nothing to add).
    """

    def __init__(self, path, kind: str, problem: str, remedy: str = ""):
        self.path = str(path)
        self.kind = str(kind)
        self.problem = str(problem)
        self.remedy = str(remedy)
        super().__init__(
            f"{self.path} is not a valid {self.kind}: {self.problem}"
            + (f"; {self.remedy}" if self.remedy else "")
        )

    def _init_args(self) -> tuple:
        return self.path, self.kind, self.problem, self.remedy


class UnreachablePoseError(StewartError, ValueError):
    """A pose that one leg cannot reach: |L| / sqrt(M^2 + N^2) > 1 (paper eq. 6).

    Attributes:
        leg: index 0..5 of the first leg that cannot close (reference_geometry.md order).
        ratio: |L| / sqrt(M^2 + N^2) of that leg; > 1 means unreachable.
        t: time in s along a trajectory, or None for a single pose.
        pose: the (6,) pose [phi, theta, psi, X, Y, Z] that failed, if known.
    """

    def __init__(self, leg: int, ratio: float, t: float | None = None, pose=None):
        self.leg = int(leg)
        self.ratio = abs(float(ratio))  # callers may pass the signed L / sqrt(M^2 + N^2)
        self.t, self.pose, where = _locate(t, pose)
        value = (
            f"= {self.ratio:.4g} > 1"
            if not math.isnan(self.ratio)
            else "is not a number (M = N = 0: the platform joint is on the motor's axis)"
        )
        # A reference's pose (a time given) can be brought in by its amplitude; a single pose
        # (--pose, a measured one) only by itself.
        amplitude = " or reduce the trajectory's amplitude" if self.t is not None else ""
        super().__init__(
            f"leg {self.leg} cannot reach the pose{where}: |L|/sqrt(M^2+N^2) {value}. Bring "
            f"the pose closer to home [0, 0, 0, 0, 0, 0.30]{amplitude}."
        )

    def _init_args(self) -> tuple:
        return self.leg, self.ratio, self.t, self.pose


class RiccatiSolveError(StewartError, RuntimeError):
    """The discrete algebraic Riccati equation (paper eqs. 31-32) had no stabilizing solution."""


class NotStabilizableError(StewartError, ValueError):
    """The LQI's error model fails the Hautus test at a pose (paper eqs. 28-29): some mode with
    |lambda| >= 1 cannot be moved by the motors (rank [lambda I - A, B] < n) or is not seen by
    the cost (rank [lambda I - A; C] < n), so no gain stabilizes it.

    Attributes:
        stabilizable, detectable: the two verdicts.  rank_AB, rank_AC: the smallest ranks
        found, of n (the error model's states).  pose: the (6,) pose [rad, m], if known.
    """

    def __init__(self, checks: dict, pose=None):
        self.checks = dict(checks)
        self.stabilizable = bool(checks["stabilizable"])
        self.detectable = bool(checks["detectable"])
        self.rank_AB, self.rank_AC, self.n = (int(checks[k]) for k in ("rank_AB", "rank_AC", "n"))
        self.pose = None if pose is None else [float(v) for v in pose]
        failed = "; ".join(
            text
            for ok, text in (
                (
                    self.stabilizable,
                    f"not stabilizable (rank [lambda I - A, B] = {self.rank_AB}"
                    f" < {self.n}): the motors' input matrix B(x) is rank "
                    f"deficient there",
                ),
                (
                    self.detectable,
                    f"not detectable (rank [lambda I - A; C] = {self.rank_AC} < "
                    f"{self.n}): a scale of LqiScales is infinite or zero",
                ),
            )
            if not ok
        )
        where = (
            ""
            if self.pose is None
            else " at pose [phi, theta, psi, X, Y, Z] = ["
            + ", ".join(f"{v:.4g}" for v in self.pose)
            + "]"
        )
        super().__init__(
            f"the LQI's error model fails the Hautus test (paper eqs. 28-29){where}: {failed}. "
            f"Start the controller at a pose away from singularities (x_initial, the "
            f"reference's start) or check the robot's geometry, robot.platform_mass, "
            f"robot.platform_inertia and the other masses and inertias (kg, kg m^2): motors that "
            f"barely move the platform leave it uncontrollable"
        )

    def _init_args(self) -> tuple:
        return self.checks, self.pose


class SimulationDivergedError(StewartError, RuntimeError):
    """A simulation left its safe envelope; the data up to then is saved at ``path``."""

    def __init__(self, message: str, t: float, path: str | None = None):
        self.message = str(message)
        self.t = float(t)
        self.path = path
        saved = f"; data up to then saved in {path}" if path else ""
        super().__init__(f"simulation diverged at t = {self.t:.4g} s: {message}{saved}")

    def _init_args(self) -> tuple:
        return self.message, self.t, self.path


class ForwardKinematicsError(StewartError, RuntimeError):
    """Newton iteration of the forward kinematics did not converge."""


class RenderToolMissingError(StewartError, RuntimeError):
    """An external renderer (Graphviz ``dot``, a browser) needed for a picture is not installed."""


class JointLimitError(StewartError, ValueError):
    """A pose every leg can close but where a leg leaves the range of a joint.

    The limits are fields of :class:`~stewart_drake.robot.geometry.StewartGeometry` (motor travel,
    ball-joint cones); ``limits.limit_margins`` computes them.

    Attributes:
        leg: index 0..5 of the leg (reference_geometry.md order).
        limit: "motor_angle", "crank_joint" or "platform_joint" (``limits.LIMITS``).
        margin: how far inside the limit, rad; < 0 here.
        t: time in s along a trajectory, or None.
        pose: the (6,) pose [phi, theta, psi, X, Y, Z] that failed, if known.
    """

    _FIELD = {
        "motor_angle": "motor_angle_min_deg / motor_angle_max_deg",
        "crank_joint": "crank_joint_cone_deg",
        "platform_joint": "platform_joint_cone_deg",
    }

    def __init__(self, leg: int, limit: str, margin: float, t: float | None = None, pose=None):
        self.leg = int(leg)
        self.limit = str(limit)
        self.margin = float(margin)
        self.t, self.pose, where = _locate(t, pose)
        super().__init__(
            f"leg {self.leg} leaves its {self.limit} limit by {math.degrees(-self.margin):.3g}"
            f" deg{where}. Reduce the trajectory's amplitude, or widen "
            f"StewartGeometry.{self._FIELD.get(self.limit, self.limit)} if the hardware allows."
        )

    def _init_args(self) -> tuple:
        return self.leg, self.limit, self.margin, self.t, self.pose


class SingularPoseError(StewartError, ValueError):
    """A pose (or a path) too close to a singularity of the Jacobian J = d theta / d x.

    Two measures (``kinematics.singularity_measures``): ``cond`` = cond(J), large where the
    rods' wrenches become dependent (the motors cannot hold the platform in some direction)
    and ``sigma_min_inv`` = 1 / sigma_max(J), small at a dead point (a crank aligned with its
    rod: the motors cannot move the platform in some direction; cond(J) can stay moderate there
    when every leg reaches it at once).

    Attributes:
        measure: "cond" or "sigma_min_inv" (or "J" for a Jacobian that is not finite).
        value: the measure at the pose. threshold: the bound it crossed.
        t: time in s along a trajectory, or None.  pose: the (6,) pose, if known.
    """

    def __init__(
        self, measure: str, value: float, threshold: float, t: float | None = None, pose=None
    ):
        self.measure = str(measure)
        self.value = float(value)
        self.threshold = float(threshold)
        self.t, self.pose, where = _locate(t, pose)
        what = {
            "cond": f"cond(J) = {self.value:.4g} > {self.threshold:g} (the motors are about to "
            f"lose the ability to hold the platform in some direction)",
            "sigma_min_inv": f"1/sigma_max(J) = {self.value:.4g} < {self.threshold:g} "
            f"(rad or m) per rad (a crank near its dead point: the motors "
            f"are about to lose the ability to move the platform)",
        }.get(self.measure, f"{self.measure} = {self.value:.4g} is not finite (a singular pose)")
        super().__init__(
            f"the pose is too close to a singularity{where}: {what}. Keep the "
            f"path nearer the home pose [0, 0, 0, 0, 0, 0.30], or change the threshold "
            f"(GuardConfig.cond_threshold / min_sigma_min_inv) if you know the margin is enough."
        )

    def _init_args(self) -> tuple:
        return self.measure, self.value, self.threshold, self.t, self.pose


class InterferenceError(StewartError, ValueError):
    """Two parts of the robot closer than the clearance a reference must keep (or overlapping).

    Measured on the collision geometry by Drake's ``SceneGraph``
    (:mod:`~stewart_drake.plant.clearance`).

    Attributes:
        part_a, part_b: "link/shape" names, e.g. "rod_2/tube", "base/plate".
        clearance: their signed distance, m (negative: they overlap).
        margin: the smallest clearance allowed, m (``GuardConfig.min_clearance_m``).
        t: time in s along a trajectory, or None.  pose: the (6,) pose, if known.
    """

    def __init__(
        self,
        part_a: str,
        part_b: str,
        clearance: float,
        margin: float,
        t: float | None = None,
        pose=None,
    ):
        self.part_a, self.part_b = str(part_a), str(part_b)
        self.clearance, self.margin = float(clearance), float(margin)
        self.t, self.pose, where = _locate(t, pose)
        how = (
            f"overlap by {-self.clearance * 1e3:.3g} mm"
            if self.clearance < 0
            else f"are {self.clearance * 1e3:.3g} mm apart"
        )
        super().__init__(
            f"{self.part_a} and {self.part_b} {how}{where}, less than the "
            f"{self.margin * 1e3:.3g} mm the path must keep between parts. Keep the path "
            f"nearer home, or lower GuardConfig.min_clearance_m if the parts allow it."
        )

    def _init_args(self) -> tuple:
        return self.part_a, self.part_b, self.clearance, self.margin, self.t, self.pose


class MotorLimitError(StewartError, ValueError):
    """A motion that needs more torque or speed from a motor than its servo gives.

    The need is the closed chain's inverse dynamics with the motors' reflected inertia and
    friction (:func:`~stewart_drake.robot.statics.motor_effort`).

    Attributes:
        motor: index 0..5 (reference_geometry.md leg order).
        quantity: "torque" (N m) or "speed" (rad/s, at the crank).
        required: what the motion needs (absolute value). limit: what the reference may use
            (the servo's peak torque or no-load speed times ``GuardConfig.effort_margin``).
        t: time in s along a trajectory, or None.  pose: the (6,) pose, if known.
    """

    def __init__(
        self,
        motor: int,
        quantity: str,
        required: float,
        limit: float,
        t: float | None = None,
        pose=None,
    ):
        self.motor, self.quantity = int(motor), str(quantity)
        self.required, self.limit = float(required), float(limit)
        self.t, self.pose, where = _locate(t, pose)
        unit = "N m" if self.quantity == "torque" else "rad/s"
        #: What the motion asks of which motor, when, and by how much over the limit: the
        #: error's first sentence, and the warning's when the run goes on anyway.
        self.need = (
            f"motor {self.motor} would need {self.required:.3g} {unit} of "
            f"{self.quantity}{where}, {_percent(100 * (self.required / self.limit - 1))}"
            f" % over the {self.limit:.3g} {unit} a reference may use"
        )
        super().__init__(
            f"{self.need}. Slow the motion or reduce its amplitude, or set "
            f"guard.allow_infeasible: true to run it anyway (the motors will saturate)."
        )

    def _init_args(self) -> tuple:
        return self.motor, self.quantity, self.required, self.limit, self.t, self.pose


class ResultsMismatchError(StewartError, ValueError):
    """An output folder that holds results of other settings or of another command.

    Raised before any work (``collect``, ``evaluate``) and before reading (``train``), so runs of
    two settings are never mixed; the message names the folder and the settings that differ.
    """


class FolderInUseError(StewartError, RuntimeError):
    """A study folder another running study is writing (its lock is held); names that writer.

    Attributes:
        folder: the folder (str).  holder: who holds it, as its lock file says ("pid 1234 on
            host, `stewart-drake evaluate`, since ..."), or "" if unknown.
    """

    def __init__(self, folder, holder: str = ""):
        self.folder = str(folder)
        self.holder = str(holder)
        who = self.holder or "its writer did not say who it is"
        super().__init__(
            f"{self.folder} is being written by another study ({who}): wait for it "
            f"to finish, or choose another --out"
        )

    def _init_args(self) -> tuple:
        return self.folder, self.holder


class IncompleteResultsError(StewartError, RuntimeError):
    """A study whose results are not all on disk: jobs lost with their worker, failed, or not
    run yet. What finished is kept; the same command run again runs only what is missing."""


class MissingFileError(StewartError, FileNotFoundError):
    """An input file (tuner weights, collected runs) that does not exist; says what makes it."""


class MissingExtraError(StewartError, ImportError):
    """An optional dependency (an extra of the package) is not installed; says which to install."""


class BusError(StewartError, RuntimeError):
    """A servo bus that failed: the port does not open, a servo does not answer or answers with
    an error, a reply is corrupt. The message names the port, the servo and the instruction.
    Whoever raises it has already tried to remove the servos' torque.

    Attributes:
        failure: the failure alone, without the verdict on that torque-off (str; set by the
            driver, whose message ends with the verdict), or None.
    """

    failure: str | None = None


class StartPoseError(StewartError, ValueError):
    """The robot's measured pose is not one a run may start from (outside the admissible set,
    no pose of the robot, or moved while the servos were configured); nothing was powered."""


class LoopStalledError(BusError):
    """Our watchdog found the control loop stalled (no period completed within its limit) and
    removed the servos' torque; the run ends at the loop's next step."""


class MissingServoError(BusError):
    """A servo id that does not answer a PING on the bus.

    Attributes:
        servo_id: the id that did not answer.  port: the serial port (str).
    """

    def __init__(self, servo_id: int, port: str):
        self.servo_id, self.port = int(servo_id), str(port)
        super().__init__(
            f"servo id {self.servo_id} does not answer on {self.port}: check its power, cable "
            f"and id (ROBOTIS DYNAMIXEL Wizard scans a bus), and the baud rate"
        )

    def _init_args(self) -> tuple:
        return self.servo_id, self.port


class ServoConfigMismatchError(BusError):
    """A servo setting read back after writing it that differs from what was written (a servo
    that refuses a value, or another model than the one named).

    Attributes:
        servo_id: the servo.  item: the control-table item ("Current Limit", ...).
        wrote: the value written (raw units).  read: the value read back (raw units).
    """

    def __init__(self, servo_id: int, item: str, wrote: int, read: int):
        self.servo_id, self.item = int(servo_id), str(item)
        self.wrote, self.read = int(wrote), int(read)
        super().__init__(
            f"servo id {self.servo_id}: {self.item} reads back {self.read} after writing "
            f"{self.wrote}: check the servo's model and firmware (torque was left off)"
        )

    def _init_args(self) -> tuple:
        return self.servo_id, self.item, self.wrote, self.read


class LiveSourceError(StewartError, RuntimeError):
    """A live source of poses the robot follows that failed: no sample within its timeout, a
    sample out of order, repeated or not six finite numbers, samples spaced otherwise than the
    stream's rate, or too many missing at once. The message names the channel and the sample;
    the session that follows the source removes the torque."""


class DeadlineMissError(BusError):
    """A control loop on the servo bus that started too many periods late: more than its
    scenario's ``bus.max_deadline_misses`` periods began over one period after their scheduled
    wall-clock time. The servos' torque was removed first.

    Attributes:
        misses: the periods missed so far.  limit: ``bus.max_deadline_misses``.
        period_s: the control period, s.  late_s: how late the last period started, s.
        t: the Diagram time of that period, s.
    """

    def __init__(self, misses: int, limit: int, period_s: float, late_s: float, t: float):
        self.misses, self.limit = int(misses), int(limit)
        self.period_s, self.late_s, self.t = float(period_s), float(late_s), float(t)
        super().__init__(
            f"the control loop missed {self.misses} deadlines (more than "
            f"bus.max_deadline_misses = {self.limit}); the last period, at t = {self.t:.3f} s, "
            f"started {1e3 * self.late_s:.1f} ms late for a {1e3 * self.period_s:g} ms period; "
            f"torque off. Lengthen control_period_s, unload the machine or raise the limit"
        )

    def _init_args(self) -> tuple:
        return self.misses, self.limit, self.period_s, self.late_s, self.t


def _percent(p: float) -> str:
    """A percentage: whole from 1 % up, two significant digits below it (an excess of 0.028 %
    does not read as "0 %" beside two limits that round alike)."""
    return f"{p:.0f}" if abs(p) >= 1 else f"{p:.2g}"


def _locate(t: float | None, pose) -> tuple[float | None, list[float] | None, str]:
    """An error's ``t`` (s or None) and ``pose`` (list or None), and " at t = ... (pose ...)"."""
    t = None if t is None else float(t)
    pose = None if pose is None else [float(v) for v in pose]
    where = "" if t is None else f" at t = {t:.4g} s"
    if pose is not None:
        where += (
            " (pose [phi, theta, psi, X, Y, Z] = [" + ", ".join(f"{v:.4g}" for v in pose) + "])"
        )
    return t, pose, where


class FeasibilityWarning(UserWarning):
    """A reference run although a motor cannot give what it needs (``guard.allow_infeasible``):
    the motors saturate and the platform falls behind the reference."""
