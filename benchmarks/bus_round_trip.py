"""Round trips of the DYNAMIXEL driver against the bus emulator on a pseudo-terminal.

Six XM430-W350-T servos (ids 1..6) in the emulator (first-order model behind them), the driver
configured and torque enabled, then ``--periods`` control periods of ``read_state()`` (one
GroupSyncRead of 10 bytes from six servos) followed by ``write_torques()`` (one GroupSyncWrite
of Goal Current), back to back, at each ``--baud`` setting. Printed per setting: the median,
99th percentile and worst of the read, the write and the period (read + write), ms.

A pty moves bytes at memory speed whatever baud rate is set (the setting only changes the SDK's
reply timeout): these figures are the driver's and the emulator's software cost in one process,
not the wire's. On a real bus, add the transfer: at 1 Mbps a sync read of six servos moves
20 + 6 x 21 = 146 bytes (1.5 ms at 10 bits a byte) plus each servo's return delay time
(default 250 us), a sync write 14 + 6 x 3 = 32 bytes (0.3 ms); at 4 Mbps a quarter of the
bytes' time.

Each setting twice: the emulator in a thread of the benchmark's process (as in the tests; the
two threads share the GIL, whose 5 ms switch interval shows in the tails) and in its own process
(``python -m stewart_drake.station.bus.emulator``), nearer a real bus.

``--plant`` adds the emulator with the robot's Drake plant behind it (``StationServos``)
holding the platform at home, and prints how much model time the plant slipped behind the wall
clock (0: it kept real time).

Usage: python benchmarks/bus_round_trip.py [--periods 2000] [--baud 1000000 4000000] [--plant]
"""

import argparse
import contextlib
import subprocess
import sys
import time

import numpy as np

from stewart_drake.station.bus.driver import DynamixelBus
from stewart_drake.station.bus.emulator import BusEmulator

IDS = [1, 2, 3, 4, 5, 6]


@contextlib.contextmanager
def emulated_bus(separate_process: bool):
    """The port of an emulated bus of servos IDS: in a thread of this process, or in its own."""
    if not separate_process:
        with BusEmulator(IDS) as emulator:
            yield emulator.port
        return
    command = [sys.executable, "-m", "stewart_drake.station.bus.emulator", "--ids"]
    with subprocess.Popen(
        command + [str(i) for i in IDS], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    ) as child:
        try:
            yield child.stdout.readline().strip()
        finally:
            child.stdin.close()  # the emulator's signal to stop
            child.wait(timeout=10)


def measure(baud: int, periods: int, separate_process: bool) -> dict:
    """{"read"|"write"|"period": (n,) seconds} of ``periods`` periods at ``baud``."""
    with emulated_bus(separate_process) as port, DynamixelBus(port, baud, IDS) as bus:
        bus.configure()
        bus.enable_torque()
        tau = np.zeros(6)
        for _ in range(periods):
            state = bus.read_state()
            tau = -0.5 * state.v  # a damper: keeps the horns near rest
            bus.write_torques(tau)
        read, write = np.array(bus.read_times), np.array(bus.write_times)
    return {"read": read, "write": write, "period": read + write}


def measure_plant(baud: int, periods: int) -> dict:
    """The same against the robot's Drake plant behind the bus (StationServos), holding the
    platform at home (holding torques + a damper); also the model time the plant slipped."""
    from stewart_drake.live.plant_backend import StationServos
    from stewart_drake.robot.kinematics import X_HOME
    from stewart_drake.robot.statics import holding_torques

    backend = StationServos()
    T_hold = holding_torques(backend.station.plan.geometry, X_HOME)
    emulator = BusEmulator(IDS, backend=backend)
    with emulator, DynamixelBus(emulator.port, baud, IDS, zero_counts=np.zeros(6)) as bus:
        bus.configure()
        bus.enable_torque()
        t0 = time.perf_counter()
        for _ in range(periods):
            state = bus.read_state()
            bus.write_torques(T_hold - 0.5 * state.v)
        wall = time.perf_counter() - t0
        read, write = np.array(bus.read_times), np.array(bus.write_times)
    print(f"plant: {emulator.slipped_s:.3f} s of {wall:.2f} s slipped (model behind the wall)")
    return {"read": read, "write": write, "period": read + write}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--periods", type=int, default=2000)
    parser.add_argument("--baud", type=int, nargs="+", default=[1_000_000, 4_000_000])
    parser.add_argument("--plant", action="store_true", help="also the Drake plant behind it")
    args = parser.parse_args()
    runs = [("thread", False), ("process", True)] + [("plant", None)] * args.plant
    for where, separate in runs:
        for baud in args.baud:
            times = (
                measure_plant(baud, args.periods)
                if separate is None
                else measure(baud, args.periods, separate)
            )
            for name, t in times.items():
                ms = 1e3 * t
                print(
                    f"emulator in a {where:7s} {baud / 1e6:g} Mbps {name:6s} "
                    f"median {np.median(ms):.3f} ms  p99 {np.percentile(ms, 99):.3f} ms  "
                    f"worst {ms.max():.3f} ms  (n = {len(ms)})"
                )


if __name__ == "__main__":
    main()
