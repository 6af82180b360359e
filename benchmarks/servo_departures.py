"""The robot on servos as they are: each shipped bus robot's breathing against the bus emulator
with the controller's own servos (ideal), with the realistic default (``emulator.servos:
realistic``: every departure drawn from the seed), and with each departure alone at the edge of
its range, the rest ideal: one table (docs/robot.md, "Servos as they are").

Each row is ``stewart-drake robot breathing --emulate``'s own session (as
:mod:`bus_accuracy`): the true pose (the emulator's plant) and the encoders' pose against the
reference, RMS / peak per axis over the motion after its first ``--skip`` s, whether the true
pose's peak X stayed within 1 mm (a loop that broke into oscillation does not), the loop's
CPU time a period (median), its deadline misses, and the model time the emulator's plant
slipped behind the wall clock (on the wall clock: a row whose plant slipped is the emulator's
figure, not a robot's).

``--loop host`` runs the host's current loop (the crank servo as the bus robots shipped it
before the servos' own loop: 2.5 Hz, its estimator 15 Hz, integral ratio 4, friction direction
12 Hz at share 0.5), ``--loop servo`` the servos' own position loop
(``controller: !ServoPositionDriver`` with ``bus.position_loop``: 30 Hz, damping 1.4 on
DYNAMIXEL-P servos; 8 Hz, damping 1.0 on the X series, whose 4096 counts a turn leave no
table room for more: 12 Hz needs an I Gain of 35998 of its 16383), ``--loop scenario`` the
scenario's own. ``--clock loop`` puts the emulator's plant on the loop's clock
(``emulator.clock``), ``wall`` on the wall clock.

Usage: python benchmarks/servo_departures.py [--scenario paper_bus phantom_bus] [--duration 20]
    [--skip 8] [--rows NAME ...] [--loop host|servo|scenario] [--clock wall|loop]
    [--period S] [--set NAME=VALUE ...] [--commissioned [ERROR]] [--markdown FILE]

``--set`` applies to every row after the row's own settings: a controller's variant measured
over the same draws (``--set controller.friction_scale=0.5``). ``--commissioned [ERROR]`` gives
the crank servo what each servo's commissioning would identify (docs/servo_bench.md): the
emulator's own draw of each servo's motor constant, Coulomb friction and the gears' load share,
each off by ERROR (a share, default 0) as a bench that found them to that accuracy.
"""

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bus_accuracy import AXES, emulated, scenario_of  # noqa: E402

from stewart_drake.run.scenario_io import load_scenario  # noqa: E402

#: (name, the emulator's settings): ideal, the realistic default, each departure alone at the
#: edge of its range (emulator_config.py's ranges; the acceptance's kt 0.7 / 1.3).
ROWS = (
    ("ideal", ["emulator.servos=ideal"]),
    ("realistic (seed 0)", []),
    ("realistic (seed 1)", ["emulator.seed=1"]),
    ("realistic (seed 2)", ["emulator.seed=2"]),
    ("realistic, kt x0.7", ["emulator.kt_scale=0.7"]),
    ("realistic, kt x1.3", ["emulator.kt_scale=1.3"]),
    ("realistic, rotor x0.5", ["emulator.rotor_inertia_scale=0.5"]),
    ("realistic, rotor x2", ["emulator.rotor_inertia_scale=2"]),
    ("kt x0.7 alone", ["emulator.servos=ideal", "emulator.kt_scale=0.7"]),
    ("kt x1.3 alone", ["emulator.servos=ideal", "emulator.kt_scale=1.3"]),
    ("rotor x0.5 alone", ["emulator.servos=ideal", "emulator.rotor_inertia_scale=0.5"]),
    ("rotor x2 alone", ["emulator.servos=ideal", "emulator.rotor_inertia_scale=2"]),
    ("friction x0.5 alone", ["emulator.servos=ideal", "emulator.friction_scale=0.5"]),
    ("friction x2 alone", ["emulator.servos=ideal", "emulator.friction_scale=2"]),
    ("current lag x2 alone", ["emulator.servos=ideal", "emulator.current_lag_scale=2"]),
    ("play at the e-Manual's most", ["emulator.servos=ideal", "emulator.backlash_rad=BACKLASH"]),
    ("encoder noise 1 count", ["emulator.servos=ideal", "emulator.encoder_noise_counts=1"]),
    ("non-linearity 5.7 counts", [
        "emulator.servos=ideal", "emulator.encoder_nonlinearity_counts=5.7",
    ]),
    ("+5 K", ["emulator.servos=ideal", "emulator.temperature_rise_K=5"]),
    ("mass +3 %", ["emulator.servos=ideal", "emulator.mass_scale=1.03"]),
    # On the loop's clock the plant moves a period at each command whenever it comes: the bus's
    # timing cannot show there, so this row is always the wall clock's.
    ("factory bus: 500 us, 16 ms timer", [
        "emulator.servos=ideal", "emulator.return_delay_us=500", "emulator.latency_timer_ms=16",
        "emulator.reply_jitter_us=100", "emulator.clock=wall",
    ]),
)  # fmt: skip


def row(scenario_name: str, settings: list[str], args) -> dict:
    """One session: {true, encoders: (rms (6,), peak (6,)), cpu_ms, misses, periods}."""
    from stewart_drake.station.bus.emulator_config import BACKLASH_MAX_RAD
    from stewart_drake.station.bus.servos import servo_spec

    args.set = []
    family = servo_spec(scenario_of(args, 0.01).bus.model, torque_control=False).table.family
    args.set = [] if args.clock is None else [f"emulator.clock={args.clock}"]  # a row's own wins
    args.set += [s.replace("BACKLASH", repr(BACKLASH_MAX_RAD[family])) for s in settings]
    args.set += args.extra  # --set: every row's, after its own
    # every row to its end: the misses are counted, not fatal (the emulator on the loop's clock
    # holds a read for its step: a loaded machine's late periods are the emulator's)
    args.set.append("bus.max_deadline_misses=1000000")
    own = load_scenario(scenario_name).control_period_s
    period = own if args.period is None else args.period
    scenario = with_loop(scenario_of(args, period), args.loop, family)
    if args.commissioned is not None:
        scenario = commissioned(scenario, args.commissioned)
    with tempfile.TemporaryDirectory() as out:
        scenario.guard.divergence_dir = f"{out}/diverged"
        e_true, e_enc, cpu, misses, n, _ = emulated(scenario, args, period, 0, out)
    return {
        "true": (np.sqrt(np.mean(e_true**2, axis=0)), np.max(np.abs(e_true), axis=0)),
        "encoders": (np.sqrt(np.mean(e_enc**2, axis=0)), np.max(np.abs(e_enc), axis=0)),
        "cpu_ms": float(np.median(cpu)),
        "slipped_s": float(args.slipped_s),
        "end": args.end_reason,
        "misses": int(misses),
        "periods": int(n),
    }


def commissioned(scenario, error: float):
    """``scenario`` with the crank servo given what each servo's commissioning identifies
    (docs/servo_bench.md): the emulator's own draw of its motor constant over the catalogue's,
    its static friction budget (sliding and the Stribeck excess), the gears' load share; each
    off by ``error`` (a share: the torque constants up and down crank to crank, the friction
    the other way, the load share up), as a bench that found them to that accuracy."""
    import dataclasses

    from stewart_drake.control.servo.driver import CrankServoDriver
    from stewart_drake.station.bus.servo_physics import FRICTION
    from stewart_drake.station.bus.servos import servo_spec

    if not isinstance(scenario.controller, CrankServoDriver):
        raise SystemExit("--commissioned needs the crank servo (--loop scenario or host)")
    bus = scenario.bus
    drawn = scenario.emulator.draw(servo_spec(bus.model, torque_control=False), len(bus.ids))
    f = drawn.friction
    sign = np.array([1.0, -1.0] * 3)
    coulomb = f[:, FRICTION["coulomb_Nm"]] + f[:, FRICTION["stribeck_Nm"]]
    scenario.controller = dataclasses.replace(
        scenario.controller,
        torque_constant_scale=[float(v) for v in drawn.kt_scale * (1 + error * sign)],
        friction_Nm=[float(v) for v in coulomb * (1 - error * sign)],
        friction_load_share=float(np.mean(f[:, FRICTION["load_motor"]]) * (1 + error)),
    )
    return scenario.validate()


def with_loop(scenario, loop: str, family: str):
    """``scenario`` with the host's current loop or the servos' own (module docstring)."""
    from stewart_drake.control.servo.driver import CrankServoDriver
    from stewart_drake.control.servo.goal_stream import ServoPositionDriver
    from stewart_drake.station.bus.position_mode import ServoPositionLoop

    if loop == "host":
        scenario.bus.position_loop = None
        scenario.controller = CrankServoDriver(
            bandwidth_hz=2.5,
            integral_ratio=4.0,
            friction_direction_hz=12.0,
            friction_direction_share=0.5,
        )
    elif loop == "servo":
        scenario.controller = ServoPositionDriver()
        scenario.bus.position_loop = (
            ServoPositionLoop(30.0, 1.4) if family == "P" else ServoPositionLoop(8.0, 1.0)
        )
    return scenario.validate()


def markdown(scenario_name: str, rows: list[tuple[str, dict]], loop_name: str) -> list[str]:
    """The rows as a Markdown table: RMS / peak, urad and um, true pose then encoders' X."""
    from stewart_drake.base.tables import markdown_lines

    header = [f"`{scenario_name}`, {loop_name}", *(f"{a} (true)" for a in AXES)]
    header += ["encoders X", "peak X < 1 mm", "CPU ms", "misses", "plant slipped s"]
    body = []
    for name, r in rows:
        rms, peak = r["true"]
        cells = [f"{1e6 * a:.0f} / {1e6 * b:.0f}" for a, b in zip(rms, peak)]
        stable = "yes" if peak[3] < 1e-3 else "no"
        body.append(
            [name, *cells, f"{1e6 * r['encoders'][0][3]:.0f}", stable, f"{r['cpu_ms']:.2f}",
             f"{r['misses']} of {r['periods']}",
             "loop's clock" if np.isnan(r["slipped_s"]) else f"{r['slipped_s']:.3f}"]
        )  # fmt: skip
    return markdown_lines(header, body)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", nargs="+", default=["paper_bus", "phantom_bus"])
    parser.add_argument("--duration", type=float, default=20.0, help="s of the motion")
    parser.add_argument("--skip", type=float, default=8.0, help="s of the motion not measured")
    parser.add_argument("--rows", nargs="+", default=None, help="only these rows (their names)")
    parser.add_argument("--markdown", default=None, help="also write the tables to this file")
    parser.add_argument("--loop", choices=("host", "servo", "scenario"), default="scenario")
    parser.add_argument(
        "--clock", choices=("wall", "loop"), default=None, help="default: the scenario's"
    )
    parser.add_argument(
        "--period", type=float, default=None, help="the control period, s (default: the scenario's)"
    )
    parser.add_argument(
        "--set",
        dest="extra",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a scenario setting for every row, after the row's own (repeatable): a controller "
        "variant, e.g. controller.friction_scale=0.5",
    )
    parser.add_argument(
        "--commissioned",
        type=float,
        nargs="?",
        const=0.0,
        default=None,
        metavar="ERROR",
        help="give the crank servo each servo's commissioning (the emulator's draw of its motor "
        "constant, friction and load share), off by ERROR (a share, default 0)",
    )
    args = parser.parse_args()
    args.motion, args.param, args.breakdown = "breathing", [], False
    tables = []
    for name in args.scenario:
        args.scenario_name = name
        rows = []
        for label, settings in ROWS:
            if args.rows and label not in args.rows:
                continue
            args.scenario = name
            r = row(name, settings, args)
            rows.append((label, r))
            print(markdown(name, [(label, r)], args.loop)[-1], flush=True)  # as it comes
            if r["end"] is not None:
                print(f"  ended before its end: {r['end']}", flush=True)
        tables += markdown(name, rows, args.loop) + [""]
    print("\n".join(tables))
    if args.markdown:
        Path(args.markdown).write_text("\n".join(tables) + "\n")


if __name__ == "__main__":
    main()
