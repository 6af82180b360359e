"""Real-time factors of the station alone and of the full Diagram, their ratios, where time goes.

Measured in ONE process and interleaved (so a busy machine slows all alike), ``--repeats`` times
each, medians printed:

* ``plant_alone``: the station of the scenario (the MultibodyPlant with its hardware: servos,
  friction, encoders, delay, current loop) under constant holding torques;
* ``full_ann``: the whole closed-loop Diagram of the scenario with the ANN tuner (the LQI with
  its estimator, density features, tuner, loggers, guard);
* ``full_fixed``: the same with fixed weights (no features, no tuner);
* ``noop``: the ANN Diagram holding home with every Python callback a no-op: what Drake's
  framework, the station's hardware systems, the loggers and the Python dispatch cost alone,
  the ceiling of the ratio;
* ``moving``: the station alone replaying, open loop, the torques of 2 s of a closed-loop run:
  the plant's own cost on the manoeuvre (SAP iterates more on a moving platform than on one
  held at home), the denominator of a second ratio that compares the same plant work.

Each ratio (full / plant_alone) is taken within a pair measured back to back; the medians of
``--repeats`` pairs are printed, one line per figure, e.g.
``ratio_ann_over_plant 0.62 (median of 5 interleaved pairs; range 0.58 .. 0.66)``.

First come what users pay: ``cpu_per_sim_s_<run>``, the CPU seconds per simulated second of the
closed loop as the scenario is (``fixed``), with the ANN tuner, of the station held and moving,
and with ``--reproduce MOTION`` of a whole ``reproduce`` (its checks, run and report) of that
motion on the scenario's robot (``--reproduce-duration`` s).

``--breakdown`` adds where the full Diagram's time goes per control step (the time inside each
Python callback of a running simulation, where each plant step leaves them with cold caches).
``--riccati`` times the gain re-solve: the Stein equation by Drake, scipy and the compiled
squared Smith iteration, and one Newton step in numpy against the compiled one.

``--rod-model distance`` also measures, interleaved with the rest, the station alone and the ANN
Diagram on a plant whose rods are distance constraints (scenario field ``rod_model``), and prints
both models' per-step times and ``ratio_ann_<model>_over_plant``: that Diagram against the
station with rods as bodies (the default), holding; and ``ratio_ann_<model>_over_sampled_plant``:
against that station with Drake's default ``use_sampled_output_ports: true`` (the plant's setting
before the scenarios turned it off; docs/plant_speed.md).

Like the ``stewart-drake`` command, it first starts itself again with glibc's thread cache sized
for the plant's step (:mod:`stewart_drake.base.allocator`), unless ``GLIBC_TUNABLES`` already sizes
it, and prints the setting it ran with (``glibc_tunables``).

``--clock cpu`` times the runs by the thread's CPU time instead of the wall clock: on a machine
shared with other jobs it leaves out the time the process waited for a core.

Usage: python benchmarks/realtime.py [--scenario paper_hardware] [--duration 5] [--repeats 5]
       [--breakdown] [--riccati] [--profile 25] [--contact] [--rod-model distance]
       [--clock cpu]
"""

import argparse
import collections
import contextlib
import copy
import cProfile
import dataclasses
import io
import os
import pstats
import time

import numpy as np

from stewart_drake.base.allocator import restart_with_tuned_allocator
from stewart_drake.control.features import DensityFeatures
from stewart_drake.control.lqi.controller import LqiController
from stewart_drake.control.lqi.gain import (
    STEIN_TOL,
    error_model,
    input_matrix,
    lqi_gain,
)
from stewart_drake.control.tuner.ann import AnnTuner
from stewart_drake.control.tuning import AnnTunerDriver
from stewart_drake.plant.sdf import ROD_MODELS
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.robot.kinematics import X_HOME
from stewart_drake.run.diagram import held_station
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import NamedReference
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import build_simulator, run_experiment
from stewart_drake.station.guard import DivergenceGuard
from stewart_drake.station.station import PlatformPoseSensor

#: The clock the runs are timed with: wall time (``time.perf_counter``), or with ``--clock
#: cpu`` the thread's CPU time (``time.thread_time``), which leaves out the time the process
#: waited for a core on a shared machine.
CLOCK = time.perf_counter


def plant_alone(scenario, duration_s: float) -> float:
    """Wall seconds to simulate the scenario's station under constant holding torques."""
    _, simulator, _ = held_station(scenario, X_HOME)
    simulator.Initialize()
    t0 = CLOCK()
    simulator.AdvanceTo(duration_s)
    return CLOCK() - t0


def full(scenario, duration_s: float, profiler=None):
    """(wall seconds, StewartDiagram) of the closed-loop run, guarded as `run` is."""
    sd, simulator = build_simulator(scenario)
    if profiler:
        profiler.enable()
    t0 = CLOCK()
    simulator.AdvanceTo(duration_s)
    wall = CLOCK() - t0
    if profiler:
        profiler.disable()
    return wall, sd


@contextlib.contextmanager
def _patched(changes):
    """Temporarily replace class attributes: changes = [(cls, name, value)]."""
    saved = [(cls, name, cls.__dict__[name]) for cls, name, _ in changes]
    try:
        for cls, name, value in changes:
            setattr(cls, name, value)
        yield
    finally:
        for cls, name, value in saved:
            setattr(cls, name, value)


def noop(scenario, duration_s: float) -> float:
    """Wall seconds of the full Diagram holding home with every Python callback a no-op."""

    def nothing(self, context, *output):
        return None

    held = dataclasses.replace(scenario, reference=NamedReference("home"))
    with _patched(
        [
            (LqiController, "_Update", nothing),
            (AnnTuner, "_Update", nothing),
            (DensityFeatures, "_CalcRho", nothing),
            (DivergenceGuard, "_Check", nothing),
        ]
    ):
        return full(held, duration_s)[0]


def moving_station(scenario, duration_s: float = 2.0):
    """A function returning the wall seconds of the station alone replaying, open loop, the
    torques a closed loop of ``scenario`` applied over ``duration_s`` (zero-order hold): the
    plant's own cost on the moving manoeuvre, which the held station does not pay. At most 2 s
    (open loop, the platform drifts off the manoeuvre and falls a few seconds later)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from stewart_drake.run.diagram import make_stewart_station

    fixed = dataclasses.replace(scenario, tuner=None, duration_s=min(duration_s, 2.0))
    result = run_experiment(fixed)
    x0, v0, _ = make_plan(fixed).reference.evaluate(0.0)

    def replay() -> float:
        builder = DiagramBuilder()
        station = builder.AddSystem(make_stewart_station(fixed))
        torques = builder.AddSystem(
            TrajectorySource(PiecewisePolynomial.ZeroOrderHold(result.t, result.T.T))
        )
        builder.Connect(torques.get_output_port(), station.GetInputPort("motor_torque"))
        builder.ExportInput(station.GetInputPort("tool_wrench"))
        diagram = builder.Build()
        simulator = Simulator(diagram)
        context = simulator.get_mutable_context()
        station.assemble(context, x0, v0)
        station.initialize(context, result.T[0])
        diagram.get_input_port(0).FixValue(context, np.zeros(6))
        simulator.Initialize()
        t0 = CLOCK()
        simulator.AdvanceTo(fixed.duration_s)
        return (CLOCK() - t0) / fixed.duration_s

    return replay


#: The Python callbacks of the full Diagram: (label, class, method).
CALLBACKS = (
    ("LQI update (all)", LqiController, "_Update"),
    ("  of which gain re-solves", LqiController, "_reschedule"),
    ("density features (rho)", DensityFeatures, "_CalcRho"),
    ("ANN tuner", AnnTuner, "_Update"),
    ("guard checks", DivergenceGuard, "_Check"),
    ("pose sensor (ideal robot's x)", PlatformPoseSensor, "_Calc"),
)


def reproduce_cpu(scenario, motion: str, duration_s: float) -> float:
    """``CLOCK`` seconds per simulated second of a whole ``reproduce`` of ``motion`` (a library
    motion or a trace file) on ``scenario``'s robot, ``duration_s`` simulated seconds (a motion
    with cycles runs its cycles): the pre-run checks, the run and the fidelity report."""
    from stewart_drake.organ_motion.reproduction import reproduce
    from stewart_drake.references.organ.library import OrganMotionReference
    from stewart_drake.references.traces import TraceReference

    trace = os.path.exists(motion)
    reference = TraceReference(motion) if trace else OrganMotionReference(motion)
    run = dataclasses.replace(scenario, reference=reference)
    t0 = CLOCK()
    result = reproduce(run, duration_s=duration_s if trace else None)
    return (CLOCK() - t0) / result.result.t[-1]


def breakdown(scenario, duration_s: float) -> dict:
    """CPU seconds inside each Python callback during one full run (label -> s, the thread's
    CPU time), and the run's own time ("wall", by ``CLOCK``)."""
    spent = collections.defaultdict(float)

    def timed(label, method):
        def wrapper(*args, **kwargs):
            t0 = time.thread_time()
            try:
                return method(*args, **kwargs)
            finally:
                spent[label] += time.thread_time() - t0

        return wrapper

    with _patched(
        [(cls, name, timed(label, cls.__dict__[name])) for label, cls, name in CALLBACKS]
    ):
        wall, _ = full(scenario, duration_s)
    return {"wall": wall, **spent}


def riccati_costs(controller, n: int = 100) -> dict:
    """Mean times (ms) along the paper manoeuvre (re-scheduled every 10 ms) of: the cold DARE;
    the Stein equation of a Newton step by Drake, scipy and the compiled iteration; one Newton
    step (the 'track' re-solve) in numpy with Drake's Stein solver against the compiled one;
    and the worst relative differences."""
    import scipy.linalg
    from pydrake.math import RealDiscreteLyapunovEquation

    from stewart_drake.control.lqi.gain import balance
    from stewart_drake.control.lqi.reschedule import newton_gain, stein

    g, h, d = controller.geometry, controller.h, controller.delay
    Q, R = controller.scales.Q_unit(d), controller.scales.R_unit()
    poses = paper_manoeuvre().evaluate(np.arange(n) * 0.01)[0]
    models = [error_model(input_matrix(g, x), h, d) for x in poses]
    t0 = time.perf_counter()
    cold = [lqi_gain(A, B, Q, R) for A, B in models]
    out = {"cold_ms": 1e3 * (time.perf_counter() - t0) / n}

    def numpy_newton_step(A, B, K):
        Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, Q, R)
        Kb = K * d_x[None, :] / d_u[:, None]
        W = Qb + Kb.T @ Rb @ Kb
        P = RealDiscreteLyapunovEquation(Ab - Bb @ Kb, 0.5 * (W + W.T))
        return d_u[:, None] * np.linalg.solve(Rb + Bb.T @ P @ Bb, Bb.T @ P @ Ab) / d_x[None, :]

    newton_gain(*models[1], Q, R, cold[0], np.inf, 1, STEIN_TOL)  # loaded before timed
    steins, times = [], collections.defaultdict(float)
    worst = collections.defaultdict(float)
    for (A, B), K_prev in zip(models[1:], cold[:-1]):
        Ab, Bb, Qb, Rb, d_x, d_u = balance(A, B, Q, R)
        Kb = K_prev * d_x[None, :] / d_u[:, None]
        A_c, W = np.ascontiguousarray(Ab - Bb @ Kb), Qb + Kb.T @ Rb @ Kb
        W = 0.5 * (W + W.T)
        stein(A_c, W, STEIN_TOL, 64)  # compiled before it is timed
        # Each solve is called in this iteration; the defaults bind A_c and W all the same.
        for label, solve in (
            ("drake", lambda A_c=A_c, W=W: RealDiscreteLyapunovEquation(A_c, W)),
            ("scipy", lambda A_c=A_c, W=W: scipy.linalg.solve_discrete_lyapunov(A_c.T, W)),
            ("compiled", lambda A_c=A_c, W=W: stein(A_c, W, STEIN_TOL, 64)[0]),
        ):
            t0 = time.perf_counter()
            P = solve()
            times[f"stein_{label}_ms"] += time.perf_counter() - t0
            steins.append((label, P))
        P_ref = steins[-3][1]
        for label, P in steins[-2:]:
            worst[f"stein_{label}_rel"] = max(
                worst[f"stein_{label}_rel"], np.abs(P - P_ref).max() / np.abs(P_ref).max()
            )
        t0 = time.perf_counter()
        K_numpy = numpy_newton_step(A, B, K_prev)
        times["newton_numpy_ms"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        K_compiled, _ = newton_gain(A, B, Q, R, K_prev, np.inf, 1, STEIN_TOL)
        times["newton_compiled_ms"] += time.perf_counter() - t0
        worst["newton_rel"] = max(
            worst["newton_rel"], np.abs(K_compiled - K_numpy).max() / np.abs(K_numpy).max()
        )
    out.update({k: 1e3 * v / (n - 1) for k, v in times.items()})
    out.update(worst)
    return out


def _print_rod_model(w: dict, rod_model: str, steps: float) -> None:
    """Per-step times of both rod models and the ratio of the ANN Diagram on ``rod_model``'s
    plant to the station with rods as bodies (pairs measured back to back)."""
    for key, label in (("plant", "station alone, holding"), ("ann", "full Diagram, ANN tuner")):
        bodies, other = np.median(w[key]), np.median(w[key + "_rod"])
        print(
            f"per_step_us_{key} bodies {bodies / steps * 1e6:.0f}  {rod_model} "
            f"{other / steps * 1e6:.0f}  (bodies / {rod_model} {bodies / other:.2f}; {label})"
        )
    for key, label in (("plant", ""), ("plant_sampled", " and sampled output ports")):
        ratios = w[key] / w["ann_rod"]
        print(
            f"ratio_ann_{rod_model}_over_{'plant' if key == 'plant' else 'sampled_plant'} "
            f"{np.median(ratios):.2f} (full Diagram with the ANN tuner on the {rod_model} plant "
            f"/ station alone with rods as bodies{label}, holding; median of {len(ratios)} "
            f"interleaved pairs; range {ratios.min():.2f} .. {ratios.max():.2f})"
        )


def main():
    # As the command does: what users pay (``GLIBC_TUNABLES=glibc.malloc.tcache_count=7`` to
    # measure glibc's default; benchmarks/allocator.py compares the two).
    restart_with_tuned_allocator()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper_hardware")
    parser.add_argument("--duration", type=float, default=5.0, help="simulated s per run (5)")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved pairs (5)")
    parser.add_argument(
        "--breakdown",
        action="store_true",
        help="also time each Python callback and the moving station",
    )
    parser.add_argument(
        "--riccati",
        action="store_true",
        help="also time the gain re-solve: numpy/scipy/Drake against compiled",
    )
    parser.add_argument("--profile", type=int, default=0, help="print the top N profile entries")
    parser.add_argument(
        "--contact",
        action="store_true",
        help="also measure the station and the ANN Diagram with contact between "
        "the parts simulated (scenario field contact)",
    )
    parser.add_argument(
        "--rod-model",
        choices=ROD_MODELS[1:],
        default=None,
        help="also measure the station and the ANN Diagram with the rods modelled so "
        "(scenario field rod_model), and the station with sampled output ports",
    )
    parser.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="cpu",
        help="time the runs by the thread's CPU time (default) or the wall clock",
    )
    parser.add_argument(
        "--reproduce",
        default=None,
        metavar="MOTION",
        help="also time a whole reproduce of MOTION (a library motion or a trace file)",
    )
    parser.add_argument(
        "--reproduce-duration", type=float, default=30.0, help="simulated s of a trace (30)"
    )
    args = parser.parse_args()
    global CLOCK
    CLOCK = time.thread_time if args.clock == "cpu" else time.perf_counter
    fixed = load_scenario(args.scenario, [f"duration_s={args.duration}"])
    ann = dataclasses.replace(fixed, tuner=AnnTunerDriver())
    D = args.duration
    full(ann, 0.01)  # compile (or load) the kernels first
    replay = moving_station(fixed)
    load = os.getloadavg()[0]
    walls = collections.defaultdict(list)
    contact = dataclasses.replace(fixed, contact=True)
    rods = dataclasses.replace(fixed, rod_model=args.rod_model or "bodies")
    sampled = dataclasses.replace(fixed, plant=copy.deepcopy(fixed.plant))
    sampled.plant.use_sampled_output_ports = True
    if args.rod_model:
        full(dataclasses.replace(ann, rod_model=args.rod_model), 0.01)
    for _ in range(max(1, args.repeats)):
        walls["plant"].append(plant_alone(fixed, D))
        walls["ann"].append(full(ann, D)[0])
        walls["fixed"].append(full(fixed, D)[0])
        walls["noop"].append(noop(ann, D))
        walls["moving"].append(replay() * D)
        if args.contact:
            walls["plant_contact"].append(plant_alone(contact, D))
            walls["ann_contact"].append(full(dataclasses.replace(ann, contact=True), D)[0])
        if args.rod_model:
            walls["plant_rod"].append(plant_alone(rods, D))
            walls["plant_sampled"].append(plant_alone(sampled, D))
            walls["ann_rod"].append(full(dataclasses.replace(ann, rod_model=args.rod_model), D)[0])
        if args.reproduce:
            walls["reproduce"].append(
                reproduce_cpu(fixed, args.reproduce, args.reproduce_duration) * D
            )
    w = {k: np.array(v) for k, v in walls.items()}
    rtf = {k: D / v for k, v in w.items()}
    clock = "the thread's CPU" if CLOCK is time.thread_time else "wall"
    for key, label in (
        ("fixed", f"closed loop, {args.scenario} as the scenario is"),
        ("ann", "closed loop with the ANN tuner"),
        ("plant", "station alone, held at home"),
        ("moving", "station alone replaying a run's torques"),
        ("reproduce", f"reproduce {args.reproduce}: checks, run, report"),
    ):
        if key in w:
            per = w[key] / D
            print(
                f"cpu_per_sim_s_{key} {np.median(per):.3f} ({label}; {clock} seconds per "
                f"simulated second, median of {per.size}; range {per.min():.3f} .. {per.max():.3f})"
            )
    print(
        f"realtime_factor_plant_alone {np.median(rtf['plant']):.2f} median ({D:g} s sim, "
        f"{args.scenario} station under constant holding torques; load {load:.1f} at start)"
    )
    labels = {
        "ann": "full Diagram, ANN tuner",
        "fixed": "full Diagram, fixed weights",
        "noop": "ANN Diagram holding home, every Python callback a no-op",
    }
    for key, label in labels.items():
        ratios = w["plant"] / w[key]
        name = {
            "ann": "ratio_ann_over_plant",
            "fixed": "ratio_fixed_over_plant",
            "noop": "ceiling_ratio_noop_over_plant",
        }[key]
        print(f"realtime_factor_{key} {np.median(rtf[key]):.2f} median ({label})")
        print(
            f"{name} {np.median(ratios):.2f} (median of {len(ratios)} interleaved pairs; range "
            f"{ratios.min():.2f} .. {ratios.max():.2f})"
        )
    moving = w["plant"] / w["moving"]
    print(
        f"station_moving_over_held {np.median(w['moving'] / w['plant']):.2f} (the station "
        f"replaying a run's torques costs this many times the held station: the plant works "
        f"harder on the manoeuvre)"
    )
    for key in ("ann", "fixed"):
        print(
            f"ratio_{key}_over_moving_station {np.median(w['moving'] / w[key]):.2f} (the "
            f"same plant work: the cost of everything but the plant; held ratio "
            f"{np.median(w['plant'] / w[key]):.2f} x {np.median(1 / moving):.2f})"
        )
    if args.contact:
        for key, label in (("plant", "station"), ("ann", "full Diagram, ANN tuner")):
            print(
                f"realtime_factor_{key}_contact {np.median(rtf[key + '_contact']):.2f} median "
                f"({label}, contact on; on / off "
                f"{np.median(w[key] / w[key + '_contact']):.2f})"
            )
        print(
            f"ratio_ann_over_plant_contact "
            f"{np.median(w['plant_contact'] / w['ann_contact']):.2f} (contact on, both)"
        )
    if args.rod_model:
        _print_rod_model(w, args.rod_model, D / fixed.control_period_s)
    print(f"load_average_1min {os.getloadavg()[0]:.1f} at the end")
    print(f"glibc_tunables {os.environ.get('GLIBC_TUNABLES', '(none)')}")
    if args.breakdown:
        steps = D / fixed.control_period_s
        plant = np.median(w["plant"])
        print(
            f"per control step: station alone {plant / steps * 1e6:.0f} us holding, "
            f"{np.median(w['moving']) / steps * 1e6:.0f} us on the manoeuvre (replaying 2 s of "
            f"a run's torques); no-op Diagram {np.median(w['noop']) / steps * 1e6:.0f} us"
        )
        for key, scenario in (("ann", ann), ("fixed", fixed)):
            spent = breakdown(scenario, D)
            print(f"  {labels[key]}: {spent['wall'] / steps * 1e6:.0f} us of wall per step")
            for label, _, _ in CALLBACKS:
                if label in spent:
                    print(f"    {label:28s} {spent[label] / steps * 1e6:7.1f} us")
    if args.riccati:
        _, sd = full(fixed, 0.01)
        c = riccati_costs(sd.controller.lqi)
        print(f"riccati_cold_ms {c['cold_ms']:.3f} (Drake's DARE, {sd.controller.n} states)")
        print(
            f"stein_ms drake {c['stein_drake_ms']:.3f}  scipy {c['stein_scipy_ms']:.3f}  "
            f"compiled {c['stein_compiled_ms']:.3f}  (max relative difference to Drake's: "
            f"scipy {c['stein_scipy_rel']:.1e}, compiled {c['stein_compiled_rel']:.1e})"
        )
        print(
            f"newton_step_ms numpy+drake {c['newton_numpy_ms']:.3f}  compiled "
            f"{c['newton_compiled_ms']:.3f}  compiled/numpy "
            f"{c['newton_compiled_ms'] / c['newton_numpy_ms']:.2f}  (max |K_c - K_n| / |K_n| "
            f"{c['newton_rel']:.1e})"
        )
    if args.profile:
        profiler = cProfile.Profile()
        full(ann, D, profiler)
        s = io.StringIO()
        pstats.Stats(profiler, stream=s).sort_stats("tottime").print_stats(args.profile)
        print(s.getvalue())


if __name__ == "__main__":
    main()
