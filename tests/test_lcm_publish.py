"""Status and commands published on LCM from a running Diagram (Drake's LcmPublisherSystem fed
by our senders), received in process through ``DrakeLcm("memq://")``: no network, no multicast."""

import re
from pathlib import Path

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.lcmtypes import lcmt_stewart_command, lcmt_stewart_status
from stewart_drake.robot.kinematics import X_HOME, ik
from stewart_drake.station.lcm_publish import (
    COMMAND_CHANNEL,
    STATUS_CHANNEL,
    LoopStatus,
    add_command_publisher,
    add_status_publisher,
)

#: What each of the status sender's vector inputs is fed, all values distinct.
FED = {
    "motor_angle": 0.1 + 0.01 * np.arange(6),
    "motor_rate": -2.0 + 0.5 * np.arange(6),
    "motor_torque_applied": 0.3 - 0.1 * np.arange(6),
    "x": np.r_[0.01, -0.02, 0.03, 0.004, -0.005, 0.31, 9.0 * np.ones(6)],  # rates not sent
    "x_d": np.r_[0.0, 0.02, -0.01, 0.001, 0.002, 0.29, 7.0 * np.ones(12)],
}


class Inbox:
    """The decoded messages of ``lcm_type`` received on ``channel``."""

    def __init__(self, lcm, channel, lcm_type):
        self.lcm, self.messages = lcm, []
        lcm.Subscribe(channel, lambda data: self.messages.append(lcm_type.decode(data)))

    def drain(self) -> list:
        for _ in range(10):  # bounded: memq hands over everything queued in one call
            if self.lcm.HandleSubscriptions(10) == 0:
                break
        return self.messages


def sources(builder, values):
    return {
        name: builder.AddSystem(ConstantVectorSource(value)).get_output_port()
        for name, value in values.items()
    }


def test_the_status_and_the_command_arrive_at_their_periods_with_the_values_fed():
    lcm = DrakeLcm("memq://")
    status, command = (
        Inbox(lcm, STATUS_CHANNEL, lcmt_stewart_status),
        Inbox(lcm, COMMAND_CHANNEL, lcmt_stewart_command),
    )
    builder = DiagramBuilder()
    loop = LoopStatus(np.zeros(4))
    loop.mode, loop.deadline_misses = lcmt_stewart_status.MODE_STOPPED, 4
    loop.period_us, loop.measurement_age_us = 1012.4, 350.0
    ports = sources(builder, FED | {"loop": loop[:]})
    ports["reason"] = builder.AddSystem(
        ConstantValueSource(AbstractValue.Make("deadline missed 4 times (limit 3)"))
    ).get_output_port()
    add_status_publisher(builder, lcm, ports, period_s=0.01)
    T = np.array([0.5, -0.25, 0.125, 0.0, -0.7, 0.7])
    add_command_publisher(builder, lcm, sources(builder, {"T": T})["T"], period_s=0.02)
    Simulator(builder.Build()).AdvanceTo(0.05)

    received = status.drain()
    assert [m.utime for m in received] == [0, 10_000, 20_000, 30_000, 40_000, 50_000]
    for m in received:
        np.testing.assert_array_equal(m.theta, FED["motor_angle"])
        np.testing.assert_array_equal(m.theta_dot, FED["motor_rate"])
        np.testing.assert_array_equal(m.tau, FED["motor_torque_applied"])
        np.testing.assert_array_equal(m.x, FED["x"][:6])
        np.testing.assert_array_equal(m.x_d, FED["x_d"][:6])
        assert (m.mode, m.deadline_misses, m.period_us, m.measurement_age_us) == (3, 4, 1012, 350)
        assert m.reason == "deadline missed 4 times (limit 3)"
    commands = command.drain()
    assert [m.utime for m in commands] == [0, 20_000, 40_000]
    assert all(list(m.tau) == T.tolist() for m in commands)


def test_without_a_driver_the_status_says_running_with_nothing_measured():
    lcm = DrakeLcm("memq://")
    status = Inbox(lcm, "SIM_STATUS", lcmt_stewart_status)
    builder = DiagramBuilder()
    sender = add_status_publisher(builder, lcm, sources(builder, FED), 0.5, channel="SIM_STATUS")
    assert not sender.GetInputPort("loop").HasValue(sender.CreateDefaultContext())
    Simulator(builder.Build()).AdvanceTo(1.0)
    received = status.drain()
    assert [m.utime for m in received] == [0, 500_000, 1_000_000]
    m = received[-1]
    assert m.mode == lcmt_stewart_status.MODE_RUNNING and m.reason == ""
    assert (m.deadline_misses, m.period_us, m.measurement_age_us) == (0, 0, 0)


def test_the_status_of_the_station_is_what_its_ports_give(capsys):
    """docs/lcm.md's example as a user pastes it: the sender on the station's own outputs (the
    ideal robot, x its platform_state), the robot held at home by its holding torques; the
    messages carry what Drake's ports give."""
    text = (Path(__file__).resolve().parent.parent / "docs" / "lcm.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    (block,) = [b for b in blocks if "add_status_publisher" in b]  # not the source's, on UDP
    pasted = {"__name__": "__main__"}
    exec(compile(block, "docs/lcm.md", "exec"), pasted)
    assert capsys.readouterr().out.startswith("11 100000 (-0.0662")  # what the page shows
    received, station, ports = pasted["received"], pasted["station"], pasted["ports"]
    assert [m.utime for m in received] == [10_000 * k for k in range(11)]
    last, now = received[-1], station.GetMyContextFromRoot(pasted["simulator"].get_context())
    np.testing.assert_array_equal(last.theta, ports["motor_angle"].Eval(now))
    np.testing.assert_array_equal(last.theta_dot, ports["motor_rate"].Eval(now))
    np.testing.assert_array_equal(last.tau, ports["motor_torque_applied"].Eval(now))
    np.testing.assert_array_equal(last.x, ports["x"].Eval(now)[:6])
    # Held at home: the torques applied are the holding torques, the pose and the crank angles
    # home's (the angles by the closed-form inverse kinematics), from the first message on.
    for m in (received[0], last):
        np.testing.assert_array_equal(m.x_d, X_HOME)
        np.testing.assert_allclose(m.tau, pasted["T"], rtol=1e-12)
        np.testing.assert_allclose(m.x, X_HOME, atol=1e-5)
        np.testing.assert_allclose(m.theta, ik(station.plan.geometry, X_HOME), atol=1e-5)


@pytest.mark.parametrize(
    "period_s, channel, extra, match",
    [
        (0.0, STATUS_CHANNEL, {}, "publish period"),
        (float("nan"), STATUS_CHANNEL, {}, "publish period"),
        ("0.01", STATUS_CHANNEL, {}, "publish period"),
        (0.01, "", {}, "channel"),
        (0.01, STATUS_CHANNEL, {"motor_angles": None}, "no input port motor_angles"),
    ],
)
def test_a_bad_publisher_is_refused_before_anything_is_added(period_s, channel, extra, match):
    builder = DiagramBuilder()
    ports = sources(builder, FED)
    if extra:
        ports |= {name: ports["motor_angle"] for name in extra}
    with pytest.raises(InvalidConfigError, match=match):
        add_status_publisher(builder, DrakeLcm("memq://"), ports, period_s, channel=channel)
    assert len(builder.GetSystems()) == len(FED)
