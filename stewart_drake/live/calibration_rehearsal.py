"""A calibration rehearsed over the bus emulator: the workflow a user follows with the robot and
a tracker, every file written and read as theirs would be.

1. A robot as built is drawn (:class:`~stewart_drake.robot.tolerances.Tolerances`, a
   seed): its geometry and its encoders' zero errors. It is the emulator's plant (the
   scenario's ``robot_as_built``; the servos read its encoder offsets,
   :class:`~.plant_backend.StationServos`); the controller believes the nominal robot.
2. The poses are chosen and the path through them written (``poses.csv`` and
   ``poses_windows.csv``, as ``calibrate --plan`` writes them).
3. The robot session drives the path over the emulated bus (``robot.npz`` and the encoder log
   ``robot_encoders.csv``, as ``stewart-drake robot poses.csv`` writes them).
4. An emulated tracker samples the plant's true pose with noise
   (:func:`~stewart_drake.calibration.tracker.track`) on the robot computer's clock
   (``tracker.csv``).
5. The files are joined (``measurements.csv``, :func:`~stewart_drake.calibration.join.join`),
   the robot identified from them (``robot.yaml``), and its readings predicted at held-out poses
   (other admissible poses) with the nominal robot (before) and the identified one (after),
   against the as-built robot's readings there, quantized by the servos' encoders.

The emulator runs in this process on the commanded clock
(:class:`~stewart_drake.station.bus.emulator.BusEmulator`'s ``command_step_s``: the plant advances
one control period per torque command) and the bus's and the loop's timing limits are relaxed
(:data:`REHEARSAL_BUS`, :data:`LOOP_TIMEOUT_S`): a rehearsal of the calibration, whose physics
follow the loop's commands however loaded the machine, not of the loop's timing (``stewart-drake
robot --emulate`` rehearses that).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration.tracker import MeasurementNoise

#: Where the emulated robot rests before the session (as ``robot --emulate``'s default).
X_REST = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.28])
#: The bus's settings in a rehearsal: the longest waits the bus allows (a servo's reply
#: within 5 s, its watchdog at 2.54 s, 127 units of 20 ms), so that a machine busy with other
#: work stalls the loop without ending it; deadline misses counted but not ending the run.
REHEARSAL_BUS = {"reply_timeout_s": 5.0, "watchdog_s": 2.54, "max_deadline_misses": 10**6}
#: Our watchdog's limit on a control period in a rehearsal, s (as long as a servo's reply may
#: take).
LOOP_TIMEOUT_S = 5.0


def emulated_bus(scenario, robot_as_built=None, x0=X_REST):
    """The bus emulator for ``scenario`` (a Scenario with a ``bus``), in this process on the
    commanded clock (module docstring), the robot ``robot_as_built`` (a
    :class:`~stewart_drake.run.scenario.Robot`; None: the scenario's) behind it resting at
    ``x0``, its plant at a 2 ms step; started. Its backend's ``record`` lists (perf_counter s,
    the platform's true pose and rate (12,)) after every command.

    Returns:
        the started :class:`~stewart_drake.station.bus.emulator.BusEmulator` (close it).
    """
    import time as clock

    from ..station.bus.emulator import BusEmulator
    from .plant_backend import StationServos, behind_the_bus, dynamixel_scenario

    bus = scenario.bus
    behind = behind_the_bus(scenario, robot_as_built=robot_as_built)

    class Recorded(StationServos):
        def __init__(self):
            super().__init__(dynamixel_scenario(bus.model, behind), bus.model, x0)
            self._pose = self.station.GetOutputPort("platform_state")
            self._context = self.station.GetMyContextFromRoot(self.simulator.get_context())
            self.record: list = []

        def advance(self, dt_s, current_A):
            super().advance(dt_s, current_A)
            self.record.append((clock.perf_counter(), *self._pose.Eval(self._context)))

    return BusEmulator(
        bus.ids,
        bus.model,
        backend=Recorded(),
        zero_counts=bus.zero_counts,
        command_step_s=scenario.control_period_s,
    ).start()


@dataclass(frozen=True)
class BusRehearsal:
    """A rehearsal's figures (module docstring); RMS over the held-out poses' readings, rad.

    Attributes:
        poses: poses measured.  seed: the robot's and the noise's.  noise: the tracker's.
        before_rad, after_rad: the nominal and the identified robot's predicted readings
            against the as-built robot's readings (quantized: what a user checking on the
            robot sees, one count's quantization included).
        model_rad: the identified robot's predicted readings against the as-built robot's
            exact ones (the model's own error).
        bound_rad: what the identification's covariance predicts for ``after_rad``.
        offsets_error_rad: (6,) identified minus true encoder offsets.
        offsets_std_rad: (6,) their standard deviations: the identification's (the
            tolerances' prior included).
        reading_error_rad: (N, 6) the joined readings minus the as-built robot's readings at
            the true mean pose of each window (the join's and the encoders' error).
        path_s: the path's length, s.  wall_s: the rehearsal's wall time, s.
        weak: combinations known mostly from the tolerances.  chi2_reduced: of the fit.
        files: {name: path} of every file written.
        run: the session's :class:`~.session.RobotRun`.
    """

    poses: int
    seed: int
    noise: MeasurementNoise
    before_rad: float
    after_rad: float
    model_rad: float
    bound_rad: float
    offsets_error_rad: np.ndarray
    offsets_std_rad: np.ndarray
    reading_error_rad: np.ndarray
    path_s: float
    wall_s: float
    weak: int
    chi2_reduced: float
    files: dict
    run: object

    def text(self) -> str:
        """The figures as lines."""
        ratio = np.abs(self.offsets_error_rad) / np.maximum(self.offsets_std_rad, 1e-12)
        return "\n".join(
            [
                f"rehearsed over the bus emulator: {self.poses} poses, a {self.path_s:.0f} s "
                f"path, {self.wall_s:.0f} s in all; tracker {self.noise.words()}",
                f"readings predicted at 50 held-out poses, RMS: {self.before_rad * 1e3:.3g} "
                f"mrad with the nominal robot, {self.after_rad * 1e6:.3g} urad identified "
                f"(the covariance predicts {self.bound_rad * 1e6:.3g} urad; one count's "
                f"quantization is {self.noise.quantization_rms_rad * 1e6:.3g} urad RMS); "
                f"against the exact readings {self.model_rad * 1e6:.3g} urad",
                f"encoder zeros: identified - true {_urad(self.offsets_error_rad)} urad, "
                f"+- {_urad(self.offsets_std_rad)} urad (at most {ratio.max():.2g} std)",
                f"{self.weak} combinations known mostly from the tolerances; chi2/dof "
                f"{self.chi2_reduced:.3g}; "
                f"the joined readings minus the as-built robot's at the tracked poses: "
                f"{np.sqrt(np.mean(self.reading_error_rad**2)) * 1e6:.3g} urad RMS",
            ]
        )


def _urad(v) -> str:
    return "[" + ", ".join(f"{x * 1e6:.0f}" for x in v) + "]"


def _calibrate_from_files(
    folder: Path, files: dict, built, geometry, t_true, x_true, noise, tolerances, seed, counts
):
    """The rehearsal's calibration as a user's, through its files: the tracker's view of the
    true poses (``t_true`` on the session's epoch clock, s) written, joined with the encoder
    log and the windows, the measurements written and read back, the robot identified and its
    ``robot.yaml`` written (each file added to ``files``). Returns (the join, the
    identification)."""
    from ..calibration.files import read_measurements, robot_section, write_measurements
    from ..calibration.identify import identify
    from ..calibration.join import join, write_tracker_file
    from ..calibration.report import write_identified
    from ..calibration.tracker import track

    t_tracked, x_tracked = track(t_true, x_true, noise, seed)
    files["tracker"] = write_tracker_file(folder / "tracker.csv", t_tracked, x_tracked)
    joined = join(files["encoders"], files["tracker"], files["windows"])
    files["measurements"] = write_measurements(
        folder / "measurements.csv", joined.poses, joined.readings
    )
    data = read_measurements(files["measurements"], counts)
    ident = identify(geometry, data.poses, data.readings, noise, tolerances)
    files["robot"] = write_identified(
        folder / "robot.yaml",
        robot_section(built.robot, geometry),
        ident,
        files["measurements"],
    )
    return joined, ident


def rehearse_on_bus(
    scenario,
    count: int,
    folder,
    seed: int = 0,
    noise: MeasurementNoise | None = None,
    select: str = "chosen",
    dwell_s: float = 3.0,
    n_candidates: int = 2000,
    progress: bool = False,
    say=print,
) -> BusRehearsal:
    """Rehearse a calibration of ``scenario``'s robot over the bus emulator (module docstring),
    writing its files in ``folder``.

    Args:
        scenario: a Scenario with a ``bus`` (its port is the emulator's).
        count: poses to measure (at least 12).  seed: the robot drawn and the noise.
        noise: the tracker's (default 5 um / 20 urad) with the servos' encoders' counts.
        select: "chosen" (greedy D-optimal, as ``calibrate --plan`` chooses) or "random".
        dwell_s: s at rest at each pose (its first second to settle).
        n_candidates: admissible poses drawn to choose from.
        say: where the steps are told.
    Returns:
        :class:`BusRehearsal`.
    Raises:
        InvalidConfigError: no bus, a bad count or dwell; BusError: the emulator did not start;
            InvalidConfigError: the session did not drive the whole path (its end line).
    """
    from ..base.errors import InvalidConfigError
    from ..calibration.files import nominal_at_temperature
    from ..calibration.tracker import COUNTS_PER_REV
    from ..robot.legs import readings
    from ..robot.tolerances import Tolerances
    from ..run.plan import as_built, robot_motor_limits

    wall0 = time.perf_counter()
    if scenario.bus is None:
        raise InvalidConfigError("the rehearsal drives a robot on a bus: give a scenario with bus")
    # Identified about the nominal robot at the measurements' temperature (temperature_c).
    geometry = nominal_at_temperature(scenario)  # the scenario validated
    built = as_built(scenario)  # the robot built with the bus's servos
    hardware = built.hardware
    counts = COUNTS_PER_REV if hardware is None else hardware.encoders.counts_per_rev
    noise = dataclasses.replace(noise or MeasurementNoise(), counts_per_rev=counts)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tolerances = Tolerances()
    truth = tolerances.draw(geometry, seed)
    say(f"drew a robot as built with seed {seed}; {select} poses: {count}")
    limits = robot_motor_limits(built)
    space, files = _plan_path(
        geometry, limits, count, noise, tolerances, seed, dwell_s, n_candidates, folder, select
    )
    run, path_s, t_true, x_true = _drive(
        built, geometry, truth, files["poses"], folder, progress, say
    )
    files.update(log=run.logs, encoders=run.encoder_log)
    epoch = time.time() - time.perf_counter()  # the session's clock: perf_counter + epoch
    joined, ident = _calibrate_from_files(
        folder, files, built, geometry, t_true + epoch, x_true, noise, tolerances, seed, counts
    )
    # The join's own error: the true pose averaged over each window, the as-built readings there.
    true_mean = np.array([_mean_between(t_true + epoch, x_true, w) for w in joined.windows])
    figures = _figures(geometry, truth, ident, space.held_out, noise)
    return BusRehearsal(
        poses=count,
        seed=seed,
        noise=noise,
        **figures,
        reading_error_rad=joined.readings - readings(geometry, truth, true_mean),
        path_s=path_s,
        wall_s=time.perf_counter() - wall0,
        weak=len(ident.weak),
        chi2_reduced=ident.chi2_reduced,
        files=files,
        run=run,
    )


def _plan_path(
    nominal, limits, count, noise, tolerances, seed, dwell_s, n_candidates, folder, select
):
    """(the :class:`~stewart_drake.calibration.rehearsal.Workspace`, {"poses", "windows": the
    files written}): ``count`` poses of the robot ``nominal`` (a geometry, its motors'
    ``limits``) picked (``select``) among the candidates, the path through them."""
    from ..calibration.files import write_path
    from ..calibration.poses import pose_path
    from ..calibration.rehearsal import pick, workspace

    space = workspace(nominal, n_candidates, motor_limits=limits)
    chosen = pick(nominal, space, count, select, noise, tolerances, seed)
    path = pose_path(nominal, space.candidates[chosen], dwell_s=dwell_s, motor_limits=limits)
    poses_csv, windows_csv = write_path(folder / "poses.csv", path)
    return space, {"poses": poses_csv, "windows": windows_csv}


def _drive(scenario, geometry, truth, poses_csv, folder, progress, say):
    """(the :class:`~.session.RobotRun`, the path's length s, the plant's record: times
    (perf_counter s) and true poses (n, 6)): the robot session of ``scenario`` (as built, its
    robot ``geometry``) driving ``poses_csv`` over the emulated bus, the robot as built
    ``truth`` behind it.

    Raises:
        InvalidConfigError: the session did not drive the whole path (its end line).
    """
    from ..base.errors import InvalidConfigError
    from ..references.traces import TraceReference, load_trace
    from ..run.scenario import Robot
    from .session import end_line, run_on_robot

    path_s = float(load_trace(poses_csv).end_time)
    bus = dataclasses.replace(scenario.bus, **REHEARSAL_BUS)
    guard = dataclasses.replace(scenario.guard, divergence_dir=str(folder / "diverged"))
    robot = dataclasses.replace(
        scenario,
        reference=TraceReference(path=str(poses_csv)),
        duration_s=path_s,
        bus=bus,
        guard=guard,
    )
    say(f"driving the {path_s:.0f} s path over the bus emulator (the robot as built behind it)")
    emulator = emulated_bus(robot, Robot.from_value(truth.geometry(geometry)))
    try:
        bus.port = emulator.port
        run = run_on_robot(
            robot,
            loop_timeout_s=LOOP_TIMEOUT_S,
            out=folder,
            stem="robot",
            progress=progress,
            say=say,
        )
    finally:
        emulator.close()
    if run.exit_code > 128:  # a signal ended it: the command ends as any interrupted one
        from ..execution.runners import Interrupted

        say(f"the session did not drive the path: {end_line(run)}")
        raise Interrupted(run.exit_code - 128)
    if not run.ok or run.encoder_log is None:
        raise InvalidConfigError(f"the session did not drive the path: {end_line(run)}")
    record = np.array(emulator.backend.record, dtype=float).reshape(-1, 13)
    return run, path_s, record[:, 0], record[:, 1:7]


def _figures(geometry, truth, ident, held_out, noise) -> dict:
    """:class:`BusRehearsal`'s prediction figures at the held-out poses (N, 6)."""
    from ..calibration.tracker import quantize
    from ..calibration.validation import predicted_rms
    from ..robot.legs import parameter_kinds, readings

    exact = readings(geometry, truth, held_out)
    read = quantize(exact, noise.counts_per_rev)
    offsets = np.array([k == "encoder_offsets_rad" for k in parameter_kinds()])
    after = readings(geometry, ident.identified, held_out)

    def rms(a, b):
        return float(np.sqrt(np.mean((a - b) ** 2)))

    return dict(
        before_rad=rms(readings(geometry, ident.nominal, held_out), read),
        after_rad=rms(after, read),
        model_rad=rms(after, exact),
        bound_rad=predicted_rms(geometry, ident, held_out, noise),
        offsets_error_rad=np.asarray(ident.identified.encoder_offsets_rad)
        - np.asarray(truth.encoder_offsets_rad),
        offsets_std_rad=np.sqrt(np.diag(ident.covariance)[offsets]),
    )


def _mean_between(t, x, window) -> np.ndarray:
    """(6,) the mean pose of the records x (n, 6) at times t (n,) within window (2,)."""
    from ..calibration.join import mean_pose

    inside = (t >= window[0]) & (t <= window[1])
    return mean_pose(x[inside])
