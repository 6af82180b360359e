"""The closed loop through the servo driver with no wall clock in its results: what two versions
of the code compute for the same run, compared.

The paper manoeuvre's scenario on the robot built with XM430s (tests/test_hardware_station.py's
``bus_scenario``: 5 ms, the LQI with the estimator from the encoders) for ``--duration`` s,
through the HardwareStation's driver to ``PlantBus`` (the robot's Drake plant stepped one control
period per read, the torque written in the previous period: a real bus's order without its
timing). Saves the logged measured poses ("x", float32), the applied torques ("T"), the plant
states ("state") and the plant's true state at the end; ``--compare A B`` prints the largest
difference of each between two such files.

Usage: python benchmarks/plant_bus_run.py --out main.npz [--duration 1.5] (with the code to
    measure on PYTHONPATH, run from the repository whose tests/ to use)
       python benchmarks/plant_bus_run.py --compare main.npz branch.npz
"""

import argparse
import sys
from pathlib import Path

import numpy as np


def run(duration: float, out: str) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from pydrake.systems.analysis import Simulator
    from test_hardware_station import PlantBus, bus_scenario

    from stewart_drake.run.diagram import make_stewart_diagram

    sd = make_stewart_diagram(bus_scenario(duration_s=duration))
    x0 = sd.trajectory.evaluate(0.0)[0]
    bus = PlantBus(x0)
    sd.station.use_bus(bus)
    simulator = Simulator(sd.diagram)
    context = simulator.get_mutable_context()
    sd.initialize(context)
    sd.station.assemble(context, x0)
    simulator.Initialize()
    simulator.AdvanceTo(duration)
    root = simulator.get_context()
    logs = {name: sd.loggers[name].FindLog(root).data().T for name in ("x", "T", "state")}
    np.savez(out, **logs, true=bus.true_state())
    print(f"wrote {out}: " + ", ".join(f"{k} {v.shape}" for k, v in logs.items()))


def compare(a: str, b: str) -> None:
    from stewart_drake.base.npz import CheckedNpz

    remedy = "give two archives this benchmark wrote (--out)"
    first, second = (CheckedNpz(path, "plant_bus_run archive", remedy) for path in (a, b))
    for name in first.arrays:
        x, y = first.array(name), second.array(name)
        what = f"{np.abs(x - y).max():.3g}" if x.shape == y.shape else f"{x.shape} vs {y.shape}"
        print(f"max_abs_difference_{name} {what}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=1.5)
    parser.add_argument("--out", default="plant_bus_run.npz")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = parser.parse_args()
    if args.compare:
        compare(*args.compare)
    else:
        run(args.duration, args.out)


if __name__ == "__main__":
    main()
