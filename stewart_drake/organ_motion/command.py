"""``stewart-drake reproduce``: a motion of the organ-motion library or a recorded trace on the
robot, checked, run (learning on request) and measured, with a report and a verdict; and
``stewart-drake examples``, the example inputs to try it and ``verify`` on (:mod:`.examples`)."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from ..base.verdicts import within
from ..execution.options import (
    add_motion_arguments,
    add_scenario_arguments,
    check_output,
    int_at_least,
    is_trace_file,
    positive_float,
    say_if_compiling,
)
from ..execution.trace_options import (
    TRACE_ONLY,
    add_trace_arguments,
    key_values,
    trace_options_given,
    trace_reference,
)
from . import SCENARIO


def register(sub) -> None:
    """Add the ``reproduce`` and ``examples`` (:mod:`.examples`) commands to ``sub``, the
    ``stewart-drake`` subparsers."""
    _add_reproduce_command(sub)
    _add_examples_command(sub)


def _add_reproduce_command(sub) -> None:
    """The ``reproduce`` command's options."""
    rp = sub.add_parser(
        "reproduce",
        help="reproduce organ motion (a library motion or a "
        "recorded trace) on the robot and report its fidelity "
        "(exit 2 if beyond --tolerance)",
    )
    add_motion_arguments(rp)
    add_trace_arguments(rp)
    add_scenario_arguments(
        rp,
        "the robot and its controller; e.g. --set learning.gain=0.5 with --learn-cycles",
        default=SCENARIO,
    )
    _add_learning_arguments(rp)
    _add_measurement_arguments(rp)
    _add_stream_arguments(rp)
    _add_surrogate_arguments(rp)
    rp.add_argument("--out", default="results/reproduce", help="report folder")
    rp.add_argument(
        "--html",
        default=None,
        metavar="FILE.html",
        help="also write a standalone Meshcat replay of the run to this file: the reference "
        "as a ghost, a marker coloured by the tracking error (default: none)",
    )
    rp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    rp.set_defaults(func=_cmd_reproduce, out_sub=("diverged",))


def _add_learning_arguments(rp) -> None:
    """``reproduce``'s learning: per cycle (``--learn-cycles``) or as a function of the
    reference (``--feedforward``, a model saved and read back)."""
    rp.add_argument(
        "--learn-cycles",
        type=int_at_least(0),
        default=0,
        metavar="N",
        help="learn a correction from the first N cycles, then hold it (0: no learning)",
    )
    rp.add_argument(
        "--feedforward",
        action="store_true",
        help="learn a correction as a function of the reference over the run (any motion: a "
        "trace, irregular breathing, a heartbeat not locked to the breath); settings: --set "
        "learning.stretch_s=5 with a scenario's learning: !FeedforwardTuning {}",
    )
    rp.add_argument(
        "--learned",
        default=None,
        metavar="FILE.npz",
        help="start the feed-forward from a model an earlier run saved (--save-learned), or "
        "from the model learned on the motion library that ships with the package "
        "('library') (default: none, from zero)",
    )
    rp.add_argument(
        "--hold",
        action="store_true",
        help="apply the --learned model without learning further",
    )
    rp.add_argument(
        "--save-learned",
        default=None,
        metavar="FILE.npz",
        help="write the learned feed-forward at the end of the run (for --learned) (default: none)",
    )


def _add_stream_arguments(rp) -> None:
    """``reproduce --stream``: the motion as if it arrived live, late, followed with a
    predictor (:mod:`~stewart_drake.organ_motion.streaming`)."""
    # Written out, not imported from references.prediction: building the parser reads no numpy
    # (tests/test_stream_reproduce.py holds them equal to PREDICTORS and DEFAULT_PREDICTOR).
    rp.add_argument(
        "--stream",
        default=None,
        metavar="LATENCY_S",
        help="run the motion as if it arrived live: each sample reaches the controller "
        "LATENCY_S s after it happened, and the robot follows it with --predictor; the verdict "
        "(PASS/FAIL, exit 2 beyond --tolerance) is the robot's true pose against the true "
        "motion, not against the predicted reference it was given (reported beside it); the "
        "report gives the error against the true motion with and without prediction (default: "
        "none, the motion known in advance)",
    )
    rp.add_argument(
        "--predictor",
        default="linear",
        choices=("none", "linear", "wlms", "mulin", "kalman", "rnn"),
        help="with --stream: how the latency is predicted away: linear, adaptive linear "
        "regression, the best measured; wlms, wavelet-based multiscale regression; mulin, "
        "multi-step linear extrapolation; kalman, a Kalman filter on a breathing model; rnn, a "
        "small recurrent network trained online (UORO); none, the samples followed without "
        'prediction (docs/organ_motion.md, "Choosing the predictor") (default: linear)',
    )
    rp.add_argument(
        "--stream-rate",
        type=positive_float,
        default=None,
        metavar="HZ",
        help="with --stream: the samples' rate (default: a trace's own, 25 Hz for a "
        "library motion)",
    )


def _add_surrogate_arguments(rp) -> None:
    """``reproduce --surrogate``: an external surrogate's stage beside the platform, following a
    recorded signal or one made from the motion by a correlation model (docs/surrogate.md)."""
    rp.add_argument(
        "--surrogate",
        default=None,
        metavar="EXTERNAL",
        help="also move an external surrogate beside the platform, on the same clock: a "
        "recorded file (IntERAct's 2-column Resp/ format, or a header naming its column), or "
        "'model' for the motion through a correlation model (--surrogate-param); the report "
        "adds the surrogate's fidelity, the pair's relative latency and its lead, hysteresis "
        "and correlation as reproduced against as asked (default: none)",
    )
    rp.add_argument(
        "--surrogate-param",
        nargs="*",
        default=None,
        metavar="KEY=VALUE",
        help="with --surrogate model: ratio=0.8 lead=0.3s drift=2mm/min change_at=20s "
        "lead_after=-0.2s ratio_after=1.2 blend=1s (default: none, the motion itself: ratio 1, "
        "no lead, no drift, no change)",
    )
    rp.add_argument(
        "--surrogate-columns",
        default="",
        metavar="COLUMNS",
        help="the recorded file's columns when it has no header or holds the internal too: "
        "the others named '-', the external's by the axis it moves, e.g. 't [s], -, SI [mm]' "
        "(default: its own)",
    )
    rp.add_argument(
        "--surrogate-latency",
        type=positive_float,
        default=0.01,
        metavar="S",
        help="largest relative latency allowed between platform and surrogate, s "
        "(default: 0.01, one period of the servo bus)",
    )


def with_surrogate(args, scenario):
    """``scenario`` with the surrogate ``--surrogate`` asks for (unchanged without it),
    validated before any run.

    Raises:
        InvalidConfigError: --surrogate-param without ``--surrogate model`` or a bad model
            (:func:`~stewart_drake.execution.trace_options.correlation_model`);
            MissingFileError: no such file.
    """
    from ..base.errors import InvalidConfigError
    from ..execution.trace_options import correlation_model
    from ..station.surrogate.axis import SurrogateAxis

    if args.surrogate is None:
        if args.surrogate_param or args.surrogate_columns:
            raise InvalidConfigError("--surrogate-param and --surrogate-columns need --surrogate")
        return scenario
    if args.surrogate == "model":
        axis = SurrogateAxis(correlation=correlation_model(args.surrogate_param))
    else:
        if args.surrogate_param:
            raise InvalidConfigError(
                "--surrogate-param sets a correlation model: give --surrogate model"
            )
        axis = SurrogateAxis(trace=args.surrogate, columns=args.surrogate_columns)
    base = scenario.surrogate
    if base is not None:  # the scenario's own stage and lag matching, with this signal
        axis.stage, axis.match_platform_lag = base.stage, base.match_platform_lag
    return replace(scenario, surrogate=axis).validate()


def _surrogate_verdict(args, rep, name: str, out: Path, tolerance) -> bool:
    """Print and write (``reproduce_<name>_surrogate.json``) the pair's figures
    (:func:`~stewart_drake.organ_motion.surrogate_pair.pair_report`); True when the surrogate is
    within the length tolerance of its signal and the relative latency within
    ``--surrogate-latency``."""
    import json

    import numpy as np

    from ..base.fileio import atomic_write
    from .surrogate_pair import pair_report, report_lines

    result, axis = rep.result, rep.plan.scenario.surrogate
    t = np.asarray(result.t, float)
    signal = axis.signal(rep.reference, rep.plan.duration_s)
    s = result.surrogate
    split = axis.correlation.change_at_s if not axis.trace else None
    fig = pair_report(
        t, result.x, result.x_d, s[:, 0], signal.evaluate(t)[0], rep.fidelity["window_s"], split
    )
    for line in report_lines(fig):
        print(line)
    latency = fig["latency"]["relative_latency_s"]
    ok = within(fig["external_rms_m"], tolerance[0]) and within(latency, args.surrogate_latency)
    fig["passed"] = bool(ok)
    fig["tolerance_m"], fig["latency_tolerance_s"] = tolerance[0], args.surrogate_latency
    path = out / f"reproduce_{name}_surrogate.json"
    text = json.dumps(fig, indent=1).encode()
    atomic_write(path, lambda f: f.write(text))
    print(
        f"surrogate {'PASS' if ok else 'FAIL'}: the stage's carriage against its signal, RMS "
        f"{fig['external_rms_m'] * 1e6:.3g} um "
        f"(tolerance {tolerance[0] * 1e6:.3g} um), relative latency {latency * 1e3:+.3g} ms "
        f"(tolerance {args.surrogate_latency * 1e3:.3g} ms); wrote {path}"
    )
    return ok


def _add_measurement_arguments(rp) -> None:
    """What ``reproduce`` measures and allows: the cycles, the tolerance, the scaling of a
    motion too large, a trace's length."""
    rp.add_argument(
        "--cycles",
        type=int_at_least(1),
        default=2,
        metavar="N",
        help="cycles measured after the learned ones (or after one cycle to settle)",
    )
    rp.add_argument(
        "--tolerance",
        default="0.1mm,0.1deg",
        help="RMS error allowed per axis, a length and an angle: of the robot's true pose "
        "against the motion (with --stream, the true motion)",
    )
    rp.add_argument(
        "--scale-to-fit",
        action="store_true",
        help="shrink a motion the robot cannot follow about its centre until every "
        "check passes (instead of refusing it), saying by how much",
    )
    rp.add_argument(
        "--duration",
        type=positive_float,
        default=None,
        help="s to run a trace that has no cycles (default: its length)",
    )


def _cmd_reproduce(args) -> int:
    """``stewart-drake reproduce``: a motion of the organ-motion library or a recorded trace on
    the robot, checked, run (learning on request) and measured: a report with a verdict."""
    from ..base.fileio import check_replaceable
    from .fidelity import format_window, parse_tolerance, verdict
    from .fidelity_report import write_report
    from .reproduction import reproduce

    tolerance = parse_tolerance(args.tolerance)
    scenario, name = motion_scenario(args)
    scenario = with_surrogate(args, scenario)
    out = Path(args.out)
    if args.stream is not None or args.stream_rate is not None:
        if args.surrogate is not None:
            from ..base.errors import InvalidConfigError

            raise InvalidConfigError("--stream and --surrogate: one at a time")
        return _cmd_stream(args, scenario, name, out, tolerance)
    for suffix in (".md", ".png", ".json"):
        check_replaceable(out / f"reproduce_{name}{suffix}")
    feedforward = _feedforward_choice(args, scenario)
    if args.html is not None:
        check_output(args.html, "--html", is_file=True)
    rep = reproduce(
        scenario,
        learn_cycles=args.learn_cycles,
        eval_cycles=args.cycles,
        scale_to_fit=args.scale_to_fit,
        duration_s=args.duration,
        progress=not args.no_progress,
        feedforward=feedforward,
        on_checked=lambda: say_if_compiling("reproduce"),
    )
    if args.save_learned and rep.learned is not None:
        from ..control.feedforward_basis import save_learned

        print(f"wrote {save_learned(args.save_learned, rep.learned)} (the learned feed-forward)")
    if rep.scale != 1.0:
        print(
            f"{name} did not fit the robot: scaled by {rep.scale:.3f} about its centre "
            f"(every check passes at that size)"
        )
    fid = rep.fidelity
    print(
        f"RMS error over t = {format_window(*fid['window_s'])} s: translation "
        f"{fid['rms_translation_m'] * 1e6:.3g} um, rotation {fid['rms_rotation_rad'] * 1e6:.3g} "
        f"urad; lag {fid['lag_all_s'] * 1e3:.3g} ms",
        flush=True,
    )
    start = rep.startup
    if start and start["window_s"][1] > 0:
        print(
            f"start-up, t = 0-{start['window_s'][1]:.4g} s (not in the figures): RMS "
            f"{start['rms_translation_m'] * 1e6:.3g} um / {start['rms_rotation_rad'] * 1e6:.3g} "
            f"urad, peak {start['peak_translation_m'] * 1e6:.3g} um"
        )
    resolution = rep.resolution()
    if resolution[0] > 0:
        print(
            f"encoders' resolution at these poses: {resolution[0] * 1e6:.3g} um / "
            f"{resolution[1] * 1e6:.3g} urad RMS in the measured pose"
        )
    note = rep.result.config_summary.get("temperature_note")
    if note is not None:
        print(note)
    md, png, js = write_report(rep, out, tolerance)
    ok, line = verdict(fid, tolerance, rep.comparison())
    print(line)
    if args.surrogate is not None:
        ok = _surrogate_verdict(args, rep, name, out, tolerance) and ok
    print(f"wrote {md}, {png} and {js}")
    if args.html:  # the run's plant-state log, replayed with the reference's ghost
        from .fidelity_replay import reproduction_html

        plan = rep.plan
        html = reproduction_html(rep, plan.plant_geometry, args.html, tolerance, plan=plan)
        print(f"wrote {html} (Meshcat replay with the reference's ghost and the error)")
    return 0 if ok else 2


def _cmd_stream(args, scenario, name, out, tolerance) -> int:
    """``reproduce --stream LATENCY_S``: refused before any work when the latency, the
    predictor or the stream is bad or learning is asked for; otherwise the run, its lines, its
    verdict (:func:`~.stream_report.stream_verdict`: the robot's true pose against the true motion,
    with the robot against the reference it was given beside it) and its reports
    (:func:`~.stream_report.write_stream_report`, and the robot's fidelity against the true motion,
    ``reproduce_<name>_stream_robot``); exit 0 within ``tolerance``, 2 beyond it."""
    from ..base.errors import InvalidConfigError
    from ..base.fileio import check_replaceable
    from ..references.stream import check_latency
    from .fidelity_report import report_markdown, write_report
    from .stream_report import stream_summary, stream_verdict, write_stream_report
    from .streaming import reproduce_stream

    if args.stream is None:
        raise InvalidConfigError("--stream-rate is for --stream LATENCY_S: give the latency")
    latency = check_latency(args.stream)
    if args.learn_cycles or args.feedforward or args.learned or args.html:
        raise InvalidConfigError(
            "--stream follows a motion as it arrives: it takes no learning (--learn-cycles, "
            "--feedforward, --learned) and no --html"
        )
    for suffix in (".md", ".png", ".json"):
        check_replaceable(out / f"reproduce_{name}_stream{suffix}")
        check_replaceable(out / f"reproduce_{name}_stream_robot{suffix}")
    figures = reproduce_stream(
        scenario,
        latency,
        args.predictor,
        args.stream_rate,
        args.duration,
        tolerance=(tolerance[0] * 3**0.5, tolerance[1] * 3**0.5),
        scale_to_fit=args.scale_to_fit,
        progress=not args.no_progress,
        on_checked=lambda: say_if_compiling("reproduce"),
    )
    if figures["scale"] != 1.0:
        print(
            f"the true motion did not fit the robot: scaled by {figures['scale']:.3f} about its "
            "centre, then streamed"
        )
    for line in stream_summary(figures):
        print(line)
    ok, lines = stream_verdict(figures, tolerance)
    md, png, js = write_stream_report(figures, out, name, tolerance)
    judged = figures["judged"]
    page = report_markdown(
        judged, tolerance, context=[f"{x[0].upper()}{x[1:]}." for x in lines[1:]]
    )
    own, _, _ = write_report(
        judged, out, tolerance, stem=f"reproduce_{name}_stream_robot", text=page
    )
    for line in lines[1:]:
        print(line)
    print(lines[0], flush=True)
    print(
        f"wrote {md}, {png} and {js} (and the robot's fidelity against the true motion, {own.name})"
    )
    return 0 if ok else 2


def motion_scenario(args):
    """The scenario of ``reproduce`` (and ``verify``) with its reference
    (:func:`motion_reference`), validated, and the motion's name (the reproduction's files'
    ``reproduce_<name>``): (Scenario, str).

    Raises:
        InvalidConfigError: as :func:`motion_reference`; the scenario, the motion or its
            parameters refused by their validation.
    """
    from ..run.scenario_io import load_scenario

    scenario = load_scenario(args.scenario, args.set or ())
    reference = motion_reference(args)
    guard = replace(scenario.guard, divergence_dir=str(Path(args.out) / "diverged"))
    return replace(scenario, reference=reference, guard=guard).validate(), reference.label


def motion_reference(args):
    """The reference a command's motion arguments choose
    (:func:`~stewart_drake.execution.options.add_motion_arguments` and
    :func:`~stewart_drake.execution.trace_options.add_trace_arguments`: ``args.motion``, ``param``,
    ``add`` and the trace options): the trace file's
    :class:`~stewart_drake.references.traces.TraceReference` or the library motion's
    :class:`~stewart_drake.references.organ.library.OrganMotionReference`, with the motions
    ``--add`` lays on it; its ``label`` names the motion. Not validated: the scenario's
    validation names an unknown motion or parameter. One conversion for ``reproduce``,
    ``verify`` and ``robot``.

    Raises:
        InvalidConfigError: a motion added twice, a ``--param`` not KEY=VALUE or given to a
            trace without ``--add``, or options of a trace for a library motion.
    """
    from ..base.errors import InvalidConfigError
    from ..references.organ.library import OrganMotionReference, split_parameters

    source = args.motion
    params = key_values(args.param, "--param")
    layers = list(args.add or ())
    if len(set(layers)) != len(layers):
        raise InvalidConfigError(f"--add takes each motion once, got {', '.join(layers)}")
    if not is_trace_file(source):
        if trace_options_given(args):
            raise InvalidConfigError(
                f"{TRACE_ONLY} are for a trace file; a library motion takes --param"
            )
        shares = split_parameters([source, *layers], params)
        return OrganMotionReference(
            motion=source, parameters=shares[0], add=dict(zip(layers, shares[1:]))
        )
    if params and not layers:
        raise InvalidConfigError(
            "--param sets a library motion's parameters (of one added with --add on a "
            f"trace); a trace takes {TRACE_ONLY}"
        )
    size = Path(source).stat().st_size if Path(source).is_file() else 0
    if size > 1e6 and not getattr(args, "no_progress", False):  # seconds to read and resample
        from ..base.checks import format_bytes

        print(f"reading {source} ({format_bytes(size)})", file=sys.stderr, flush=True)
    return trace_reference(args, source, dict(zip(layers, split_parameters(layers, params))))


def _feedforward_choice(args, scenario):
    """The feed-forward learner ``reproduce``'s flags ask for (None: none), checked before the
    run: ``--feedforward``, ``--learned FILE`` (read now: numbers only), ``--hold``,
    ``--save-learned FILE``; the scenario's own ``learning`` when it is one, applied as ``run``
    applies it when it names a model (``learned_from``)."""
    from ..base.errors import InvalidConfigError
    from ..control.feedforward_basis import LIBRARY_MODEL, load_learned
    from ..control.feedforward_tuning import FeedforwardTuning

    ff = scenario.learning if isinstance(scenario.learning, FeedforwardTuning) else None
    flags = args.feedforward or args.learned or args.hold or args.save_learned
    if not flags and not (ff is not None and ff.learned_from):
        return None
    if args.learn_cycles:
        raise InvalidConfigError(
            "--learn-cycles learns per cycle; --feedforward, --learned, --hold and "
            "--save-learned (or the scenario's learning.learned_from) learn as a function of "
            "the reference: choose one"
        )
    if args.hold and not (args.learned or (ff is not None and ff.learned_from)):
        raise InvalidConfigError("--hold applies a model learned before: give --learned FILE")
    ff = ff or FeedforwardTuning()
    if args.learned:
        ff.learned_from = str(LIBRARY_MODEL if args.learned == "library" else args.learned)
    if ff.learned_from:
        load_learned(ff.learned_from)  # refused now, not after the run
    if args.hold:
        ff.learn = False
    elif args.feedforward or args.learned:
        ff.learn = True
    if args.save_learned:
        check_output(args.save_learned, "--save-learned", is_file=True)
    ff.validate(scenario.control_period_s)
    return ff


def _add_examples_command(sub) -> None:
    """Add the ``examples`` command to ``sub``, the ``stewart-drake`` subparsers."""
    ex = sub.add_parser(
        "examples",
        help="copy small example inputs (a tracker's exports, a registration, an encoder log, "
        "traces) into a folder, to try the documented commands on",
    )
    ex.add_argument(
        "folder",
        nargs="?",
        default=".",
        metavar="DIR",
        help="where to copy them (default: the current folder); a file there of an example's "
        "name is replaced only if this command wrote it",
    )
    ex.set_defaults(func=_cmd_examples)


def _cmd_examples(args) -> int:
    """``stewart-drake examples``: copy the examples, one line per file written."""
    from .examples import copy_examples

    for path, size, what in copy_examples(args.folder):
        print(f"wrote {path} ({size / 1e3:.0f} kB): {what}")
    return 0
