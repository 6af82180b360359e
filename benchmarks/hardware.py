"""The figures of docs/hardware.md, measured: writes docs/hardware_figures.md.

Every number docs/hardware.md quotes about the robot as built comes from this script (about two
minutes on one core):

* the paper manoeuvre (eqs. 37-38, 10 s, omega_Q = omega_R = 1) on the ideal robot, on the
  hardware with everything that is not a sensor switched off (2^24 counts, no delay, no friction,
  no limit) and the same sensed exactly (2^40 counts), and on the default hardware: RMS error
  per axis, nRMS, peak torque;
* what the LQI's knowledge of the computation delay is worth (delay compensation on / off);
* the FK estimator along the manoeuvre without control (encoders read the exact reference): pose
  and rate errors of the estimate the controller uses, and of the same filter one period late
  (what Drake's ``DiscreteDerivative``, updated at the plant instants, would give);
* stiction: a pose held with torques inside the friction band, with and without Coulomb friction.

Usage: python benchmarks/hardware.py [--out docs/hardware_figures.md] [--duration 10]
"""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from stewart_drake.base.fileio import atomic_write
from stewart_drake.base.tables import markdown_lines
from stewart_drake.control.estimator import PoseEstimator
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.kinematics import AXIS_NAMES, X_HOME
from stewart_drake.robot.servo import ServoModel
from stewart_drake.run import diagram
from stewart_drake.run.diagram import held_station
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment

CLEAN = [
    "hardware.encoders.counts_per_rev=16777216",
    "hardware.computation_delay_periods=0",
    "hardware.motors.coulomb_friction_Nm=0",
    "hardware.motors.viscous_damping=0",
    "torque_limit_Nm=1000",
]


def _nrms(rms) -> float:
    """sqrt(mean (rms_i / 1e-3)^2): the LQI's error scales (1 mrad, 1 mm)."""
    return float(np.sqrt(np.mean((np.asarray(rms) / 1e-3) ** 2)))


class _Late(PoseEstimator):
    """The same estimator with its rate one control period late (DiscreteDerivative timing), in
    the open-loop study (``track``) and in the Diagram's FK estimator system (``update``)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._previous = None

    def _late(self, v):
        late, self._previous = (v if self._previous is None else self._previous), v
        return late

    def track(self, theta, x_prev, v_prev, J_inv):
        x, v = super().track(theta, x_prev, v_prev, J_inv)
        return x, self._late(v)

    def update(self, theta, x_prev, v_prev):
        x, v = super().update(theta, x_prev, v_prev)
        return x, self._late(v)


def _lqi_reading_x(driver):
    """The LQI of ``driver`` without its own estimator: it reads ``x``, which the Diagram then
    takes from an FK estimator system (where :class:`_Late` can delay the rate)."""

    def make(context):
        return driver.make(dataclasses.replace(context, pose_estimator=None))

    return make


def closed_loop(duration_s: float) -> list:
    """Rows (label, metrics) of the paper manoeuvre on the ideal robot and the hardware."""
    runs = [
        ("ideal robot (paper_ideal)", "paper_ideal", []),
        (
            "hardware, exact sensing (2^40 counts; no delay, friction or limit)",
            "paper_hardware",
            CLEAN + ["hardware.encoders.counts_per_rev=1099511627776"],
        ),
        (
            "hardware, sensors only (2^24 counts; no delay, friction or limit)",
            "paper_hardware",
            CLEAN,
        ),
        ("hardware (paper_hardware)", "paper_hardware", []),
        (
            "hardware, LQI not told of the delay",
            "paper_hardware",
            ["controller.delay_compensation=false"],
        ),
        ("hardware, 12-bit encoders", "paper_hardware", ["hardware.encoders.counts_per_rev=4096"]),
    ]
    rows = []
    for label, base, changes in runs + [
        ("hardware, rate one period late (DiscreteDerivative timing)", "paper_hardware", "late")
    ]:
        scenario = load_scenario(
            base, [f"duration_s={duration_s}"] + ([] if changes == "late" else changes)
        )
        try:
            controller = None
            if changes == "late":  # the diagram builds the estimator
                diagram.PoseEstimator = _Late
                controller = _lqi_reading_x(scenario.controller)
            rows.append((label, run_experiment(scenario, controller=controller).metrics))
        except Exception as err:  # noqa: BLE001 - reported, not hidden
            rows.append((label, {"error": f"{type(err).__name__}: {err}".splitlines()[0]}))
        finally:
            diagram.PoseEstimator = PoseEstimator
    return rows


def estimator_open_loop(duration_s: float, counts: int = 2**17) -> dict:
    """Pose and rate errors of the FK estimate along the exact paper manoeuvre (no control)."""
    g, h = make_plan(load_scenario("paper_hardware")).geometry, 1e-3
    q = 2 * np.pi / counts
    t = np.arange(0.0, duration_s, h)
    X, V, _ = paper_manoeuvre().evaluate(t)
    measured = np.round(kinematics.ik(g, X) / q) * q
    out = {}
    for name, cls in (
        ("in the controller's update (ours)", PoseEstimator),
        ("one period late (DiscreteDerivative timing)", _Late),
    ):
        est = cls(g, h, q, X[0])
        x, v = X[0], V[0]
        J_inv = np.linalg.inv(kinematics.jacobian(g, X[0]))
        e_x, e_v = [], []
        for k in range(1, len(t)):
            x, v = est.track(measured[k], x, v, J_inv)
            if k % 20 == 0:  # the LQI refreshes J^-1 every re-schedule
                J_inv = np.linalg.inv(kinematics.jacobian(g, x))
            e_x.append(np.subtract(x, X[k]))
            e_v.append(np.subtract(v, V[k]))
        e_x, e_v = np.array(e_x), np.array(e_v)
        out[name] = {
            "pose_rms": np.sqrt((e_x**2).mean(axis=0)),
            "pose_max": np.abs(e_x).max(axis=0),
            "rate_rms": np.sqrt((e_v**2).mean(axis=0)),
        }
    return out


def stiction(duration_s: float = 1.0) -> dict:
    """Drift (max |x - x0| in 1 s) of home held with torques 60 % of the Coulomb band off."""
    servo = ServoModel()
    T = statics.holding_torques(
        make_plan(load_scenario("paper_hardware")).geometry, X_HOME
    ) + 0.6 * servo.coulomb_friction_Nm * np.array([1, -1, 1, -1, 1, -1])
    out = {}
    for label, changes in (
        ("with Coulomb friction", []),
        ("without", ["hardware.motors.coulomb_friction_Nm=0"]),
    ):
        station, simulator, context = held_station(
            load_scenario("paper_hardware", changes), X_HOME, T
        )
        simulator.AdvanceTo(duration_s)
        x = station.GetOutputPort("platform_state").Eval(context)[:6]
        out[label] = float(np.abs(x - X_HOME).max())
    return out


def _fmt(v, scale=1.0, digits=3) -> str:
    return f"{v * scale:.{digits}g}"


def render(rows, est, stick, duration_s, wall) -> str:
    L = [
        "# Hardware figures",
        "",
        f"Generated by `python benchmarks/hardware.py` ({wall:.0f} s wall). Do not edit by hand. "
        "docs/hardware.md explains them.",
        "",
        f"## Paper manoeuvre, omega_Q = omega_R = 1 ({duration_s:g} s)",
        "",
        "RMS error over the second half of the run (urad, um), nRMS with the LQI's scales "
        "(1 mrad, 1 mm), peak torque (N m), Sum T^2 dt (N^2 m^2 s), saturated control steps.",
        "",
    ]
    ideal, cells = None, []
    for label, m in rows:
        if "error" in m:
            cells.append([label, f"lost: {m['error'][:100]}"])
            continue
        nrms = _nrms(m["rms_error"])
        ideal = ideal if ideal is not None else nrms
        cells.append(
            [label, *(_fmt(v, 1e6) for v in m["rms_error"]), f"{nrms:.4g}"]
            + [f"{max(m['peak_torque']):.3f}", f"{m['sum_T2_dt']:.4g}"]
            + [int(m["status"].get("saturated_steps", 0))]
        )
    header = ["robot", *AXIS_NAMES, "nRMS", "peak T", "Sum T^2 dt", "saturated"]
    L += markdown_lines(header, cells)
    found = {label.split(" (")[0]: m for label, m in rows if "error" not in m}
    clean, exact = found.get("hardware, sensors only"), found.get("hardware, exact sensing")
    if clean and exact and ideal:
        L += [
            "",
            f"Sensors-only hardware / exact sensing of the same robot, nRMS: "
            f"**{_nrms(clean['rms_error']) / _nrms(exact['rms_error']):.3f}** (the encoders "
            f"and the FK estimate cost this much); exact sensing / ideal robot: "
            f"{_nrms(exact['rms_error']) / ideal:.3f} (the rotors' reflected inertia, with the "
            f"same weights).",
        ]
    L += [
        "",
        "## FK estimator along the exact manoeuvre (2^17 counts, no control)",
        "",
        "Pose error RMS and max (urad, um) of the chord-step FK estimate; rate error RMS "
        "(urad/s, um/s) of the 100 Hz filtered difference.",
        "",
        *markdown_lines(
            ["rate taken", "pose RMS", "pose max", "rate RMS phi..Z"],
            [
                [name, _fmt(r["pose_rms"].max(), 1e6), _fmt(r["pose_max"].max(), 1e6)]
                + [", ".join(_fmt(v, 1e6) for v in r["rate_rms"])]
                for name, r in est.items()
            ],
        ),
    ]
    L += [
        "",
        "## Stiction (home held 1 s, torques 60 % of the Coulomb band off balance)",
        "",
        *markdown_lines(["plant", "drift (rad or m)"], [[k, f"{v:.3g}"] for k, v in stick.items()]),
    ]
    return "\n".join(L) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/hardware_figures.md")
    parser.add_argument("--duration", type=float, default=10.0)
    args = parser.parse_args()
    t0 = time.perf_counter()
    rows = closed_loop(args.duration)
    est = estimator_open_loop(args.duration)
    stick = stiction()
    text = render(rows, est, stick, args.duration, time.perf_counter() - t0)
    atomic_write(Path(args.out), lambda f: f.write(text.encode()))
    print(text)


if __name__ == "__main__":
    main()
