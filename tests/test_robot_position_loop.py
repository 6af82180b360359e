"""A session on servos running their own position loop: the phantom's robot, its six PM42s as the
realistic emulator draws them (their own motor constants, windings, friction, rotors, play and
encoder noise, never the controller's model), Position Control Mode with the loop's gains, the
host streaming the reference's crank angles each period; the emulator on the loop's clock (its
firmware's 1 ms cannot keep real time on a loaded machine: docs/robot.md)."""

import numpy as np
import pytest
from conftest import LOADED_MACHINE_BUS, require_extra

require_extra("robot")

from stewart_drake.control.servo.goal_stream import ServoPositionDriver  # noqa: E402
from stewart_drake.live.session import run_on_robot  # noqa: E402
from stewart_drake.references.organ.library import OrganMotionReference  # noqa: E402
from stewart_drake.run.plan import run_reference  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402
from stewart_drake.station.bus.position_mode import ServoPositionLoop  # noqa: E402

#: One encoder count at the phantom's platform along X, m (docs/robot.md: about 1 um).
COUNT_X_M = 1.04e-6


def _compiled_signatures() -> dict:
    """Every signature compiled so far of the servos' loop's kernels (the goals' IK, their
    sync write, the bus's reading)."""
    from stewart_drake.control.servo import kernels as servo
    from stewart_drake.station.bus import kernels as bus

    dispatchers = {
        "crank_reference": servo.crank_reference,
        "fill_goal_write": bus.fill_goal_write,
        "parse_status": bus.parse_status,
        "measure_pose": bus.measure_pose,
    }
    return {name: list(f.signatures) for name, f in dispatchers.items()}


def _phantom_on_its_servos_loop(duration_s: float):
    scenario = load_scenario("phantom_bus")
    scenario.controller = ServoPositionDriver()
    scenario.bus.position_loop = ServoPositionLoop()
    scenario.reference = OrganMotionReference(motion="breathing")
    scenario.duration_s = duration_s
    for name, value in LOADED_MACHINE_BUS.items():
        setattr(scenario.bus, name, value)
    return scenario.validate()


def test_the_phantom_on_its_servos_own_loop_follows_breathing_within_tens_of_micrometres(
    tmp_path,
):
    """Realistic servos (seed 0) behind the bus in a process of their own, on the loop's clock,
    as ``robot --emulate`` runs them: the platform's true X (the emulator's plant) within 40 um
    RMS of the breathing, and its encoders' X too (16 um each in a session, docs/robot.md), and
    not below a count (nothing reads closer than its encoders); the truth and the encoders
    within 10 um RMS of each other (the loop's clock pairs them); every period one sync write of
    goals; torque off at the end. A goal taken without the lead (the reference's own instant)
    would trail by 19 ms, 0.3 mm at the breath's speed. Nothing compiled after torque on."""
    from stewart_drake.live.emulator_process import start_emulator, truth_and_reading

    scenario = _phantom_on_its_servos_loop(8.0)
    assert scenario.emulator.clock == "loop" and scenario.emulator.servos == "realistic"
    x0 = run_reference(scenario).evaluate(np.array([0.0]))[0][0]
    emulator = start_emulator(scenario, x0)
    held = {}
    try:
        run = run_on_robot(
            scenario,
            home_s=1.0,
            loop_timeout_s=10.0,
            out=tmp_path,
            say=lambda line: None,
            before_torque=lambda sd, simulator: held.update(sd=sd, kernels=_compiled_signatures()),
        )
    finally:
        emulator.close()
    assert run.ok and run.torque_off_confirmed, run.reason
    assert _compiled_signatures() == held["kernels"]
    sd = held["sd"]
    e_true, e_read = truth_and_reading(sd, emulator.truth(), (4.0, 9.0), loop_clock=True)
    rms_true = np.sqrt(np.mean(e_true**2, axis=0))
    rms_read = np.sqrt(np.mean(e_read**2, axis=0))
    assert COUNT_X_M < rms_true[3] < 40e-6, rms_true
    assert COUNT_X_M < rms_read[3] < 40e-6, rms_read
    assert abs(rms_true[3] - rms_read[3]) < 10e-6
    periods = sd.station.driver.timing_summary()["periods"]
    assert periods == pytest.approx(sd.plan.duration_s / scenario.control_period_s, abs=2)
    assert sd.plan.duration_s >= 9.0  # the homing and the 8 s of breathing
