"""A calibration over the bus emulator: the robot as built behind the bus (its encoders' zero
errors read by the servos), the robot session driving a planned path and logging its readings,
the join of its encoder log with an emulated tracker's file, and the whole rehearsal
(``calibrate --rehearse --bus``) on a few poses (slow)."""

import dataclasses
import time

import numpy as np
import pytest
from conftest import require_extra

require_extra("robot")

from stewart_drake.calibration import files, join, poses  # noqa: E402
from stewart_drake.calibration.tracker import MeasurementNoise, track  # noqa: E402
from stewart_drake.live.calibrate_command import BUS_REHEARSAL_FILES  # noqa: E402
from stewart_drake.live.calibration_rehearsal import (  # noqa: E402
    LOOP_TIMEOUT_S,
    REHEARSAL_BUS,
    emulated_bus,
)
from stewart_drake.live.plant_backend import (  # noqa: E402
    StationServos,
    behind_the_bus,
    dynamixel_scenario,
)
from stewart_drake.live.session import end_line, run_on_robot  # noqa: E402
from stewart_drake.references.traces import TraceReference, load_trace  # noqa: E402
from stewart_drake.robot.legs import LegParameters, readings  # noqa: E402
from stewart_drake.robot.tolerances import Tolerances  # noqa: E402
from stewart_drake.run.plan import make_plan  # noqa: E402
from stewart_drake.run.scenario import Robot  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402
from stewart_drake.station.bus.driver import DynamixelBus  # noqa: E402
from stewart_drake.station.bus.emulator import BusEmulator  # noqa: E402
from stewart_drake.station.bus.servos import DynamixelBusConfig  # noqa: E402

QUANTUM = 2 * np.pi / 4096  # the servos' encoders
X_REST = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.28])


def _robot():
    """The robot scenario (paper_bus) with a tolerant bus (a loaded machine runs late), its
    nominal geometry, and a robot as built drawn from it with seed 4."""
    scenario = load_scenario("paper_bus")
    scenario.bus = dataclasses.replace(scenario.bus, **REHEARSAL_BUS)
    nominal = make_plan(scenario, with_reference=False).geometry
    return scenario, nominal, Tolerances().draw(nominal, 4)


def test_the_servos_read_the_robot_as_built_s_encoder_zeros():
    """Read back over the bus: what each servo reports is the as-built crank angle plus its
    encoder's zero error, to half a count; not the nominal robot's reading."""
    scenario, nominal, truth = _robot()
    behind = behind_the_bus(scenario, robot_as_built=Robot.from_value(truth.geometry(nominal)))
    backend = StationServos(dynamixel_scenario(scenario=behind), x0=X_REST)
    with BusEmulator([1, 2, 3, 4, 5, 6], backend=backend) as emu:
        with DynamixelBus.from_config(DynamixelBusConfig(port=emu.port)) as bus:
            q = bus.read_state().q
    expected = readings(nominal, truth, X_REST[None])[0]
    assert np.max(np.abs(q - expected)) <= 0.5 * QUANTUM + 1e-12, (q - expected) / QUANTUM
    nominal_q = readings(nominal, LegParameters.nominal(nominal), X_REST[None])[0]
    assert np.max(np.abs(q - nominal_q - truth.encoder_offsets_rad)) > 2 * QUANTUM


def test_the_session_logs_readings_that_join_with_a_tracker_at_each_window(tmp_path):
    """Two poses driven over the emulated bus, the robot as built behind it: the encoder log's
    readings, joined with a tracker following the plant's true pose, are the as-built robot's
    readings at the tracked pose, to about a count (the windows are where the robot rests)."""
    scenario, nominal, truth = _robot()
    plan = make_plan(scenario, with_reference=False)
    x = poses.candidate_poses(nominal, 2, 7, motor_limits=plan.motor_limits)
    path = poses.pose_path(nominal, x, dwell_s=1.5, motor_limits=plan.motor_limits)
    poses_csv, windows_csv = files.write_path(tmp_path / "poses.csv", path)
    robot = dataclasses.replace(
        scenario,
        reference=TraceReference(path=str(poses_csv)),
        duration_s=float(load_trace(poses_csv).end_time),
    )
    robot.guard.divergence_dir = str(tmp_path / "diverged")
    emulator = emulated_bus(robot, Robot.from_value(truth.geometry(nominal)))
    try:
        robot.bus.port = emulator.port
        run = run_on_robot(
            robot,
            home_s=1.0,
            loop_timeout_s=LOOP_TIMEOUT_S,
            out=tmp_path,
            stem="robot",
            say=lambda s: None,
        )
    finally:
        emulator.close()
    assert run.ok and run.torque_off_confirmed and run.encoder_log is not None, end_line(run)
    record = np.array(emulator.backend.record).reshape(-1, 13)
    t_true, x_true = record[:, 0], record[:, 1:7]
    log = join.read_table(
        run.encoder_log, "encoder log", join.ENCODER_LOG_COLUMNS, "", nan_ok=("t_path",)
    )
    assert np.all(np.diff(log["time"]) > 0) and np.all(np.diff(log["t_run"]) > 0)
    assert np.isnan(log["t_path"][0]) and log["t_path"][-1] > path.t[-1] - 0.5
    # The tracker on the log's clock (the session's perf_counter and its epoch offset).
    t_tracked, x_tracked = track(
        t_true + (time.time() - time.perf_counter()), x_true, MeasurementNoise(0.0, 0.0), 0
    )
    tracker = join.write_tracker_file(tmp_path / "tracker.csv", t_tracked, x_tracked)
    joined = join.join(run.encoder_log, tracker, windows_csv)
    assert len(joined.poses) == 2 and np.all(joined.tracker_used >= 20)
    error = joined.readings - readings(nominal, truth, joined.poses)
    assert np.max(np.abs(error)) < 1.5 * QUANTUM, error / QUANTUM
    # And not the nominal robot's: the zero errors are in the readings.
    nominal_error = joined.readings - readings(
        nominal, LegParameters.nominal(nominal), joined.poses
    )
    assert np.max(np.abs(nominal_error)) > 3 * QUANTUM


@pytest.mark.slow
def test_the_rehearsal_over_the_bus_identifies_the_robot_as_built(tmp_path):
    """``calibrate --rehearse --bus``'s rehearsal on 16 poses, 2 s at each (about 2 minutes):
    the identified robot predicts the held-out readings much better than the nominal one, down
    to the 12-bit encoders' quantization; its encoder zeros within their stated standard
    deviations; each window's joined readings the as-built robot's to about a count."""
    from stewart_drake.live.calibration_rehearsal import rehearse_on_bus

    scenario, nominal, _ = _robot()
    r = rehearse_on_bus(scenario, 16, tmp_path, seed=4, dwell_s=2.0, n_candidates=500, say=print)
    print(r.text())
    assert r.run.ok
    # Measured: before 2 mrad, after 471 urad against the quantized readings (their own
    # quantization, 443 urad RMS, is the floor), 225 urad against the exact ones, the zeros
    # within 1.9 std (by least squares, before the tolerances' prior: 440 and 198 urad).
    assert r.model_rad < 0.25 * r.before_rad and r.after_rad < 0.3 * r.before_rad, r.text()
    assert r.after_rad < 1.3 * r.noise.quantization_rms_rad, r.text()
    assert np.all(np.abs(r.offsets_error_rad) < 3 * r.offsets_std_rad), r.text()
    assert np.sqrt(np.mean((r.offsets_error_rad / r.offsets_std_rad) ** 2)) < 2.0, r.text()
    assert np.max(np.abs(r.reading_error_rad)) < 1.5 * QUANTUM, r.text()
    # What it wrote is what the command checks before the drive: a file added to one is added
    # to the other.
    assert {p.name for p in r.files.values()} == set(BUS_REHEARSAL_FILES)


def test_the_bus_rehearsal_plans_the_poses_its_selection_picks(tmp_path):
    """``--rehearse --bus --select random`` drives random poses, chosen ones by default: the
    path's poses are the picked candidates, in the tour's order."""
    from stewart_drake.calibration.rehearsal import pick
    from stewart_drake.live.calibration_rehearsal import _plan_path

    plan = make_plan(load_scenario("paper_bus"), with_reference=False)
    noise, tolerances = MeasurementNoise(), Tolerances()
    planned = {}
    for select in ("random", "chosen"):
        folder = tmp_path / select
        folder.mkdir()
        space, written = _plan_path(
            plan.geometry, plan.motor_limits, 12, noise, tolerances, 4, 2.0, 300, folder, select
        )
        picked = space.candidates[pick(plan.geometry, space, 12, select, noise, tolerances, 4)]
        windows = join.read_table(written["windows"], "windows", join.WINDOW_COLUMNS, "")
        planned[select] = np.column_stack([windows[n] for n in files.POSE_COLUMNS])
        np.testing.assert_array_equal(_rows_sorted(planned[select]), _rows_sorted(picked))
    assert not np.allclose(_rows_sorted(planned["random"]), _rows_sorted(planned["chosen"]))


def _rows_sorted(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]
