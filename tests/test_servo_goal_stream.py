"""The servos' own position loop in a run: the host's goals (control/servo/goal_stream), the loop's
settings and gains (station/bus/position_mode), the scenario that pairs them and the driver that
writes them, each checked against numbers worked out here."""

import math

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control.contract import ControllerContext
from stewart_drake.control.servo.goal_stream import CrankGoalStreamer, ServoPositionDriver
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.kinematics import X_HOME, ik
from stewart_drake.robot.motor_catalogue import catalogue_motor
from stewart_drake.run.scenario import Scenario
from stewart_drake.station.bus.position_mode import ServoPositionLoop, crank_inertia
from stewart_drake.station.bus.servos import DynamixelBusConfig, servo_spec

H = 0.01  # the bus robots' control period, s
X0 = X_HOME + np.array([0.01, -0.02, 0.005, 0.004, -0.003, 0.002])
V0 = np.array([0.05, 0.02, -0.04, 0.01, 0.006, -0.008])
A0 = np.array([-0.3, 0.2, 0.1, -0.05, 0.04, 0.02])


def _pose(t):
    """A pose moving with constant acceleration: its extrapolation to second order is exact."""
    return X0 + V0 * t + 0.5 * A0 * t * t


def test_each_goal_is_the_references_crank_angles_a_lead_ahead_with_the_profile_that_reaches_it():
    """Sampled at tau, the goal is the inverse kinematics of the reference at tau + lead (the
    pose carried forward by its rate and acceleration: exact for this motion) and each Profile
    Velocity the step from the goal before it over one period; before the first sample the goal
    is the pose a period on from the start."""
    geometry, lead, tau = StewartGeometry(), 0.019, 0.3
    system = CrankGoalStreamer(geometry, H, 5e-4, lead, X0, V0)
    context = system.CreateDefaultContext()
    first = system.GetOutputPort("crank_goal").Eval(context).copy()
    start = ik(geometry, X0[None, :])[0]
    ahead = ik(geometry, (X0 + V0 * H)[None, :])[0]
    np.testing.assert_allclose(first[:6], ahead, atol=1e-12)
    np.testing.assert_allclose(first[6:], np.abs(ahead - start) / H, atol=1e-9)
    x_d = np.concatenate([_pose(tau), V0 + A0 * tau, A0])
    system.get_input_port(0).FixValue(context, x_d)
    state = system.EvalUniquePeriodicDiscreteUpdate(context)
    goal = state.get_vector(0).CopyToVector()
    want = ik(geometry, _pose(tau + lead)[None, :])[0]
    np.testing.assert_allclose(goal[:6], want, atol=1e-12)
    np.testing.assert_allclose(goal[6:], np.abs(want - ahead) / H, atol=1e-9)
    assert np.all(goal[6:] > 0.0)
    np.testing.assert_array_equal(system.GetOutputPort("T").Eval(context), np.zeros(6))


def test_a_goal_no_crank_reaches_is_refused_naming_the_leg():
    from stewart_drake.base.errors import UnreachablePoseError

    far = X_HOME + np.array([0, 0, 0, 0.0, 0.0, 0.3])  # 30 cm above home: no leg closes
    with pytest.raises(UnreachablePoseError, match="leg"):
        CrankGoalStreamer(StewartGeometry(), H, 5e-4, 0.019, far)


def test_the_lead_is_the_write_delay_and_the_period_the_profile_takes():
    """Sampled half a plant step into period k (the reference half a step further on), a goal is
    written at the start of period k + d and reached a period later: (d + 1) h - h_p after the
    reference's instant at the sample; plus extra_lead_s."""
    context = ControllerContext(
        geometry=StewartGeometry(),
        period_s=0.01,
        offset_s=5e-4,
        plant_time_step_s=1e-3,
        x_initial=X_HOME,
        delay_periods=1,
    )
    assert ServoPositionDriver().lead_s(context) == pytest.approx(0.019, abs=1e-15)
    assert ServoPositionDriver(extra_lead_s=0.002).lead_s(context) == pytest.approx(0.021)
    with pytest.raises(InvalidConfigError, match="controller.extra_lead_s"):
        ServoPositionDriver(extra_lead_s=-0.001).validate(0.01, 1)


def test_the_loops_table_gains_are_the_e_manuals_units_of_the_designed_loop():
    """PM42-010 on the phantom's crank: the inertia its loop drives is its rotor reflected plus
    a sixth of the platform and the rod at the crank's tip; K_P = J w^2 R / k, K_I = K_P w /
    ratio, K_D = (2 zeta w J - k^2 / R) R / k, K_FF = k, in PWM units (of pwm_full over 24 V)
    per count, over 128, 65536 / h, 16 h and 4 h (the X series' divisors), worked here."""
    from stewart_drake.run.scenario_io import load_scenario

    geometry = load_scenario("phantom_bus").robot.build()
    model = "PM42-010-S260-R"
    spec = servo_spec(model, torque_control=False)
    share = (1.0 / 6 + 0.08) * 0.11**2  # the phantom's platform 1 kg, rod 80 g, crank 11 cm
    J = catalogue_motor(model).servo.reflected_inertia + share
    assert crank_inertia(geometry, model) == pytest.approx(J, rel=1e-12)
    k, R, V, h = 2.8333333333333335, 24.0 / 1.2, 24.0, 1e-3  # 3.4 N m at 1.2 A; 24 V
    w, zeta, ratio = 2 * math.pi * 30.0, 1.4, 4.0
    kp = J * w * w * R / k
    si = ((2 * zeta * w * J - k * k / R) * R / k, kp * w / ratio, kp, k)
    pwm_per_count = 2009 / V * (2 * math.pi / 526_374)  # PWM units per count per volt-rad
    scales = (16.0 / h, 65536.0 * h, 128.0, 4.0 / h)
    want = tuple(round(g * pwm_per_count * s) for g, s in zip(si, scales, strict=True))
    raw = ServoPositionLoop(30.0, 1.4, 4.0).raw_gains(spec, J)
    assert raw == want
    assert all(0 < v <= 32767 for v in raw)


@pytest.mark.parametrize(
    "loop, match",
    [
        (ServoPositionLoop(bandwidth_hz=0.0), "bus.position_loop.bandwidth_hz"),
        (ServoPositionLoop(bandwidth_hz=60.0), "bus.position_loop.bandwidth_hz"),
        (ServoPositionLoop(damping=-1.0), "bus.position_loop.damping"),
        (ServoPositionLoop(integral_ratio=0.5), "bus.position_loop.integral_ratio"),
    ],
)
def test_a_bad_position_loop_is_refused_naming_the_field(loop, match):
    with pytest.raises(InvalidConfigError, match=match):
        loop.validate(servo_spec("XM430-W350-T", torque_control=False))


def _bus_scenario(controller, loop):
    bus = DynamixelBusConfig(port="/dev/null", position_loop=loop)
    return Scenario(controller=controller, control_period_s=H, log_period_s=H, bus=bus)


def test_the_scenario_pairs_the_servos_loop_with_the_controller_that_streams_its_goals():
    xm430_loop = ServoPositionLoop(8.0, 1.0)  # what fits an XM430's table on this crank
    _bus_scenario(ServoPositionDriver(), xm430_loop).validate()
    from stewart_drake.control.servo.driver import CrankServoDriver

    with pytest.raises(InvalidConfigError, match="bus.position_loop set"):
        _bus_scenario(CrankServoDriver(), xm430_loop).validate()
    with pytest.raises(InvalidConfigError, match="bus.position_loop null"):
        _bus_scenario(ServoPositionDriver(), None).validate()
    with pytest.raises(InvalidConfigError, match="ServoPositionDriver"):
        Scenario(controller=ServoPositionDriver()).validate()  # no bus at all


class GoalBus:
    """A bus in Position Control Mode that keeps what it is told: the goals written, the reads
    answered from the robot at rest where it is."""

    position_gains_raw = (1, 2, 3, 4)

    def __init__(self, theta):
        from stewart_drake.station.bus.protocol import BusState

        self.state = BusState(np.asarray(theta, float), np.zeros(6), np.zeros(6), 0.0, 0.0)
        self.goals: list = []

    def write_goals(self, q, profile):
        self.goals.append((np.array(q), np.array(profile)))

    def write_torques(self, tau):  # pragma: no cover - a position-mode driver never calls it
        raise AssertionError("torques written to servos in Position Control Mode")

    def read_state(self):
        return self.state

    def torque_off(self):
        return True


def test_the_driver_writes_the_goals_with_the_encoders_zero_errors_and_no_torque():
    """On a calibrated robot (encoder i reads theta_i + offset_i) the goal the servo is sent is
    the crank's angle plus its encoder's zero error, and its profile as given; the torque input
    is never read into a write."""
    from stewart_drake.station.bus.station import DynamixelDriver

    offsets = (0.004, -0.003, 0.002, -0.001, 0.005, -0.002)
    geometry = StewartGeometry(encoder_offsets_rad=offsets)
    theta = ik(geometry, X_HOME[None, :])[0]
    bus = GoalBus(theta + np.asarray(offsets))
    builder = DiagramBuilder()
    driver = builder.AddSystem(DynamixelDriver(bus, geometry, H, max_deadline_misses=10**6))
    assert driver.HasInputPort("crank_goal")
    goal = np.concatenate([theta + 0.01, np.full(6, 0.25)])
    source = builder.AddSystem(ConstantVectorSource(goal))
    builder.Connect(source.get_output_port(), driver.GetInputPort("crank_goal"))
    torque = builder.AddSystem(ConstantVectorSource(np.full(6, np.nan)))
    builder.Connect(torque.get_output_port(), driver.GetInputPort("motor_torque"))
    from pydrake.systems.analysis import Simulator

    simulator = Simulator(builder.Build())
    driver.seed(driver.GetMyMutableContextFromRoot(simulator.get_mutable_context()))
    simulator.AdvanceTo(2.5 * H)
    assert len(bus.goals) == 3
    for q, profile in bus.goals:
        np.testing.assert_allclose(q, theta + 0.01 + np.asarray(offsets), atol=1e-15)
        np.testing.assert_array_equal(profile, np.full(6, 0.25))


def test_a_loop_whose_gains_do_not_fit_the_table_is_refused_when_the_scenario_is_read():
    """paper_bus's XM430 on its crank at 12 Hz: an I Gain of K_P w / 4 over the table's unit,
    35998 against its 16383 (the raw gains test above works such figures out), refused with
    the field's name before anything runs; 8 Hz fits."""
    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario("paper_bus")
    scenario.controller = ServoPositionDriver()
    scenario.bus.position_loop = ServoPositionLoop(12.0, 1.0)
    with pytest.raises(InvalidConfigError, match=r"bus.position_loop.bandwidth_hz: .* 35998 "):
        scenario.validate()
    scenario.bus.position_loop = ServoPositionLoop(8.0, 1.0)
    scenario.validate()


def test_the_driver_makes_the_streamer_of_its_context():
    """What make() builds, read back: the context's robot, period and sample offset (its update
    event's), the lead of lead_s (extra_lead_s on top), the start pose's goals; a lead below 0
    (no delay, a long plant step) is 0."""
    geometry = StewartGeometry()
    context = ControllerContext(
        geometry=geometry,
        period_s=0.02,
        offset_s=1e-3,
        plant_time_step_s=2e-3,
        x_initial=X0,
        x_dot_initial=V0,
        delay_periods=2,
    )
    driver = ServoPositionDriver(extra_lead_s=0.004)
    system = driver.make(context)
    assert system.geometry is geometry and system.period_s == 0.02
    assert system.lead_s == pytest.approx(3 * 0.02 - 2e-3 + 0.004, abs=1e-15)
    events = system.GetUniquePeriodicDiscreteUpdateAttribute()
    assert (events.period_sec(), events.offset_sec()) == (0.02, 1e-3)
    goal = system.GetOutputPort("crank_goal").Eval(system.CreateDefaultContext())
    np.testing.assert_allclose(goal[:6], ik(geometry, (X0 + V0 * 0.02)[None, :])[0], atol=1e-12)
    assert driver.summary() == {"extra_lead_s": 0.004}
    assert driver.validate(0.02, 4) is driver
    late = ControllerContext(
        geometry=geometry, period_s=0.001, offset_s=0.0, plant_time_step_s=0.002,
        x_initial=X_HOME, delay_periods=0,
    )  # fmt: skip
    assert ServoPositionDriver().lead_s(late) == 0.0


@pytest.mark.parametrize(
    "extra, delay, words",
    [
        (1.0 + 1e-9, 1, r"^ctl\.extra_lead_s must be"),
        (-1e-9, 1, r"^ctl\.extra_lead_s must be"),
        (0.0, 5, "a computation delay of 5 periods: the goals would lead"),
    ],
)
def test_the_drivers_option_and_delay_are_refused_past_their_bounds(extra, delay, words):
    ServoPositionDriver(extra_lead_s=1.0).validate(0.01, 4, prefix="ctl.")  # both at the bound
    with pytest.raises(InvalidConfigError, match=words):
        ServoPositionDriver(extra_lead_s=extra).validate(0.01, delay, prefix="ctl.")


@pytest.mark.parametrize(
    "period, lead, named",
    [(0.0, 0.01, "period_s"), (1.0 + 1e-9, 0.01, "period_s"), (H, -1e-9, "lead_s"),
     (H, 1.0 + 1e-9, "lead_s")],
)  # fmt: skip
def test_the_streamer_refuses_a_period_or_lead_past_its_bounds(period, lead, named):
    geometry = StewartGeometry()
    CrankGoalStreamer(geometry, 1.0, 0.0, 1.0, X_HOME)  # at the bounds: taken
    CrankGoalStreamer(geometry, H, 0.0, 0.0, X_HOME)
    with pytest.raises(InvalidConfigError, match=f"^{named} must be"):
        CrankGoalStreamer(geometry, period, 0.0, lead, X_HOME)
