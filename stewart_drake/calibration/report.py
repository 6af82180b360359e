"""What ``stewart-drake calibrate`` prints and writes: the identified parameters with their
uncertainties, the combinations known mostly from the tolerances, the outliers dropped, the
residuals before and after, the accuracy to expect and the held-out check, the warnings; the
robot section; the planned path, checked as the robot command will check it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import InvalidConfigError
from ..robot.geometry import StewartGeometry
from ..robot.legs import PARAMETER_KINDS, LegParameters, leg_frames, leg_ik_unchecked
from .files import MeasurementsFile, robot_yaml, write_path, write_robot
from .identify import BEYOND_TOLERANCE, Identification
from .tracker import MeasurementNoise

#: How each kind of parameter is shown: (label, unit, factor from SI) per entry of a leg.
_SHOWN = {
    "pivot_offsets_m": [(f"pivot {a}", "um", 1e6) for a in "xyz"],
    "platform_offsets_m": [(f"platform joint {a}", "um", 1e6) for a in "xyz"],
    "crank_lengths_m": [("crank length", "um", 1e6)],
    "rod_lengths_m": [("rod length", "um", 1e6)],
    "shaft_tilts_rad": [("shaft tilt", "urad", 1e6)],
    "crank_angles_deg": [("crank azimuth", "urad", 1e6)],
    "encoder_offsets_rad": [("encoder offset", "urad", 1e6)],
}


def check_reachable(
    geometry: StewartGeometry, data: MeasurementsFile, registered: bool = False
) -> None:
    """Refuse measurements whose poses the nominal robot cannot reach (wrong units or frames),
    before any work; ``registered``: the poses were converted by a registration.

    Raises:
        InvalidConfigError: names the first such line.
    """
    theta, _ = leg_ik_unchecked(leg_frames(geometry, LegParameters.nominal(geometry)), data.poses)
    bad = ~np.all(np.isfinite(theta), axis=1)
    if np.any(bad):
        k = int(np.argmax(bad))
        check = (
            "that the file's poses are the marker's in the tracker's frame, as REG.yaml's "
            "fiducials are, and the columns' units"
            if registered
            else "the columns' units and that the pose is the platform frame's in the base frame "
            "(a tracker's own frame: --registration REG.yaml)"
        )
        units = "rad, m, converted to the base frame" if registered else "rad, m"
        raise InvalidConfigError(
            f"line {data.lines[k]}: the nominal robot cannot reach the pose "
            f"{np.round(data.poses[k], 6).tolist()} ({units}): check {check}"
        )


def _shown(k: int) -> tuple[str, str, float]:
    """(label with its leg, unit, factor from SI) of entry k of the deviation vector."""
    start = 0
    for kind, width, _ in PARAMETER_KINDS:
        if k < start + 6 * width:
            leg, j = divmod(k - start, width)
            label, unit, factor = _SHOWN[kind][j]
            return f"leg {leg} {label}", unit, factor
        start += 6 * width
    raise IndexError(k)


def deviations_table(ident: Identification) -> str:
    """The identified deviations, value +- standard deviation, one row per quantity, one column
    per leg."""
    lines = ["quantity".ljust(24) + "".join(f"leg {i}".rjust(18) for i in range(6))]
    start = 0
    for kind, width, _ in PARAMETER_KINDS:
        for j, (label, unit, factor) in enumerate(_SHOWN[kind]):
            cells = []
            for leg in range(6):
                k = start + leg * width + j
                v, s = ident.deviation[k] * factor, ident.std[k] * factor
                cell = f"{v:+.1f} +- {s:.1f}" if ident.scale[k] > 0 else f"{v:+.1f} (fixed)"
                cells.append(cell.rjust(18))
            lines.append(f"{label} [{unit}]".ljust(24) + "".join(cells))
        start += 6 * width
    return "\n".join(lines)


def identification_text(ident: Identification, noise: MeasurementNoise, lines=None) -> str:
    """The identification as text: its figures, the deviations, the combinations known mostly
    from the tolerances and the outliers (``lines``: the file's line of each pose, to name
    them)."""
    used = int(ident.used.sum())
    out = [
        f"identified from {used} poses ({noise.words()}), the tolerances as the prior: chi2/dof "
        f"{ident.chi2_reduced:.3g} (dof {ident.dof:.0f}; about 1 when the noise is as stated)",
        f"readings' residuals (model - read), RMS: {ident.rms_before_rad * 1e3:.3g} mrad with "
        f"the nominal robot, {ident.rms_after_rad * 1e6:.3g} urad identified",
        "identified deviations from the nominal robot (value +- standard deviation, from the "
        "data and the tolerances together; crank azimuth is crank_angles_deg's, in urad):",
        deviations_table(ident),
    ]
    if ident.weak:
        out.append(
            f"known mostly from the tolerances ({len(ident.weak)} combinations of the "
            f"parameters, each in units of its tolerance's standard deviation, whose singular "
            f"value S < --min-singular: the data alone know it to 1/S, less well than the "
            f"drawing; it stays near nominal and its +- is about its tolerance's):"
        )
        out += [f"  {c.words()}" for c in ident.weak]
    else:
        out.append(
            "known mostly from the tolerances: none (every singular value >= --min-singular)"
        )
    return "\n".join(out + outliers_lines(ident, lines))


def outliers_lines(ident: Identification, lines=None) -> list[str]:
    """The outliers, one line per pose (its line of the file when ``lines`` gives them) with
    its flagged readings, and whether it was dropped."""
    if not ident.outliers:
        return ["outliers: none"]
    by_pose: dict[int, list] = {}
    for o in ident.outliers:
        by_pose.setdefault(o.pose, []).append(o)
    dropped = int((~ident.used).sum())
    kept = [p for p in by_pose if ident.used[p]]
    rounds = ident.rounds - 1
    head = (
        f"outliers (a reading's studentized residual beyond the threshold): {dropped} "
        f"pose{'s' * (dropped > 1)} dropped in {rounds} round{'s' * (rounds > 1)}, the "
        f"identification repeated without them"
        if dropped
        else "outliers (a reading's studentized residual beyond the threshold):"
    )
    out = [head]
    for pose, flagged in by_pose.items():
        where = f"line {lines[pose]}" if lines is not None else f"pose {pose}"
        what = "; ".join(
            f"q{o.leg} {o.residual_rad * 1e6:+.1f} urad (studentized {o.studentized:+.1f})"
            for o in flagged
        )
        fate = f"dropped in round {flagged[0].round}" if not ident.used[pose] else "kept"
        out.append(f"  {where}: {fate}: {what}")
    if kept:
        out.append(
            f"  {len(kept)} pose{'s' * (len(kept) > 1)} still flagged, kept: "
            + (
                f"after {ident.rounds} rounds (check the measurements)"
                if dropped
                else "--no-drop-outliers"
            )
        )
    return out


#: A pose set identifies too little when, with the noise as stated, it leaves over this
#: share of the drawing's error on the readings over the workspace (the quantization aside),
#: or over :data:`SPREAD_RATIO` times what as many poses spread over the workspace leave.
TOO_LITTLE = 0.05
SPREAD_RATIO = 3.0
#: Over this ratio of the held-out readings' RMS to what the covariance predicts, the model
#: misses something the noise does not explain.
HELD_OUT_RATIO = 1.5


def identification_warnings(
    ident: Identification, noise: MeasurementNoise, frames_moved: bool = False
) -> list[str]:
    """Lines to warn of: each parameter identified beyond
    :data:`~.identify.BEYOND_TOLERANCE` standard deviations of its tolerance (one line for
    them all when ``frames_moved``: a rigid motion of a set of joints, :func:`frame_warnings`,
    explains them), the noise the residuals imply when chi2/dof is far from 1, many poses
    dropped."""
    from scipy.stats import chi2

    from ..robot.legs import parameter_names

    out = []
    names = parameter_names()
    beyond = ident.beyond_tolerance()
    for k, ratio in beyond if not frames_moved else ():
        label, unit, factor = _shown(k)
        out.append(
            f"{label} ({names[k]}) identified at {ident.deviation[k] * factor:+.1f} {unit}, "
            f"{abs(ratio):.1f} times its tolerance's standard deviation "
            f"({ident.scale[k] * factor:.1f} {unit}): the drawing is probably wrong there, or "
            f"the poses are not in the base frame (--registration REG.yaml)"
        )
    if beyond and frames_moved:
        k, ratio = beyond[0]
        out.append(
            f"{len(beyond)} parameters identified beyond {BEYOND_TOLERANCE:g} standard "
            f"deviations of their tolerance, as the rigid motion above makes them (the "
            f"largest: {names[k]}, {abs(ratio):.1f})"
        )
    band = chi2.ppf([0.0005, 0.9995], ident.dof) / ident.dof
    s = ident.noise_scale
    if not band[0] <= ident.chi2_reduced <= band[1] and abs(np.log(s)) > np.log(1.25):
        out.append(
            f"chi2/dof {ident.chi2_reduced:.3g}: the residuals imply a measurement noise about "
            f"{s:.2g} times the stated ({noise.words()}); check --noise, the encoders' counts "
            f"per revolution (the scenario's) and the frames of the poses; the +- values are "
            f"scaled to it"
        )
    dropped = int((~ident.used).sum())
    if dropped > 0.2 * len(ident.used):
        out.append(
            f"{dropped} of {len(ident.used)} poses were dropped as outliers: the tracker lost "
            f"its marker often, or the poses are not this robot's (the frames, the units)"
        )
    return out


def accuracy_lines(
    geometry: StewartGeometry,
    ident: Identification,
    noise: MeasurementNoise,
    workspace,
    held_out,
    tolerances=None,
) -> tuple[list[str], list[str]]:
    """(lines to print, lines to warn of): the accuracy the covariance promises at the
    workspace's poses ``workspace`` (W, 6), beside the nominal robot's; the held-out check
    (a :class:`~.validation.HeldOut`, or None when the poses were too few); a warning when the
    pose set identifies too little (:data:`TOO_LITTLE`, :data:`SPREAD_RATIO`, at the noise as
    stated: :meth:`~.identify.Identification.design_covariance`) or the held-out readings miss by
    more than the covariance predicts (:data:`HELD_OUT_RATIO`)."""
    from ..robot.legs import derivatives
    from ..robot.tolerances import Tolerances
    from .poses import information_rows
    from .validation import nominal_rms, predicted_rms

    tolerances = Tolerances() if tolerances is None else tolerances
    quantization = noise.quantization_rms_rad
    after = predicted_rms(geometry, ident, workspace, noise)
    before = nominal_rms(geometry, tolerances, workspace, noise)
    # The pose set's own share, at the noise as stated: a misstated noise has its own line.
    design = predicted_rms(geometry, ident, workspace, noise, ident.design_covariance())
    share = np.sqrt(max(design**2 - quantization**2, 0.0) / max(before**2 - quantization**2, 1e-30))
    # As many poses spread over the workspace: its poses' information, scaled to their count.
    rows = information_rows(geometry, workspace, noise, tolerances)
    held_rows = derivatives(geometry, ident.nominal, workspace).parameters * tolerances.stds()
    spread = expected_rms(rows * np.sqrt(ident.used.sum() / len(workspace)), held_rows, noise)
    text = [
        f"accuracy to expect (the covariance, at {len(workspace)} admissible poses over the "
        f"workspace): the readings predicted to {after * 1e6:.3g} urad RMS (the drawing alone "
        f"{before * 1e3:.3g} mrad; the encoders' quantization {quantization * 1e6:.3g} urad)"
    ]
    frames = ident.frames_covariance
    if frames is not None and frames.any():
        # The registration's part: the same error in every pose, which no pose count averages.
        part = np.sqrt(
            max(
                predicted_rms(geometry, ident, workspace, noise, frames) ** 2 - quantization**2, 0.0
            )
        )
        if part**2 > 0.5 * (after**2 - quantization**2):
            text.append(
                f"the registration's error is most of it ({part * 1e6:.3g} urad RMS alone): "
                f"more fiducials, spread wider and measured more precisely, lower it; more "
                f'poses do not (docs/calibration.md, "The error budget")'
            )
    warn = []
    if share > TOO_LITTLE or design > SPREAD_RATIO * spread:
        warn.append(
            f"this pose set identifies too little: with the noise as stated, the readings over "
            f"the workspace are predicted to {design * 1e6:.3g} urad RMS ({share:.1%} of the "
            f"drawing's error), where as many poses spread over the workspace give about "
            f"{spread * 1e6:.3g}: measure poses spread over the workspace (calibrate --plan N "
            f"chooses them)"
        )
    if held_out is None:
        text.append("held-out check: too few poses to leave a fold out")
        return text, warn
    text.append(
        f"held-out check ({held_out.folds}-fold on the {held_out.poses} poses used): each "
        f"fold's readings predicted by the robot identified from the others, "
        f"{held_out.rms_rad * 1e6:.3g} urad RMS; their covariances predict "
        f"{held_out.predicted_rad * 1e6:.3g} urad (the measurements' own noise "
        f"{held_out.noise_rad * 1e6:.3g} urad of it)"
    )
    if held_out.rms_rad > HELD_OUT_RATIO * held_out.predicted_rad:
        warn.append(
            f"the held-out readings are predicted to {held_out.rms_rad * 1e6:.3g} urad RMS, "
            f"{held_out.rms_rad / held_out.predicted_rad:.2g} times what the covariance "
            f"predicts: the model misses something the noise does not explain (the frames, "
            f"the temperature, a loose joint, the readings' timing)"
        )
    return text, warn


def identification_checks(
    scenario, geometry: StewartGeometry, ident: Identification, poses, q, noise, registered=None
) -> tuple[list[str], list[str]]:
    """(lines to print, lines to warn of) after an identification from ``poses`` (N, 6) and
    ``q`` (N, 6) of the robot of ``scenario``: :func:`accuracy_lines` at 50 admissible poses
    (the rehearsal's held-out ones) with a 5-fold :func:`~.validation.cross_validate`,
    :func:`frame_warnings` and :func:`identification_warnings` (``registered``: the
    :class:`~.registration.RegisteredPoses` the poses came from, or None)."""
    from ..run.plan import robot_motor_limits
    from .poses import candidate_poses
    from .rehearsal import HELD_OUT_SEED
    from .validation import cross_validate

    workspace = candidate_poses(
        geometry, 50, HELD_OUT_SEED, motor_limits=robot_motor_limits(scenario)
    )
    covariances = None if registered is None else registered.pose_covariances
    held_out = cross_validate(geometry, poses, q, noise, ident, pose_covariances=covariances)
    text, warn = accuracy_lines(geometry, ident, noise, workspace, held_out)
    frames = frame_warnings(geometry, ident, registered is not None)
    return text, frames + identification_warnings(ident, noise, bool(frames)) + warn


def write_identified(out, robot, ident: Identification, source, frames=None) -> Path | None:
    """The identified robot as a scenario's ``robot:`` section at ``out``
    (:func:`~.files.write_robot`), its comments saying where it came from (with ``frames``,
    (a :class:`~.registration.Registration`, its source), the frames its poses were converted
    by), once the scenario loader accepts it (:func:`loader_refusal`).

    Returns:
        the path written, or None when the loader would refuse the section: nothing is then
        written, and one line on stderr says why.
    """
    import sys

    from .registration import transform_words

    comments: tuple[str, ...] = (
        f"The robot identified by stewart-drake calibrate from {source}: "
        f"{int(ident.used.sum())} poses,",
        f"readings' residuals {ident.rms_before_rad * 1e3:.3g} mrad RMS with the nominal robot, "
        f"{ident.rms_after_rad * 1e6:.3g} urad identified; {len(ident.weak)} combinations known "
        f"mostly from the tolerances; {int((~ident.used).sum())} poses dropped as outliers.",
        "Per-leg fields: docs/calibration.md (encoder_offsets_rad: what each encoder reads at "
        "theta_i = 0).",
    )
    if frames is not None:
        registration, where = frames
        comments += (
            f"The poses were the tracker's marker M in its frame T, converted to the base frame "
            f"B by the registration of {where}:",
            f"X_TB {transform_words(registration.X_TB, registration.cov_B, exact=True)};",
            f"X_PM {transform_words(registration.X_PM, registration.cov_M, exact=True)}.",
        )
    text = robot_yaml(robot, ident.identified, comments)
    refusal = loader_refusal(text)
    if refusal is not None:
        print(
            f"stewart-drake calibrate: the identified robot was not written to {out}: the "
            f"scenario loader would refuse it ({refusal}); the poses are probably not the "
            f"platform frame's in the base frame (register the tracker's frames: "
            f"--registration REG.yaml, docs/calibration.md), or the readings not this robot's",
            file=sys.stderr,
        )
        return None
    return write_robot(out, robot, ident.identified, comments)


def loader_refusal(text: str) -> str | None:
    """Why the scenario loader would refuse the scenario ``text`` (a robot section), in one
    line, or None when it loads: the text is loaded as a scenario file is
    (:func:`~stewart_drake.run.scenario_io.load_scenario`) and its robot built
    (:func:`~stewart_drake.run.plan.robot_geometry`, which validates the scenario)."""
    import tempfile

    from ..base.errors import StewartError
    from ..run.plan import robot_geometry
    from ..run.scenario_io import load_scenario

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "robot.yaml"
        path.write_bytes(text.encode())
        try:
            robot_geometry(load_scenario(path))
        except StewartError as err:
            return str(err).replace(f"{path}: ", "").splitlines()[0]
    return None


def frame_warnings(geometry: StewartGeometry, ident: Identification, registered: bool) -> list:
    """One line for each set of joints the identification moved as a rigid whole beyond what
    the tolerances allow (:func:`~.validation.rigid_motions`): the poses were probably not the
    platform frame's in the base frame; ``registered``: they were converted by a registration
    (the line then blames it)."""
    from .validation import RIGID_MOTION_CHI2, rigid_motions

    lines = []
    for m in rigid_motions(geometry, ident):
        if not m.beyond:
            continue
        joints, frame = (
            ("pivots", "the base frame B")
            if m.frame == "base"
            else ("platform joints", "the platform frame P (E)")
        )
        fix = (
            f"check REG.yaml's {'base_points' if m.frame == 'base' else 'platform_points'}"
            if registered
            else "measure fiducials and give them with --registration REG.yaml "
            "(docs/calibration.md, Registration)"
        )
        lines.append(
            f"the identified {joints} moved together, as one rigid body, by "
            f"{m.angle_rad * 1e3:.3g} mrad and {m.shift_m * 1e3:.3g} mm from the drawing (chi2 "
            f"{m.chi2:.3g} on 6 degrees of freedom, over {RIGID_MOTION_CHI2:g}: under 0.1 % of "
            f"robots within their tolerances do so): the poses are probably not in {frame}; "
            f"{fix}"
        )
    return lines


def frames_text(geometry: StewartGeometry, ident: Identification, registration, poses, source):
    """The registration as text: its frames (:meth:`~.registration.Registration.words`) and
    what their error costs the readings predicted at the measured poses ``poses`` (N, 6) in B
    (the frames' part of the parameters' covariance mapped through the readings' derivatives,
    RMS)."""
    from ..robot.legs import derivatives

    J = derivatives(geometry, ident.identified, poses).parameters
    C = ident.frames_covariance if ident.frames_covariance is not None else np.zeros((66, 66))
    var = np.einsum("nik,kl,nil->ni", J, C, J)
    return (
        f"registered by {source}: {registration.words()}; the poses converted to the base "
        f"frame; the frames' error, in every pose, carried into the parameters' covariance: "
        f"{np.sqrt(np.mean(var)) * 1e6:.3g} urad RMS on the readings from it alone"
    )


def rehearsal_text(r, noise: MeasurementNoise) -> str:
    """A rehearsal (:class:`~.rehearsal.Rehearsal`) as text: the identification, then the
    prediction on the held-out poses before and after, and the parameters' errors."""
    ident = r.identification
    err = ident.deviation - r.truth.deviation(ident.nominal)
    free = ident.std > 0
    z = np.abs(err[free] / ident.std[free])
    from ..robot.legs import parameter_names

    worst = np.array(parameter_names())[free][int(np.argmax(z))]
    registered = (
        []
        if r.registration is None
        else [f"registered by the emulated fiducials: {r.registration.words()}"]
    )
    return "\n".join(
        registered
        + [
            identification_text(ident, noise),
            f"identified minus drawn, in standard deviations: RMS {np.sqrt(np.mean(z**2)):.2f}, "
            f"largest {z.max():.2f} ({worst})",
            f"readings of 50 other poses predicted, RMS: before {r.before_rad * 1e3:.3g} mrad, "
            f"after {r.after_rad * 1e6:.3g} urad (the covariance's bound "
            f"{r.bound_rad * 1e6:.3g} urad; quantization alone "
            f"{noise.quantization_rms_rad * 1e6:.3g} urad); from the tracker's poses "
            f"{r.after_tracked_rad * 1e6:.3g} urad",
        ]
    )


def expected_rms(rows: np.ndarray, held_rows: np.ndarray, noise: MeasurementNoise) -> float:
    """The RMS of the readings' prediction at held-out poses that poses of information rows
    ``rows`` (N, 6, 66) promise (the posterior covariance with the tolerances as prior, mapped
    by the held-out poses' unwhitened scaled rows ``held_rows`` (H, 6, 66)), rad."""
    A = np.eye(rows.shape[-1]) + np.einsum("nik,nil->kl", rows, rows)
    C = np.linalg.inv(A)
    var = np.einsum("nik,kl,nil->ni", held_rows, C, held_rows)
    return float(np.sqrt(np.mean(var) + noise.quantization_rms_rad**2))


def plan_poses(
    scenario,
    count: int,
    out,
    noise: MeasurementNoise,
    seed: int,
    dwell_s: float,
    n_candidates: int = 2000,
    progress: bool = False,
) -> int:
    """``calibrate --plan``: choose ``count`` poses among ``n_candidates`` admissible ones of
    the robot of ``scenario`` (a :class:`~stewart_drake.run.scenario.Scenario`), write the path
    through them at ``out`` with its windows, and check the path as the robot command will.

    Raises:
        InvalidConfigError, JointLimitError, SingularPoseError, InterferenceError,
            MotorLimitError: the path refused by the reference's check (it should not be).
    """
    from tqdm import tqdm

    from ..references.traces import load_trace
    from ..robot.legs import derivatives
    from ..robot.tolerances import Tolerances
    from ..run.plan import check_reference, robot_geometry, robot_motor_limits
    from .poses import (
        PREFIX_BLOCK,
        candidate_poses,
        choose_poses,
        information_rows,
        pose_path,
    )

    geometry, limits = robot_geometry(scenario), robot_motor_limits(scenario)
    tolerances = Tolerances()
    with tqdm(total=count + 2, desc="planning", disable=not progress, leave=False) as bar:
        candidates = candidate_poses(geometry, n_candidates, seed, motor_limits=limits)
        held = candidate_poses(geometry, 50, seed + 1, motor_limits=limits)
        bar.update(1)
        rows = information_rows(geometry, candidates, noise, tolerances)
        chosen = choose_poses(rows, count, on_step=lambda: bar.update(1))
        path = pose_path(
            geometry, candidates[chosen], dwell_s, motor_limits=limits, block=PREFIX_BLOCK
        )
        bar.update(1)
    nominal = LegParameters.nominal(geometry)
    held_rows = derivatives(geometry, nominal, held).parameters * tolerances.stds()
    random = np.random.default_rng(seed).choice(len(candidates), count, replace=False)
    written, windows = write_path(out, path)
    reference = load_trace(written)  # as the robot command reads it
    duration = float(reference.end_time)
    report = check_reference(
        scenario, reference, raise_refused=True, keep_series=False, duration_s=duration
    )
    print(
        f"chose {count} poses of {len(candidates)} admissible candidates (greedy D-optimal, "
        f"tracker {noise.words()}); expected RMS of the readings' prediction on 50 other "
        f"poses: {expected_rms(rows[chosen], held_rows, noise) * 1e6:.3g} urad "
        f"(random poses: {expected_rms(rows[random], held_rows, noise) * 1e6:.3g} urad)"
    )
    visited = information_rows(geometry, path.poses, noise, tolerances)
    prefixes = sorted({max(count // 4, 12), max(count // 2, 12)})
    print(
        f"the path: {duration:.0f} s, at rest {dwell_s:g} s at each pose, the poses in blocks "
        f"of {PREFIX_BLOCK} in the order chosen, so that a session cut short has measured a "
        f"good set (its first "
        + " and ".join(str(n) for n in prefixes)
        + " poses promise "
        + " and ".join(f"{expected_rms(visited[:n], held_rows, noise) * 1e6:.3g}" for n in prefixes)
        + f" urad); checked as the robot command checks it: "
        f"{'passes' if report.ok else 'REFUSED'}"
    )
    print(
        f"wrote {written} (drive it: stewart-drake robot {written}) and {windows} (each pose "
        f"and the window to measure it in, s of the path; docs/calibration.md)"
    )
    return 0 if report.ok else 2
