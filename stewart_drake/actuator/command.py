"""``stewart-drake servo``: a servo identified from its bench logs (``servo identify``) and a model
replayed against what a real servo did (``servo replay``), docs/servo_bench.md."""

from __future__ import annotations

import sys

from ..execution.options import add_scenario_arguments, int_at_least, positive_float


def register(sub) -> None:
    """Add the ``servo`` command, with ``identify`` and ``replay``, to ``sub``, the
    ``stewart-drake`` subparsers."""
    servo = sub.add_parser(
        "servo",
        help="identify a servo's drive and friction from its bench logs, or replay a model "
        "against them (docs/servo_bench.md)",
    )
    verbs = servo.add_subparsers(
        dest="servo_verb", metavar="{identify,replay,excite}", required=True
    )
    ident = verbs.add_parser(
        "identify",
        help="fit a servo's drive and friction to bench logs and write the model",
    )
    ident.add_argument("bench_logs", nargs="+", metavar="LOG", help="bench logs (JSON)")
    ident.add_argument("--servo", required=True, help="the servo (e.g. XL330-M288-T)")
    ident.add_argument(
        "--model-class",
        default="m6",
        choices=("m1", "m2", "m3", "m4", "m5", "m6"),
        help="the friction model (Duclusaud et al., ICRA 2025): m1 Coulomb and viscous, m2 "
        "with Stribeck, m3 load-dependent, m4 both, m5 directional, m6 quadratic",
    )
    ident.add_argument("--seed", type=int_at_least(0), default=0, help="the search's seed")
    ident.add_argument(
        "--generations",
        type=int_at_least(1),
        default=150,
        help="generations of the search at most (each replays every log 15 times per term)",
    )
    ident.add_argument("--no-progress", action="store_true", help="no progress bar")
    ident.add_argument("--out", required=True, help="the model file to write (JSON)")
    ident.set_defaults(func=_cmd_identify, out_is_file=True)
    rep = verbs.add_parser(
        "replay",
        help="run a servo model on bench logs' goals and print its error against the real servo",
    )
    rep.add_argument("bench_logs", nargs="+", metavar="LOG", help="bench logs (JSON)")
    rep.add_argument(
        "--model",
        dest="servo_model",
        required=True,
        help="a model file (servo identify), or a servo whose model is shipped (XL330-M288-T)",
    )
    rep.add_argument(
        "--plot",
        default=None,
        metavar="FILE.png",
        help="also draw each log's measured and replayed angle (default: no figure)",
    )
    rep.set_defaults(func=_cmd_replay, derived_inputs=_model_input)
    _add_excite(verbs)


def _add_excite(verbs) -> None:
    """``servo excite``'s options."""
    ex = verbs.add_parser(
        "excite",
        help="commission a servo on its bench over the bus: drive its current, log its angle",
    )
    ex.add_argument("--port", default=None, help="the servo's serial port (or --emulate)")
    ex.add_argument("--id", type=int_at_least(0), default=1, help="the servo's id")
    ex.add_argument("--baud-rate", type=int_at_least(9600), default=1_000_000, help="bps")
    ex.add_argument(
        "--servo",
        default="XM430-W350-T",
        help="its model, one of the bus's with Current Control Mode",
    )
    ex.add_argument("--mass", type=positive_float, required=True, help="kg at the arm's end")
    ex.add_argument("--length", type=positive_float, required=True, help="the arm, m")
    ex.add_argument("--supply", type=positive_float, default=12.0, help="the servo's supply, V")
    ex.add_argument("--seconds", type=positive_float, default=8.0, help="of the excitation")
    ex.add_argument(
        "--amplitude",
        type=positive_float,
        default=1.0,
        help="the current's amplitude as a share of the safe one (at most 1)",
    )
    ex.add_argument(
        "--emulate",
        type=int_at_least(0),
        nargs="?",
        const=0,
        default=None,
        metavar="SEED",
        help="on the bus emulator: a servo as it is, drawn from SEED (default 0; its hidden "
        "figures printed at the end, for identify to find), on the emulator's own clock",
    )
    ex.add_argument(
        "--crank",
        type=int,
        choices=range(1, 7),
        metavar="I",
        help="with --emulate: the servo of crank I (1-6) of the robot emulator's draw of SEED "
        "(robot --emulate --scenario's, emulator.seed=SEED), to commission the robot's own "
        "servos (default: a servo drawn alone)",
    )
    from ..run.scenario_io import ROBOT_SCENARIO

    add_scenario_arguments(
        ex,
        "with --crank: the robot whose emulator draws the servos (its 'emulator:' section, "
        "--emulate's SEED for its seed; --set emulator.kt_scale=1.3 as robot takes it)",
        ROBOT_SCENARIO,
    )
    ex.add_argument("--out", required=True, help="the bench log to write (JSON)")
    ex.set_defaults(func=_cmd_excite, out_is_file=True)


def _model_input(args) -> list:
    """The model file ``--model`` reads (a shipped one where it names a servo): an input no
    output may replace."""
    from .model_file import model_path

    return [(f"--model {args.servo_model}", model_path(args.servo_model))]


def _read_logs(paths) -> list:
    from .bench_log import read_bench_log

    return [read_bench_log(path) for path in paths]


def _table(model, logs, identified_on=()) -> tuple[list[str], list[dict]]:
    """Lines of each log's error (mean absolute, RMS, peak, mrad), which logs the model was
    identified on apart from the others, and the mean of each group; the rows."""
    from .bench import errors, replay

    rows = []
    for log in logs:
        row = errors(replay(model, log), log)
        mode = f"kp {log.kp:g}" if log.mode == "position" else "current"
        row.update(log=log.name, mode=mode, seen=log.name in identified_on)
        rows.append(row)
    width = max(len(r["log"]) for r in rows)
    lines = [f"  {'log':<{width}}  {'goal':>8}  {'MAE':>7}  {'RMS':>7}  {'peak':>7} mrad"]
    for r in rows:
        lines.append(
            f"  {r['log']:<{width}}  {r['mode']:>8}  {1e3 * r['mae_rad']:>7.2f}  "
            f"{1e3 * r['rms_rad']:>7.2f}  {1e3 * r['peak_rad']:>7.1f}"
            + ("   (identified on it)" if r["seen"] else "")
        )
    for label, group in (
        ("logs it was identified on", [r for r in rows if r["seen"]]),
        ("logs held out of its identification", [r for r in rows if not r["seen"]]),
    ):
        if group:
            mae = sum(r["mae_rad"] for r in group) / len(group)
            rms = (sum(r["rms_rad"] ** 2 for r in group) / len(group)) ** 0.5
            logs_word = f"{len(group)} {label}" if len(group) > 1 else label.replace("logs", "log")
            lines.append(
                f"  mean over the {logs_word}: MAE {1e3 * mae:.2f} mrad, RMS {1e3 * rms:.2f} mrad"
            )
    return lines, rows


def check_same_servo(log, servo: str) -> None:
    """Refuse a log of another servo than ``servo`` (its ``motor``, as a bench names it:
    "xl330" or the model's full name, compared without case and punctuation; a log naming no
    motor is taken).

    Raises:
        InvalidConfigError: names the log, its motor and the servo.
    """
    from ..base.errors import InvalidConfigError

    def plain(name: str) -> str:
        return "".join(c for c in name.lower() if c.isalnum())

    if log.motor and not plain(servo).startswith(plain(log.motor)):
        raise InvalidConfigError(
            f"{log.name} logs a {log.motor}, not a {servo}: give the logs of that servo"
        )


def _cmd_identify(args) -> int:
    """``servo identify``: the logs read and checked, the search, the table, the file."""
    from .bench import bench_servo, crank_servo_settings
    from .identify import identify
    from .model_file import write_model

    bench_servo(args.servo)  # an unknown servo refused before the logs are read
    logs = _read_logs(args.bench_logs)
    for log in logs:
        check_same_servo(log, args.servo)
    print(
        f"stewart-drake servo: identifying {args.servo} ({args.model_class}) on {len(logs)} "
        f"logs, {args.generations} generations at most (a minute or more)",
        file=sys.stderr,
        flush=True,
    )
    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=args.generations, unit="gen", file=sys.stderr, leave=False)

    def progress(generation: int, mae: float) -> None:
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"MAE {1e3 * mae:.2f} mrad")

    try:
        found = identify(logs, args.servo, args.model_class, args.seed, args.generations, progress)
    finally:
        if bar is not None:
            bar.close()
    m = found.model
    print(
        f"{m.servo} ({m.model_class}): k {m.k_Nm_per_A:.4g} N m/A, R {m.resistance_ohm:.4g} "
        f"ohm, armature {m.armature_kg_m2:.4g} kg m^2, zero {1e3 * m.q_offset_rad:.3g} mrad; "
        "friction " + ", ".join(f"{name} {value:.4g}" for name, value in m.friction.items())
    )
    crank = crank_servo_settings(m)
    if crank is not None:
        print(
            "  for its crank in the crank servo (controller: !CrankServoDriver, one entry a "
            "servo): " + ", ".join(f"{name} {value:.4g}" for name, value in crank.items())
        )
    lines, _ = _table(m, logs, found.logs)
    if m.current_time_constant_s:
        print(f"  its current loop's lag {1e3 * m.current_time_constant_s:.3g} ms")
    print("replayed on the logs it was identified on (the servo's firmware, its position loop "
          "or its current loop, run on the simulated shaft over the whole log):")  # fmt: skip
    print("\n".join(lines))
    print(_search_line(found))
    path = write_model(args.out, found, args.seed)
    print(f"wrote {path}")
    return 0


def _search_line(found) -> str:
    """Whether the search had settled, and what to do when it had not."""
    from .identify import SETTLED_COUNTS, SETTLED_SHARE, settling_window

    n = found.generations
    window = settling_window(n)
    share, count = f"{SETTLED_SHARE:.0%} of itself", f"{SETTLED_COUNTS:g} of an encoder count"
    if found.settled:
        return (
            f"the search had settled: over its last {window} of {n} generations its best "
            f"error fell by under {share} or under {count}"
        )
    why = (
        f"its {n} generations are too few to tell (it takes over {window})"
        if n <= window
        else f"over its last {window} of {n} generations its best error still fell by over "
        f"{share} and over {count}"
    )
    return (
        f"the search had not settled: {why}, and the figures above can be far from the servo's "
        "(an emulated XM430 came out 20 % off in its load share at 150 generations, within 3 % "
        "at 400): run it again with more --generations"
    )


def _cmd_replay(args) -> int:
    """``servo replay``: the model and logs read and checked, each log replayed, the table."""
    from .model_file import model_path, read_model

    model, identified_on = read_model(args.servo_model)
    logs = _read_logs(args.bench_logs)
    for log in logs:
        check_same_servo(log, model.servo)
    lines, rows = _table(model, logs, identified_on)
    print(
        f"{model.servo} ({model.model_class}) from {model_path(args.servo_model)}, driven by "
        "each log's goals (positions in the servo's position mode, currents in Current Control "
        "Mode), against the angles the log's encoder recorded:"
    )
    print("\n".join(lines))
    if args.plot:
        from .figures import plot_replays

        path = plot_replays(model, logs, rows, args.plot)
        print(f"wrote {path}")
    return 0


def _cmd_excite(args) -> int:
    """``servo excite``: the bench checked, the bus opened (or emulated), the excitation run
    with the torque off at every end, the log written."""
    import numpy as np

    from ..base.errors import InvalidConfigError
    from ..station.bus.servos import servo_spec
    from .bench_log import write_bench_log
    from .commissioning import Pendulum, excitation_current, excite, safe_amplitude_A

    spec = servo_spec(args.servo)
    if args.amplitude > 1.0:
        raise InvalidConfigError(f"--amplitude {args.amplitude:g}: at most 1 (the safe one)")
    if (args.port is None) == (args.emulate is None):
        raise InvalidConfigError("give the servo's --port, or --emulate [SEED], one of them")
    if args.crank is not None and args.emulate is None:
        raise InvalidConfigError(
            f"--crank {args.crank}: only with --emulate (a real servo is the one on --port)"
        )
    if args.set and args.crank is None:
        raise InvalidConfigError(
            f"--set {args.set[0]}: only with --crank (it sets the robot whose servo is excited)"
        )
    pendulum = Pendulum(args.mass, args.length, supply_V=args.supply)
    period = 0.01
    t = np.arange(0.0, args.seconds, period)
    amplitude = args.amplitude * safe_amplitude_A(pendulum, spec.torque_constant_Nm_per_A)
    currents = excitation_current(t, amplitude, args.seconds)
    print(
        f"stewart-drake servo: exciting {args.servo} id {args.id} for {args.seconds:g} s, "
        f"currents within {amplitude:.3g} A, the arm {args.mass:g} kg at {args.length:g} m",
        file=sys.stderr,
        flush=True,
    )
    emulated = None
    if args.emulate is not None:
        from ..station.bus.emulator import BusEmulator
        from ..station.bus.emulator_config import EmulatorConfig
        from ..station.bus.servo_models import BenchServos

        if args.crank is None:
            hidden = EmulatorConfig(seed=args.emulate).draw(spec, 1)
        else:
            hidden = _robot_servo(args, spec)
        backend = BenchServos(hidden, args.mass, args.length)
        emulated = BusEmulator([args.id], args.servo, backend=backend, command_step_s=period)
        emulated.start()
        port = emulated.port
    else:
        port = args.port
    from ..station.bus.driver import DynamixelBus

    try:
        # On the emulator's own clock a pause of this machine is not the servo's: its bus
        # watchdog at its longest; on a real servo the driver's 0.1 s.
        watchdog_s = 2.54 if emulated is not None else 0.1
        bus = DynamixelBus(
            port, args.baud_rate, [args.id], args.servo, reply_timeout_s=2.0, watchdog_s=watchdog_s
        )
        log = excite(bus, pendulum, currents, period, commanded=emulated is not None)
    finally:
        if emulated is not None:
            emulated.close()
    path = write_bench_log(args.out, log)
    print(f"logged {log.t[-1]:.2f} s, the arm within {np.abs(log.q).max():.3g} rad; wrote {path}")
    if emulated is not None:
        print(_hidden_line(hidden, backend, args.crank))
    return 0


def _robot_servo(args, spec):
    """The servo ``robot --emulate`` puts at crank ``args.crank`` of ``args.scenario`` (with
    ``args.set``, its seed ``args.emulate``): the emulator's draw of the robot's six.

    Raises:
        InvalidConfigError: a scenario without a bus, or whose servos are not ``args.servo``.
    """
    from ..base.errors import InvalidConfigError
    from ..run.scenario_io import load_scenario
    from ..station.bus.servos import servo_spec

    scenario = load_scenario(args.scenario, [*(args.set or ()), f"emulator.seed={args.emulate}"])
    bus = scenario.bus
    if bus is None or bus.model != args.servo:
        on = "no bus" if bus is None else f"{bus.model} servos"
        raise InvalidConfigError(
            f"--crank {args.crank}: {args.scenario} has {on}, not {args.servo}: give the robot's "
            "own --servo, or the --scenario of a robot on them"
        )
    draw = scenario.emulator.draw(servo_spec(bus.model, torque_control=False), len(bus.ids))
    return draw.one(args.crank - 1)


def _hidden_line(hidden, backend, crank: int | None = None) -> str:
    """What the emulated servo (the robot's crank ``crank``'s, or one drawn alone) hid, as
    ``identify`` would name it."""
    from ..station.bus.servo_physics import FRICTION

    f = hidden.friction[0]
    terms = ("coulomb_Nm", "stribeck_Nm", "stribeck_rad_s", "load_motor", "load_motor_stribeck")
    return (
        f"the emulated servo (seed {hidden.seed}"
        + ("" if crank is None else f", the robot's crank {crank}")
        + f") hid: k {hidden.k_Nm_per_A[0]:.4g} N m/A, R "
        f"{hidden.resistance_ohm[0]:.4g} ohm, armature "
        f"{backend.armature:.4g} kg m^2, current lag "
        f"{1e3 * hidden.current_time_constant_s:.3g} ms; friction "
        + ", ".join(f"{name} {f[FRICTION[name]]:.4g}" for name in terms)
    )
