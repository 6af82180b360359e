"""The error budget of a calibrated robot: what each of a real laboratory's imperfections costs
the platform's pose, beside the ideal calibration.

A calibration (:mod:`~.identify`) is rehearsed as :mod:`~.rehearsal` does (a robot drawn with
the tolerances, measured at poses picked among the candidates, identified), with one or more of
the imperfections of a :class:`Laboratory` added; then the identified robot is *used*: at each
held-out pose x the controller drives the encoders to the readings the identified robot gives
for x (:func:`~stewart_drake.robot.legs.readings`), and the robot as built settles where its
cranks are at those readings (its encoder zeros, its encoders' cyclic error, its temperature),
by its own forward kinematics (:func:`~stewart_drake.robot.forward_kinematics.fk`). The
platform's static error is that pose against x: the translation's norm and the rotation's angle,
RMS over the held-out poses (:func:`static_error`). It leaves out the controller's own tracking
error, which a run adds (docs/calibration.md, "What calibration does to the figures users
read").

The imperfections (:class:`Laboratory`):

- the tracker's noise (:class:`~.tracker.MeasurementNoise`);
- gross errors among the poses (a marker seen wrongly): ``blunders`` poses moved by
  :data:`BLUNDER_M` in a random direction, left to the identification's outlier rejection;
- the registration: either a tracker standing as a real one does (1 m / 30 deg from the base, a
  marker 50 mm off the platform frame: :func:`~.tracker.emulated_setup`) registered by
  ``fiducials`` fiducials a body measured at ``point_sigma_m`` (:mod:`~.registration`), or the
  poses handed over in a base frame that is off by a rigid motion of ``frame_m`` and
  ``frame_rad`` (a registration made elsewhere and believed exact);
- the encoders' cyclic error: each reads theta + offset + A sin(theta + phase_i), one cycle a
  turn, A = ``cyclic_rad``, the phases drawn with the robot (the calibration and the run see the
  same error; the identification knows nothing of it);
- the temperature: the run ``delta_k`` kelvin above the calibration, the controller not told
  (:meth:`~stewart_drake.robot.geometry.StewartGeometry.at_temperature`).

:func:`budget_rows` measures the rows of :data:`BUDGET` over robots drawn with seeds;
:func:`budget_table` makes docs/calibration.md's table ("The error budget";
``tools/calibration_budget.py`` regenerates it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from scipy.spatial.transform import Rotation

from ..base.checks import as_number, check_int
from ..base.errors import InvalidConfigError
from ..base.tables import markdown_lines
from ..robot.forward_kinematics import fk
from ..robot.geometry import StewartGeometry
from ..robot.kinematics import rotation_rpy
from ..robot.legs import LegParameters, leg_ik, readings
from ..robot.tolerances import Tolerances
from .identify import identify
from .registration import DEFAULT_POINT_SIGMA_M, Registration, register, register_poses
from .rehearsal import Workspace, pick
from .tracker import MeasurementNoise, emulated_setup, noisy_poses, quantize

#: How far a blunder moves a pose, m (a marker seen on the wrong reflector: millimetres).
BLUNDER_M = 1e-3


@dataclass(frozen=True)
class Laboratory:
    """What a calibration and the run after it face (module docstring).

    Attributes:
        noise: the tracker's noise and the encoders' counts.
        poses: how many poses are measured.
        selection: "chosen" or "random" (:func:`~.rehearsal.pick`).
        blunders: poses among them moved by :data:`BLUNDER_M`, >= 0.
        fiducials: > 0: the tracker stands 1 m / 30 deg from the base, its marker 50 mm off the
            platform frame, and this many fiducials a body register it; 0: the tracker measures
            the platform frame in the base frame.
        point_sigma_m: the fiducials' noise per axis, m.
        frame_m, frame_rad: the base frame the poses are handed over in is off by a rigid motion
            of this translation (m) and rotation (rad), each in a random direction; >= 0.
        cyclic_rad: the encoders' cyclic error's amplitude, rad, >= 0.
        delta_k: the run's temperature minus the calibration's, K; the controller is not told.
    Raises:
        InvalidConfigError: a value out of its range.
    """

    noise: MeasurementNoise = field(default_factory=MeasurementNoise)
    poses: int = 60
    selection: str = "chosen"
    blunders: int = 0
    fiducials: int = 0
    point_sigma_m: float = DEFAULT_POINT_SIGMA_M
    frame_m: float = 0.0
    frame_rad: float = 0.0
    cyclic_rad: float = 0.0
    delta_k: float = 0.0

    def __post_init__(self):
        check_int("poses", self.poses, 1, 100_000)
        check_int("blunders", self.blunders, 0, self.poses)
        check_int("fiducials", self.fiducials, 0, 1000)
        if self.fiducials and (self.frame_m or self.frame_rad):
            raise InvalidConfigError(
                "a laboratory either registers its tracker by fiducials or hands over poses in a "
                "frame that is off, not both"
            )
        for name in ("point_sigma_m", "frame_m", "frame_rad", "cyclic_rad"):
            as_number(name, getattr(self, name), 0.0)
        as_number("delta_k", self.delta_k, -100.0, 100.0)


@dataclass(frozen=True)
class StaticError:
    """One calibrated robot's static error over the held-out poses (module docstring).

    Attributes:
        translation_m, rotation_rad: (H,) the translation's norm, m, and the rotation's angle,
            rad, of where the robot settles against each held-out pose.
        readings_rad: RMS over the held-out poses' readings of the identified robot's prediction
            against the robot's own readings there (what :mod:`~.rehearsal` measures), rad.
        dropped: poses the identification dropped as outliers.
        settled: (H, 6) where the robot settled, [rad, m].
    """

    translation_m: np.ndarray
    rotation_rad: np.ndarray
    readings_rad: float
    dropped: int
    settled: np.ndarray

    @property
    def translation_rms_m(self) -> float:
        return float(np.sqrt(np.mean(self.translation_m**2)))

    @property
    def rotation_rms_rad(self) -> float:
        return float(np.sqrt(np.mean(self.rotation_rad**2)))


def _direction(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _cyclic(theta, amplitude: float, phases: np.ndarray) -> np.ndarray:
    return amplitude * np.sin(np.asarray(theta) + phases)


def _settled(
    geometry: StewartGeometry,
    truth: LegParameters,
    target_readings: np.ndarray,
    x_guess: np.ndarray,
    amplitude: float,
    phases: np.ndarray,
    delta_k: float,
) -> np.ndarray:
    """(H, 6) where the robot as built settles with its encoders at ``target_readings`` (H, 6):
    its crank angles from theta + offset + cyclic(theta) = reading (a fixed point: the cyclic
    error's slope is far below 1), then its forward kinematics at its temperature."""
    theta = target_readings - truth.encoder_offsets_rad
    for _ in range(60):
        step = target_readings - truth.encoder_offsets_rad - _cyclic(theta, amplitude, phases)
        done = np.max(np.abs(step - theta)) < 1e-15
        theta = step
        if done:
            break
    built = truth.geometry(geometry)
    if delta_k:
        built = built.at_temperature(built.lengths_at_c + delta_k)
    x, _ = fk(built, theta, x0=x_guess)
    return x


def _pose_errors(x: np.ndarray, x_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    moved = np.linalg.norm(x[:, 3:] - x_ref[:, 3:], axis=-1)
    R = np.einsum("nij,nkj->nik", rotation_rpy(x[:, :3]), rotation_rpy(x_ref[:, :3]))
    cos = np.clip(0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    return moved, np.arccos(cos)


def frame_offset(lab: Laboratory, seed: int) -> RigidTransform:
    """X_B'B: where the base frame B' the poses are handed over in puts the true base frame B
    (poses measured as X_B'P = X_B'B X_BP), ``lab.frame_rad`` about and ``lab.frame_m`` along
    directions drawn with ``seed``."""
    rng = np.random.default_rng(check_int("seed", seed, 0, 2**32 - 1) + 50_000)
    turn = Rotation.from_rotvec(lab.frame_rad * _direction(rng)).as_matrix()
    return RigidTransform(RotationMatrix(turn), lab.frame_m * _direction(rng))


def static_error(
    geometry: StewartGeometry,
    space: Workspace,
    lab: Laboratory,
    seed: int,
    tolerances: Tolerances | None = None,
    indices=None,
) -> StaticError:
    """Calibrate a robot drawn with ``seed`` in ``lab`` and measure its static error at the
    held-out poses (module docstring).

    Args:
        geometry: the nominal robot.  space: the candidate and held-out poses.
        lab: the imperfections.  seed: the robot's draw (0 .. 2^32 - 1), and every noise's.
        tolerances: the robot's (default :class:`~stewart_drake.robot.tolerances.Tolerances`).
        indices: the candidates measured (default :func:`~.rehearsal.pick` by ``lab``'s
            selection: pass the chosen ones to reuse them across robots).
    Returns:
        :class:`StaticError`.
    Raises:
        InvalidConfigError: as :func:`~.identify.identify` (too few poses left), a seed out of
            range. ForwardKinematicsError: the robot cannot settle near a held-out pose.
    """
    tolerances = Tolerances() if tolerances is None else tolerances
    seed = check_int("seed", seed, 0, 2**32 - 1)
    rng = np.random.default_rng(seed + 40_000)
    truth = tolerances.draw(geometry, seed)
    phases = rng.uniform(0.0, 2.0 * np.pi, 6)
    if indices is None:
        indices = pick(geometry, space, lab.poses, lab.selection, lab.noise, tolerances, seed)
    x = space.candidates[np.asarray(indices)]
    noise = lab.noise

    def read(poses):
        theta = leg_ik(geometry, truth, poses)
        q = theta + truth.encoder_offsets_rad + _cyclic(theta, lab.cyclic_rad, phases)
        return quantize(q, noise.counts_per_rev)

    q = read(x)
    pose_covariances = frames = None
    if lab.fiducials:
        setup = emulated_setup(geometry, fiducials=lab.fiducials)
        seen = noisy_poses(setup.tracker_poses(x), noise, rng)
        reg = register(setup.fiducials(noise, seed + 30_000, lab.point_sigma_m), "the fiducials")
    else:
        zero = np.zeros((6, 6))
        reg = Registration(frame_offset(lab, seed), RigidTransform(), zero, zero, 0.0, 0.0)
        seen = noisy_poses(reg.tracker_poses(x), noise, rng)
    if lab.blunders:
        hit = rng.choice(len(seen), lab.blunders, replace=False)
        seen[hit, 3:] += BLUNDER_M * np.array([_direction(rng) for _ in hit])
    if lab.fiducials:
        moved = register_poses(reg, seen, noise.rotation_rad, noise.translation_m)
        poses, pose_covariances, frames = moved.poses, moved.pose_covariances, moved.frames
    else:
        poses = seen  # believed to be in the base frame
    ident = identify(
        geometry, poses, q, noise, tolerances, pose_covariances=pose_covariances, frames=frames
    )
    H = space.held_out
    target = readings(geometry, ident.identified, H)
    x_run = _settled(geometry, truth, target, H, lab.cyclic_rad, phases, lab.delta_k)
    moved_m, turned = _pose_errors(x_run, H)
    readings_rms = float(np.sqrt(np.mean((target - read(H)) ** 2)))
    return StaticError(moved_m, turned, readings_rms, int(np.sum(~ident.used)), x_run)


def uncalibrated_error(
    geometry: StewartGeometry, space: Workspace, seed: int, tolerances: Tolerances | None = None
) -> StaticError:
    """The static error of a robot drawn with ``seed`` whose controller believes the nominal
    robot (no calibration), as :func:`static_error` measures it."""
    tolerances = Tolerances() if tolerances is None else tolerances
    truth = tolerances.draw(geometry, check_int("seed", seed, 0, 2**32 - 1))
    H = space.held_out
    nominal = LegParameters.nominal(geometry)
    target = readings(geometry, nominal, H)
    x_run = _settled(geometry, truth, target, H, 0.0, np.zeros(6), 0.0)
    moved_m, turned = _pose_errors(x_run, H)
    own = quantize(readings(geometry, truth, H), MeasurementNoise().counts_per_rev)
    return StaticError(moved_m, turned, float(np.sqrt(np.mean((target - own) ** 2))), 0, x_run)


_IDEAL = Laboratory()
_MIX = Laboratory(
    noise=MeasurementNoise(10e-6, 35e-6), blunders=1, frame_m=50e-6, frame_rad=100e-6,
    cyclic_rad=100e-6,
)  # fmt: skip

#: The rows of docs/calibration.md's budget: (label, laboratory); None: the robot uncalibrated.
BUDGET: tuple[tuple[str, Laboratory | None], ...] = (
    ("uncalibrated (the controller believes the drawing)", None),
    ("ideal: tracker in the base frame, 5 um / 20 urad, 60 chosen poses, 17-bit encoders", _IDEAL),
    ("tracker 10 um / 35 urad", replace(_IDEAL, noise=MeasurementNoise(10e-6, 35e-6))),
    ("tracker 20 um / 50 urad", replace(_IDEAL, noise=MeasurementNoise(20e-6, 50e-6))),
    ("one blunder (a pose 1 mm off), rejected", replace(_IDEAL, blunders=1)),
    ("three blunders, rejected", replace(_IDEAL, blunders=3)),
    ("registered: 4 fiducials a body at 2 um, tracker 1 m / 30 deg, marker 50 mm off",
     replace(_IDEAL, fiducials=4)),
    ("registered: 8 fiducials a body at 2 um", replace(_IDEAL, fiducials=8)),
    ("a base frame 50 um / 100 urad off, believed exact",
     replace(_IDEAL, frame_m=50e-6, frame_rad=100e-6)),
    ("encoder cyclic error 100 urad", replace(_IDEAL, cyclic_rad=100e-6)),
    ("+1 K at the run, not compensated", replace(_IDEAL, delta_k=1.0)),
    ("+2 K at the run, not compensated", replace(_IDEAL, delta_k=2.0)),
    ("20 chosen poses", replace(_IDEAL, poses=20)),
    ("40 chosen poses", replace(_IDEAL, poses=40)),
    ("60 random poses", replace(_IDEAL, selection="random")),
    ("120 chosen poses", replace(_IDEAL, poses=120)),
    ("the mix: 10 um / 35 urad, one blunder, frame 50 um / 100 urad off, cyclic 100 urad", _MIX),
    ("the mix, +2 K at the run", replace(_MIX, delta_k=2.0)),
    ("the mix, 120 chosen poses", replace(_MIX, poses=120)),
    ("the mix registered by 8 fiducials a body instead",
     replace(_MIX, frame_m=0.0, frame_rad=0.0, fiducials=8)),
)  # fmt: skip


def budget_rows(
    geometry: StewartGeometry,
    space: Workspace,
    seeds,
    rows=BUDGET,
    tolerances: Tolerances | None = None,
    progress=None,
) -> list[dict]:
    """Measure each of ``rows`` ((label, :class:`Laboratory` or None) pairs) on the robots drawn
    with ``seeds``; the chosen poses are chosen once per noise and count (as ``calibrate
    --plan`` would).

    Returns:
        One dict per row: "label", "robots", and per robot lists "translation_um",
        "rotation_urad" (RMS over the held-out poses), "readings_urad", "dropped".
    """
    tolerances = Tolerances() if tolerances is None else tolerances
    seeds = [check_int("seed", s, 0, 2**32 - 1) for s in seeds]
    chosen: dict = {}
    out = []
    for label, lab in rows:
        found: dict = {
            "translation_um": [],
            "rotation_urad": [],
            "readings_urad": [],
            "dropped": [],
        }
        for seed in seeds:
            if lab is None:
                e = uncalibrated_error(geometry, space, seed, tolerances)
            else:
                idx = None
                if lab.selection == "chosen":
                    key = (lab.noise, lab.poses)
                    if key not in chosen:
                        chosen[key] = pick(
                            geometry, space, lab.poses, "chosen", lab.noise, tolerances, 0
                        )
                    idx = chosen[key]
                e = static_error(geometry, space, lab, seed, tolerances, idx)
            found["translation_um"].append(1e6 * e.translation_rms_m)
            found["rotation_urad"].append(1e6 * e.rotation_rms_rad)
            found["readings_urad"].append(1e6 * e.readings_rad)
            found["dropped"].append(e.dropped)
            if progress is not None:
                progress()
        out.append({"label": label, "robots": len(seeds), **found})
    return out


#: docs/calibration.md's markers around the budget table.
BUDGET_MARKERS = (
    "<!-- calibration budget: generated by tools/calibration_budget.py "
    "(stewart_drake.calibration.budget) -->",
    "<!-- end of calibration budget -->",
)


def budget_table(rows: list[dict]) -> str:
    """The rows of :func:`budget_rows` as a markdown table: mean (worst) over the robots of the
    static translation and rotation RMS and of the readings predicted, beside the ideal row's
    (the row whose label starts "ideal")."""

    def cell(values, fmt="{:.1f}"):
        v = np.asarray(values, dtype=float)
        return f"{fmt.format(v.mean())} ({fmt.format(v.max())})"

    ideal = next((r for r in rows if r["label"].startswith("ideal")), rows[0])
    base_t = float(np.mean(ideal["translation_um"]))
    base_r = float(np.mean(ideal["rotation_urad"]))
    body = [
        [
            r["label"],
            str(r["robots"]),
            cell(r["translation_um"]),
            f"{np.mean(r['translation_um']) / base_t:.1f}x",
            cell(r["rotation_urad"]),
            f"{np.mean(r['rotation_urad']) / base_r:.1f}x",
            cell(r["readings_urad"]),
            str(int(np.sum(r["dropped"]))),
        ]
        for r in rows
    ]
    head = [
        "laboratory",
        "robots",
        "translation RMS, um: mean (worst)",
        "/ ideal",
        "rotation RMS, urad: mean (worst)",
        "/ ideal",
        "readings predicted, urad: mean (worst)",
        "poses dropped",
    ]
    return "\n".join(markdown_lines(head, body))
