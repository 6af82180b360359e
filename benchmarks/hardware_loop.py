"""The closed loop through the servo driver, against the bus emulator, at real time.

For each reference (the paper manoeuvre, eqs. 37-38, and the breathing trace of the organ
motion library), ``--duration`` seconds of ``make_stewart_diagram`` on a scenario with ``bus``:
the HardwareStation's DynamixelDriver reads and writes six XM430-W350-T over a pty to the bus
emulator in its own process, with the robot's Drake plant behind it (``EmulatorProcess``,
its plant stepping at ``--emulator-step``), the Simulator at target realtime rate 1. The bus is
opened, configured and torque enabled here, as the robot session does.

Printed per reference: the tracking RMS and worst error (rotation mrad, translation mm) of the
*true* pose (the emulator's plant, each step against the reference at the Diagram time of its
wall-clock time), of the measured pose (the "x" log: forward kinematics of the servos' angles),
and of the pure simulation of the same scenario (the robot as built with those servos, the
simulated station, started at rest as the robot is); then the driver's timing summary and the
machine's load average.

Usage: python benchmarks/hardware_loop.py [--duration 10] [--period 0.01] [--omega-q 0.01]
    [--emulator-step 0.002] [--references paper breathing]
"""

import argparse
import dataclasses
import os
import time

import numpy as np
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import Simulator

from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.live.emulator_process import EmulatorProcess
from stewart_drake.references.organ.library import OrganMotionReference
from stewart_drake.references.trajectories import NamedReference
from stewart_drake.run.diagram import make_stewart_diagram
from stewart_drake.run.plan import as_built, make_plan
from stewart_drake.run.scenario import Scenario
from stewart_drake.station.bus.servos import DynamixelBusConfig
from stewart_drake.station.guard import GuardConfig

REFERENCES = {"paper": NamedReference, "breathing": OrganMotionReference}


def rms_worst(e) -> str:
    """'rot RMS / worst mrad, trans RMS / worst mm' of errors e (n, 6)."""
    rot, pos = e[:, :3], e[:, 3:]
    return (
        f"rot {1e3 * np.sqrt((rot**2).mean()):7.2f} / {1e3 * np.abs(rot).max():7.2f} mrad, "
        f"trans {1e3 * np.sqrt((pos**2).mean()):6.3f} / {1e3 * np.abs(pos).max():6.3f} mm"
    )


def logged_error(sd, root) -> np.ndarray:
    log = sd.loggers["x"].FindLog(root)
    x_d = np.array([sd.trajectory.evaluate(t)[0] for t in log.sample_times()])
    return log.data().T[:, :6] - x_d


def simulated(fields: dict) -> np.ndarray:
    """The pure simulation's errors: the same run on the simulated robot as built."""
    scenario = dataclasses.replace(as_built(Scenario(**fields, bus=DynamixelBusConfig())), bus=None)
    sd = make_stewart_diagram(scenario)
    simulator = Simulator(sd.diagram)
    context = simulator.get_mutable_context()
    sd.initialize(context)
    sd.station.assemble(context, sd.trajectory.evaluate(0.0)[0])  # at rest, as the robot
    simulator.Initialize()
    simulator.AdvanceTo(fields["duration_s"])
    return logged_error(sd, simulator.get_context())


def on_the_bus(fields: dict, emulator_step: float):
    """(true errors, measured errors, driver) of the run through the driver."""
    x0 = make_plan(Scenario(**fields)).reference.evaluate(0.0)[0]
    robot = Scenario(
        plant=MultibodyPlantConfig(time_step=emulator_step, discrete_contact_approximation="sap"),
        control_period_s=emulator_step,
        log_period_s=emulator_step,
    )
    with EmulatorProcess(x0=x0, scenario=robot) as emu:
        bus_config = DynamixelBusConfig(
            port=emu.port, reply_timeout_s=1.0, watchdog_s=1.0, max_deadline_misses=10**6
        )
        sd = make_stewart_diagram(Scenario(**fields, bus=bus_config))
        bus = sd.station.bus
        with bus:
            bus.configure()
            simulator = Simulator(sd.diagram)
            simulator.set_target_realtime_rate(1.0)
            context = simulator.get_mutable_context()
            sd.initialize(context)
            sd.station.assemble(context, x0)
            simulator.Initialize()
            bus.enable_torque()
            try:
                simulator.AdvanceTo(fields["duration_s"])
            except Exception as err:  # a lost loop: report what it did
                print(f"  the run stopped: {type(err).__name__}: {str(err)[:160]}")
    driver = sd.station.driver
    walls = driver.timing.rows()[:, 0]
    t_true, x_true = emu.truth()
    inside = (t_true >= walls[0]) & (t_true <= walls[-1])
    t_run = np.interp(t_true[inside], walls, fields["control_period_s"] * np.arange(len(walls)))
    x_d = np.array([sd.trajectory.evaluate(t)[0] for t in t_run])
    return x_true[inside, :6] - x_d, logged_error(sd, simulator.get_context()), driver


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--period", type=float, default=0.01, help="control period, s")
    parser.add_argument("--omega-q", type=float, default=0.01, help="the LQI's omega_Q")
    parser.add_argument("--emulator-step", type=float, default=0.002)
    parser.add_argument("--references", nargs="+", default=list(REFERENCES))
    args = parser.parse_args()
    for name in args.references:
        fields = dict(
            reference=REFERENCES[name](),
            controller=LqiDriver(omega_Q=args.omega_q),
            duration_s=args.duration,
            control_period_s=args.period,
            log_period_s=args.period,
            guard=GuardConfig(max_tracking_error=None),
        )
        print(
            f"{name}: {args.duration:g} s, period {1e3 * args.period:g} ms, "
            f"omega_Q {args.omega_q:g}, load average {os.getloadavg()[0]:.2f}"
        )
        t0 = time.perf_counter()
        true, measured, driver = on_the_bus(fields, args.emulator_step)
        print(f"  on the bus, true pose:     {rms_worst(true)}")
        print(f"  on the bus, measured pose: {rms_worst(measured)}")
        print(f"  pure simulation:           {rms_worst(simulated(fields))}")
        for line in driver.timing_lines():
            print(f"  {line}")
        print(
            f"  ({time.perf_counter() - t0:.0f} s wall; load average now {os.getloadavg()[0]:.2f})"
        )


if __name__ == "__main__":
    main()
