"""A calibration rehearsed on an emulated robot, and the study of its accuracy that
docs/calibration.md tabulates.

A rehearsal draws a robot as built (:class:`~stewart_drake.robot.tolerances.Tolerances`, a seed),
measures it at the poses chosen (:func:`~.poses.choose_poses`) or at random ones from the same
candidates with the emulated tracker and encoders (:func:`~.tracker.measure`), identifies it
(:func:`~.identify.identify`) and predicts the readings at held-out poses (other admissible
poses, drawn with another seed): the RMS of predicted minus read (quantized at the true pose),
with the nominal robot (before) and the identified one (after), beside the bound the
identification's covariance predicts (:func:`~.validation.predicted_rms`), and the same after
the prediction from the tracker's measurement of the held-out poses (what a user validating
with the tracker sees: the tracker's own noise included). With a tracker set up as a real one
stands (:class:`~.tracker.TrackerSetup`: its own frame, a marker off the platform frame), the
tracker measures the marker in its frame and fiducials besides; the frames registered from the
fiducials (:mod:`~.registration`) convert its poses to the base frame before the identification,
and the held-out readings are predicted from the true base-frame poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.fileio import atomic_write, write_between_markers
from ..base.tables import markdown_lines
from ..robot.geometry import StewartGeometry
from ..robot.legs import LegParameters, readings
from ..robot.tolerances import Tolerances
from .identify import Identification, identify
from .poses import candidate_poses, choose_poses, information_rows
from .registration import DEFAULT_POINT_SIGMA_M, Registration, register, register_poses
from .tracker import MeasurementNoise, TrackerSetup, measure, quantize
from .validation import predicted_rms

#: The ways a rehearsal's poses are picked from the candidates.
SELECTIONS = ("chosen", "random")
#: Seeds of the candidates and of the held-out poses (fixed: every rehearsal of a study sees the
#: same workspace; the robot and the noise change with the rehearsal's seed).
CANDIDATE_SEED = 1
HELD_OUT_SEED = 2


@dataclass(frozen=True)
class Workspace:
    """The poses a rehearsal draws from: candidates (C, 6) and held-out poses (H, 6), rad and
    m."""

    candidates: np.ndarray
    held_out: np.ndarray


def setup_of_registration(registration) -> tuple:
    """(the :class:`~.tracker.TrackerSetup` a registration describes: the tracker and its marker
    at its frames, its fiducials where its drawing puts them; their noise, m), or (None, the
    default noise) for ``registration`` None.

    Args:
        registration: (:class:`~.registration.Registration`, its fiducials as read from
            REG.yaml) or None.
    """
    if registration is None:
        return None, DEFAULT_POINT_SIGMA_M
    reg, fiducials = registration
    setup = TrackerSetup(reg.X_TB, reg.X_PM, fiducials.base_B, fiducials.platform_P)
    return setup, fiducials.point_sigma_m


def workspace(
    geometry: StewartGeometry, n_candidates: int = 2000, n_held_out: int = 50, motor_limits=None
) -> Workspace:
    """Candidates and held-out poses, admissible with margin (:func:`~.poses.candidate_poses`,
    seeds :data:`CANDIDATE_SEED` and :data:`HELD_OUT_SEED`)."""
    return Workspace(
        candidate_poses(geometry, n_candidates, CANDIDATE_SEED, motor_limits=motor_limits),
        candidate_poses(geometry, n_held_out, HELD_OUT_SEED, motor_limits=motor_limits),
    )


def pick(
    geometry: StewartGeometry,
    space: Workspace,
    count: int,
    selection: str,
    noise: MeasurementNoise,
    tolerances: Tolerances,
    seed: int,
) -> np.ndarray:
    """(count,) indices into the candidates: the greedy D-optimal choice ("chosen") or
    ``count`` drawn at random with ``seed`` ("random").

    Raises:
        InvalidConfigError: another selection, or more poses than candidates.
    """
    if selection not in SELECTIONS:
        raise InvalidConfigError(
            f"the selection is one of {', '.join(SELECTIONS)}, got {selection!r}"
        )
    if count > len(space.candidates):
        raise InvalidConfigError(f"{count} poses from {len(space.candidates)} candidates")
    if selection == "chosen":
        return choose_poses(information_rows(geometry, space.candidates, noise, tolerances), count)
    return np.random.default_rng(seed + 10_000).choice(len(space.candidates), count, replace=False)


@dataclass(frozen=True)
class Rehearsal:
    """One rehearsal's figures (module docstring); RMS over the held-out poses' readings, rad.

    Attributes:
        poses, selection, noise, seed: what was rehearsed.
        before_rad: the nominal robot's readings against the readings.
        after_rad: the identified robot's, from the true poses.
        after_tracked_rad: the identified robot's, from the tracker's measurement of them.
        bound_rad: what the identification's covariance predicts for ``after_rad``.
        weak: combinations known mostly from the tolerances.  chi2_reduced: of the fit.
        identification: the :class:`~.identify.Identification`.
        truth: the robot drawn, :class:`~stewart_drake.robot.legs.LegParameters`.
        registration: the frames registered from the emulated fiducials, or None (the tracker
            measured the platform frame in the base frame).
    """

    poses: int
    selection: str
    noise: MeasurementNoise
    seed: int
    before_rad: float
    after_rad: float
    after_tracked_rad: float
    bound_rad: float
    weak: int
    chi2_reduced: float
    identification: Identification
    truth: LegParameters
    registration: Registration | None = None

    def row(self) -> dict:
        """The figures as a flat dict (JSON)."""
        return {
            "poses": self.poses,
            "selection": self.selection,
            "translation_m": self.noise.translation_m,
            "rotation_rad": self.noise.rotation_rad,
            "seed": self.seed,
            "before_rad": self.before_rad,
            "after_rad": self.after_rad,
            "after_tracked_rad": self.after_tracked_rad,
            "bound_rad": self.bound_rad,
            "weak": self.weak,
            "chi2_reduced": self.chi2_reduced,
        }


def rehearse(
    geometry: StewartGeometry,
    space: Workspace,
    indices,
    noise: MeasurementNoise,
    seed: int,
    tolerances: Tolerances | None = None,
    selection: str = "random",
    setup: TrackerSetup | None = None,
    point_sigma_m: float = DEFAULT_POINT_SIGMA_M,
) -> Rehearsal:
    """Draw a robot with ``seed``, measure it at the candidates ``indices``, identify it and
    predict its readings at the held-out poses (module docstring); with a ``setup``, the
    tracker measures in its frame, its fiducials with ``point_sigma_m`` of noise, and the
    frames they register convert its poses."""
    tolerances = Tolerances() if tolerances is None else tolerances
    truth = tolerances.draw(geometry, seed)
    x = space.candidates[np.asarray(indices)]
    data = measure(geometry, truth, x, noise, seed, setup=setup)
    H = space.held_out
    read = quantize(readings(geometry, truth, H), noise.counts_per_rev)
    checked = measure(geometry, truth, H, noise, seed + 20_000, setup=setup)  # held-out poses
    reg = None
    if setup is None:
        ident = identify(geometry, data.poses, data.readings, noise, tolerances)
        seen = checked.poses
    else:
        reg = register(setup.fiducials(noise, seed + 30_000, point_sigma_m), "the fiducials")
        moved = register_poses(reg, data.poses, noise.rotation_rad, noise.translation_m)
        ident = identify(
            geometry,
            moved.poses,
            data.readings,
            noise,
            tolerances,
            pose_covariances=moved.pose_covariances,
            frames=moved.frames,
        )
        seen = reg.base_poses(checked.poses)

    def rms(a, b):
        return float(np.sqrt(np.mean((a - b) ** 2)))

    return Rehearsal(
        poses=len(x),
        selection=selection,
        noise=noise,
        seed=seed,
        before_rad=rms(readings(geometry, ident.nominal, H), read),
        after_rad=rms(readings(geometry, ident.identified, H), read),
        after_tracked_rad=rms(readings(geometry, ident.identified, seen), read),
        bound_rad=predicted_rms(geometry, ident, H, noise),
        weak=len(ident.weak),
        chi2_reduced=ident.chi2_reduced,
        identification=ident,
        truth=truth,
        registration=reg,
    )


#: The study of docs/calibration.md: pose counts, noise levels (m, rad), seeds.
STUDY_POSES = (20, 40, 60, 80, 120)
STUDY_NOISE = ((5e-6, 20e-6), (20e-6, 50e-6))
STUDY_SEEDS = tuple(range(10))


def study(
    geometry: StewartGeometry,
    poses=STUDY_POSES,
    noise_levels=STUDY_NOISE,
    seeds=STUDY_SEEDS,
    motor_limits=None,
    progress: bool = False,
) -> list[dict]:
    """Rehearsals over pose counts, noise levels, both selections and seeds, on the poses of
    :func:`workspace` (``motor_limits``: the robot's, or None); their :meth:`Rehearsal.row` s.
    The chosen poses are one greedy choice per noise level (a prefix for fewer poses), the
    random ones a draw per seed."""
    from tqdm import tqdm

    space = workspace(geometry, motor_limits=motor_limits)
    tolerances = Tolerances()
    rows = []
    total = len(noise_levels) * len(poses) * len(SELECTIONS) * len(seeds)
    with tqdm(total=total, desc="rehearsals", disable=not progress) as bar:
        for translation, rotation in noise_levels:
            noise = MeasurementNoise(translation, rotation)
            chosen = pick(geometry, space, max(poses), "chosen", noise, tolerances, 0)
            for n in poses:
                for selection in SELECTIONS:
                    for seed in seeds:
                        idx = (
                            chosen[:n]
                            if selection == "chosen"
                            else pick(geometry, space, n, "random", noise, tolerances, seed)
                        )
                        r = rehearse(geometry, space, idx, noise, seed, tolerances, selection)
                        rows.append(r.row())
                        bar.update(1)
    return rows


#: The accuracy goal of docs/calibration.md: the RMS, urad, that 60 random poses must reach for
#: each tracker noise (m, rad).
ACCEPTANCE_URAD = {(5e-6, 20e-6): 35.0, (20e-6, 50e-6): 110.0}
#: Where docs/calibration.md holds the study's table.
TABLE_MARKERS = (
    "<!-- calibration table: generated by tools/calibration_tables.py "
    "(stewart_drake.calibration.rehearsal) -->",
    "<!-- end of calibration table -->",
)


def table(rows: list[dict]) -> str:
    """The study's rows as a markdown table between :data:`TABLE_MARKERS`: per noise level,
    pose count and selection, the RMS of the held-out readings' prediction in urad (mean and
    worst over the seeds, with how many seeds exceed :data:`ACCEPTANCE_URAD` for the noise level),
    the covariance's bound, the prediction from the tracker's poses, before (mean and range,
    mrad), and the combinations known mostly from the tolerances."""
    keys = sorted(
        {(r["translation_m"], r["rotation_rad"], r["poses"], r["selection"]) for r in rows},
        key=lambda k: (k[0], k[1], k[2], SELECTIONS.index(k[3])),
    )
    lines = [
        TABLE_MARKERS[0],
        "",
    ]
    header = ["tracker noise", "poses", "picked", "seeds", "after: mean (worst)"]
    header += ["seeds over the figure", "bound", "after, from the tracker's poses"]
    header += ["before: mean (range)", "known from the tolerances"]
    cells = []
    for key in keys:
        group = [
            r
            for r in rows
            if (r["translation_m"], r["rotation_rad"], r["poses"], r["selection"]) == key
        ]
        after = np.array([r["after_rad"] for r in group]) * 1e6
        before = np.array([r["before_rad"] for r in group]) * 1e3
        figure = ACCEPTANCE_URAD.get((key[0], key[1]))
        over = "" if figure is None else f"{int(np.sum(after > figure))} over {figure:g}"
        cells.append(
            [f"{key[0] * 1e6:g} um / {key[1] * 1e6:g} urad", key[2], key[3], len(group)]
            + [f"{np.mean(after):.1f} ({np.max(after):.1f})", over]
            + [f"{np.mean([r['bound_rad'] for r in group]) * 1e6:.1f}"]
            + [f"{np.mean([r['after_tracked_rad'] for r in group]) * 1e6:.1f}"]
            + [f"{np.mean(before):.2f} ({np.min(before):.2f}-{np.max(before):.2f})"]
            + [f"{np.mean([r['weak'] for r in group]):.1f}"]
        )
    lines += markdown_lines(header, cells) + ["", TABLE_MARKERS[1]]
    return "\n".join(lines)


def write_table(doc, rows: list[dict]):
    """Put :func:`table` between :data:`TABLE_MARKERS` in ``doc``, and the rows it comes from
    in ``doc`` with the suffix .json."""
    import json
    from pathlib import Path

    doc = Path(doc)
    text = json.dumps(rows, indent=0)
    atomic_write(doc.with_suffix(".json"), lambda f: f.write(text.encode()))
    return write_between_markers(doc, TABLE_MARKERS, table(rows))
