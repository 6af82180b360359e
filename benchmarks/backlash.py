"""The figures of docs/hardware.md's "Backlash": gear play on the paper run and a breathing trace.

Each line is one run: the gearheads' play ``backlash_rad`` (0, a control of 1 urad that has the
play's model without its play, the Dynamixel X-series' 0.25 deg and the 0.5 deg and 1 deg that
bracket a planetary gearhead's), the pose error as the CLI measures it (``run``: the largest
axis's RMS and peak over t in [5, 10] s; ``reproduce breathing``: over the four measured 4 s
cycles after the first), the share of the plant-state samples at which any crank is inside its
play (off both flanks), the motors' smallest torque, and the process's CPU time per simulated
second (the whole run: build, reference check, simulation; a shared machine inflates it, so
compare lines of one invocation). Then the paper run on six Dynamixel XM430-W350 (the servo
bus's default) with the scenario's 17-bit encoders and with the servo's own 12-bit one.

Usage: python benchmarks/backlash.py [--only paper,breathing,dynamixel] (about three minutes)
"""

import argparse
import math
import time

import numpy as np

from stewart_drake.references.organ.library import OrganMotionReference
from stewart_drake.robot.motor_catalogue import catalogue_motor
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment
from stewart_drake.station.hardware import Motors

#: (label, backlash_rad): the play of every gearhead.
PLAYS = (
    ("none", 0.0),
    ("1 urad (control)", 1e-6),
    ("0.25 deg (Dynamixel X)", math.radians(0.25)),
    ("0.5 deg", math.radians(0.5)),
    ("1 deg", math.radians(1.0)),
)


def _open_fraction(state, scenario) -> float:
    """Share of the state samples (rows of ``state``) at which a crank is off both stops."""
    from stewart_drake.run.diagram import make_stewart_station

    b = scenario.hardware.motors.backlash_rad
    if b < 1e-5:  # a control play below the stops' compliance: not measured
        return float("nan")
    handles = make_stewart_station(scenario).handles
    plays = state[:, [joint.position_start() for joint in handles.plays]]
    return float(np.any(np.abs(plays) < b / 2 - 1e-6, axis=1).mean())


def _line(name: str, label: str, rms, peak, open_fraction, T_min, cpu) -> None:
    print(
        f"{name} play={label}: rms_translation_um {1e6 * max(rms[3:]):.2f} peak_translation_um "
        f"{1e6 * max(peak[3:]):.1f} rms_rotation_urad {1e6 * max(rms[:3]):.1f} "
        f"peak_rotation_urad {1e6 * max(peak[:3]):.0f} play_open_fraction {open_fraction:.3f} "
        f"min_torque_Nm {T_min:.3f} cpu_s_per_sim_s {cpu:.3f}",
        flush=True,
    )


def paper(name: str = "paper", overrides=(), motors=None) -> None:
    """The paper run (``stewart-drake run``, 10 s) at every play."""
    for label, b in PLAYS if motors is None else PLAYS[:1] + PLAYS[2:3]:
        scenario = load_scenario("paper_hardware", list(overrides))
        if motors is not None:
            scenario.hardware.motors = Motors.from_value(motors)
        scenario.hardware.motors.backlash_rad = b
        scenario.validate()
        cpu = time.process_time()
        result = run_experiment(scenario)
        cpu = (time.process_time() - cpu) / scenario.duration_s
        m = result.metrics
        opened = _open_fraction(result.state, scenario) if b > 0 else 0.0
        _line(name, label, m["rms_error"], m["peak_error"], opened, float(result.T.min()), cpu)


def breathing() -> None:
    """``stewart-drake reproduce breathing --cycles 4`` (20 s) at every play."""
    from stewart_drake.organ_motion.reproduction import reproduce

    for label, b in PLAYS:
        scenario = load_scenario("paper_hardware", [f"hardware.motors.backlash_rad={b!r}"])
        scenario.reference = OrganMotionReference(motion="breathing")
        cpu = time.process_time()
        rep = reproduce(scenario, eval_cycles=4)
        cpu = (time.process_time() - cpu) / scenario.duration_s
        f = rep.fidelity
        opened = _open_fraction(rep.result.state, scenario) if b > 0 else 0.0
        _line("breathing", label, f["rms"], f["peak"], opened, float(rep.result.T.min()), cpu)


def dynamixel() -> None:
    """The paper run on six Dynamixel XM430-W350 (catalogue servo, the bus's default), with
    the scenario's 17-bit encoders and with the servo's own 12-bit one; no play and 0.25 deg."""
    servo = catalogue_motor("XM430-W350-T").servo
    paper("paper XM430 17-bit", motors=servo)
    paper("paper XM430 12-bit", ["hardware.encoders.counts_per_rev=4096"], motors=servo)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="paper,breathing,dynamixel")
    for part in parser.parse_args().only.split(","):
        {"paper": paper, "breathing": breathing, "dynamixel": dynamixel}[part]()


if __name__ == "__main__":
    main()
