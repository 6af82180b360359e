"""The options that say how a trace file is read, one definition for every command that reads one
(``check``, ``reproduce``, ``robot``, ``verify``), with what they build
(:func:`trace_reference`) (a motion's source is a trace file when
:func:`~.options.is_trace_file` says so).

Like :mod:`.options`, it imports nothing of the features and nothing heavy when imported."""

from __future__ import annotations

from ..base.trace_layouts import trace_formats
from .options import positive_float


def add_trace_arguments(parser) -> None:
    """The options that say how a trace file is read, one definition for every command that
    reads one (``check``, ``reproduce``): :func:`trace_reference` turns them into a
    :class:`~stewart_drake.references.traces.TraceReference`."""
    # The formats from their one table (base.trace_layouts: names only); the rest written out,
    # not imported from references.traces: building the parser reads no numpy
    # (tests/test_trace_formats.py holds them equal to CENTRE_MODES, SKIP_COLUMN,
    # SMOOTHING_MODES and SEAM_BLEND_S).
    parser.add_argument(
        "--format",
        choices=trace_formats(),
        default="auto",
        help="a trace's layout: auto reads a header line (a Varian RPM .vxp export by its "
        "[Header]), else 7 columns as the phantom format and 2 as a surrogate",
    )
    parser.add_argument(
        "--columns",
        default=None,
        metavar="'t [s],SI [mm],...'",
        help="a trace's columns and units when it has no header line (or to replace it); "
        "a column named - is not read (a frame counter: "
        "'-,t [ms],X [mm],Y [mm],Z [mm]') (default: the file's header, or the "
        "phantom format's by its width)",
    )
    parser.add_argument(
        "--map",
        action="append",
        metavar="COLUMN=AXIS",
        help="put a trace's column on a platform axis, with a sign (repeatable): "
        "SI=-Z; patient axes SI, LR, AP go to X, Y, Z by default",
    )
    parser.add_argument(
        "--lowpass-hz",
        type=positive_float,
        default=None,
        help="zero-phase low-pass of a trace, Hz (default: none)",
    )
    parser.add_argument(
        "--centre",
        default=None,
        metavar="PHI,THETA,PSI,X,Y,Z",
        help="the pose a trace is centred on, rad and m (default: home, 0,0,0,0,0,0.3)",
    )
    parser.add_argument(
        "--centre-on",
        choices=["mean", "first", "none"],
        default="mean",
        help="which pose of a trace goes to --centre (the report says what was removed)",
    )
    parser.add_argument(
        "--smoothing",
        choices=["auto", "none"],
        default="auto",
        help="join a trace's samples by a smoothing spline that drops their measurement noise "
        "(auto; the report says how far it departs from them) or through every sample (none)",
    )
    parser.add_argument(
        "--seam-blend",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="blend each seam of a looped recording (where it starts again with a step) over "
        "this time (default 2 s; 0: leave the seams as recorded)",
    )
    parser.add_argument(
        "--max-gap",
        type=positive_float,
        default=1.0,
        metavar="S",
        help="longest interval without data a trace may have, s",
    )


#: The options of :func:`add_trace_arguments` a motion that is not a trace file refuses.
TRACE_ONLY = (
    "--format, --columns, --map, --lowpass-hz, --centre, --centre-on, --max-gap, --smoothing, "
    "--seam-blend"
)


def trace_options_given(args) -> bool:
    """Whether any option of :func:`add_trace_arguments` differs from its default."""
    return bool(
        args.format != "auto"
        or args.columns
        or args.map
        or args.lowpass_hz
        or args.centre is not None
        or args.centre_on != "mean"
        or args.max_gap != 1.0
        or args.smoothing != "auto"
        or args.seam_blend != 2.0
    )


def trace_reference(args, source: str, add: dict | None = None):
    """The :class:`~stewart_drake.references.traces.TraceReference` of the trace file
    ``source`` read as the options of :func:`add_trace_arguments` say, with library motions
    ``add`` laid on it (the file itself is read later, by the reference).

    Raises:
        InvalidConfigError: ``--centre`` not six numbers, or a ``--map`` not KEY=VALUE.
    """
    from ..base.errors import InvalidConfigError
    from ..references.traces import TraceReference

    centre = [0.0, 0.0, 0.0, 0.0, 0.0, 0.30]
    if args.centre is not None:
        try:
            centre = [float(v) for v in args.centre.split(",")]
        except ValueError:
            raise InvalidConfigError(
                f"--centre takes six numbers phi,theta,psi,X,Y,Z (rad, m), got {args.centre!r}"
            ) from None
    return TraceReference(
        path=source,
        axis_map=key_values(args.map, "--map"),
        centre=centre,
        centre_on=args.centre_on,
        lowpass_hz=args.lowpass_hz or 0.0,
        max_gap_s=args.max_gap,
        format=args.format,
        columns=args.columns or "",
        add=dict(add or {}),
        smoothing=args.smoothing,
        seam_blend_s=args.seam_blend,
    )


def key_values(items, option: str) -> dict:
    """{key: value} of repeated ``KEY=VALUE`` options (values kept as text).

    Raises:
        InvalidConfigError: an item without ``=``, or with an empty key or value.
    """
    from ..base.errors import InvalidConfigError

    out = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise InvalidConfigError(f"{option} takes KEY=VALUE, got {item!r}")
        out[key.strip()] = value.strip()
    return out


#: ``--surrogate-param`` keys: the
#: :class:`~stewart_drake.station.surrogate.correlation.CorrelationModel` field each sets.
MODEL_KEYS = {
    "ratio": "amplitude_ratio",
    "lead": "lead_s",
    "drift": "drift_m_per_s",
    "change_at": "change_at_s",
    "lead_after": "lead_after_s",
    "ratio_after": "ratio_after",
    "blend": "change_blend_s",
}


def _model_units() -> dict[str, float]:
    """The units a ``--surrogate-param`` value may carry, factor to SI: none, a time, or a
    length over a time (the one unit table, :data:`stewart_drake.base.units.UNITS`)."""
    from ..base.units import LENGTH_UNITS, UNITS

    times = UNITS["s"]
    rates = {f"{ln}/{tn}": lf / tf for ln, lf in LENGTH_UNITS.items() for tn, tf in times.items()}
    return {"": 1.0, **times, **rates}


def correlation_model(items):
    """The :class:`~stewart_drake.station.surrogate.correlation.CorrelationModel` of
    ``KEY=VALUE`` words (:data:`MODEL_KEYS`; each value a number with no unit, a time (``s``,
    ``ms``, ``min``) or a speed (a length over a time: ``mm/s``, ``mm/min``, ``m/s``...)),
    validated.

    Raises:
        InvalidConfigError: an unknown key (the keys listed), a value that is not a number with
            one of those units, a model refused by its validation.
    """
    import re

    from ..base.errors import InvalidConfigError
    from ..station.surrogate.correlation import CorrelationModel

    units = _model_units()
    fields = {}
    for item in items or ():
        key, _, value = item.partition("=")
        if key not in MODEL_KEYS:
            raise InvalidConfigError(
                f"--surrogate-param {item!r}: the keys are {', '.join(MODEL_KEYS)}"
            )
        match = re.fullmatch(r"\s*([-+0-9.eE]+)\s*([a-z/]*)\s*", value)
        if match is None or match.group(2) not in units:
            raise InvalidConfigError(
                f"--surrogate-param {item!r}: a number with no unit, a time (s, ms, min) or a "
                "speed (a length over a time: mm/s, mm/min, m/s)"
            )
        try:
            number = float(match.group(1))
        except ValueError:
            raise InvalidConfigError(f"--surrogate-param {item!r}: not a number") from None
        fields[MODEL_KEYS[key]] = number * units[match.group(2)]
    return CorrelationModel(**fields).validate()


__all__ = [
    "add_trace_arguments",
    "TRACE_ONLY",
    "trace_options_given",
    "trace_reference",
    "key_values",
    "MODEL_KEYS",
    "correlation_model",
]
