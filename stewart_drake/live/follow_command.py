"""``stewart-drake robot --follow-lcm CHANNEL --latency S``: the options of following a motion
live over LCM (:mod:`.follow`), checked before any work. Imports nothing heavy: the command's
parser is built from it.
"""

from __future__ import annotations

import dataclasses
import math

from ..base.errors import InvalidConfigError

#: The rate a live source is read at unless told, Hz (``references.stream``'s
#: ``DEFAULT_STREAM_RATE_HZ``, written out: building the parser reads no numpy;
#: tests/test_robot_follow.py holds them equal).
DEFAULT_RATE_HZ = 25.0
#: The predictors (``references.prediction.PREDICTORS``, written out for the same reason) and
#: the default.
PREDICTORS, DEFAULT_PREDICTOR = ("none", "linear", "wlms", "mulin", "kalman", "rnn"), "linear"


def add_follow_arguments(parser) -> None:
    """``robot --follow-lcm CHANNEL --latency S`` and the options that go with it."""
    parser.add_argument(
        "--follow-lcm",
        default=None,
        metavar="CHANNEL",
        help="follow the poses published live on the LCM channel CHANNEL "
        "(lcmt_stewart_pose_sample, docs/lcm.md) with the latency predicted away, until "
        "--duration s, the source stops or Ctrl-C (default: none, a reference known in advance)",
    )
    parser.add_argument(
        "--latency",
        default=None,
        metavar="S",
        help="with --follow-lcm: how old a sample is when it arrives, s (required: no default)",
    )
    parser.add_argument(
        "--follow-rate",
        default=None,
        metavar="HZ",
        help=f"with --follow-lcm: the samples' rate (default: {DEFAULT_RATE_HZ:g} Hz)",
    )
    parser.add_argument(
        "--predictor",
        default=None,
        choices=PREDICTORS,
        help=f"with --follow-lcm: how the latency is predicted away (default: {DEFAULT_PREDICTOR})",
    )
    parser.add_argument(
        "--lcm-url",
        default=None,
        metavar="URL",
        help="with --follow-lcm: the LCM URL to listen on: udpm://ADDRESS:PORT[?ttl=N], or "
        "memq:// (default: Drake's, LCM_DEFAULT_URL or udpm://239.255.76.67:7667?ttl=0)",
    )


@dataclasses.dataclass(frozen=True)
class FollowOptions:
    """``robot --follow-lcm``'s options, checked (:func:`check_follow_arguments`)."""

    channel: str
    latency_s: float
    rate_hz: float
    predictor: str
    url: str


def check_follow_arguments(args) -> FollowOptions | None:
    """``robot``'s follow options, checked before any work: None without ``--follow-lcm``.

    Raises:
        InvalidConfigError: a follow option without ``--follow-lcm``; with it, a reference,
            ``--teleop``, ``--dry-run``, ``--calibrate`` or ``--meshcat``; no ``--latency``;
            a latency, rate, channel or URL that is not one (each named).
    """
    from ..references.stream import check_latency
    from ..station.lcm_publish import LCM_MAX_CHANNEL_CHARS, check_lcm_url

    given = [
        option
        for option, value in (
            ("--latency", args.latency),
            ("--follow-rate", args.follow_rate),
            ("--predictor", args.predictor),
            ("--lcm-url", args.lcm_url),
        )
        if value is not None
    ]
    if args.follow_lcm is None:
        if given:
            raise InvalidConfigError(f"{', '.join(given)}: for --follow-lcm CHANNEL, give one")
        return None
    others = [
        option
        for option, on in (
            ("reference (MOTION)", args.motion is not None),
            ("--teleop", args.teleop),
            ("--dry-run", args.dry_run),
            ("--calibrate", args.calibrate is not None),
            ("--meshcat", args.meshcat),
        )
        if on
    ]
    if others:
        raise InvalidConfigError(f"--follow-lcm follows a live source: it takes no {others[0]}")
    channel = args.follow_lcm
    if not channel or not channel.isprintable() or len(channel) > LCM_MAX_CHANNEL_CHARS:
        raise InvalidConfigError(
            f"--follow-lcm {channel!r}: a channel is 1 to {LCM_MAX_CHANNEL_CHARS} printable "
            "characters"
        )
    if args.latency is None:
        raise InvalidConfigError("--follow-lcm needs --latency S: how old a sample is on arrival")
    latency = check_latency(args.latency)
    rate = DEFAULT_RATE_HZ
    if args.follow_rate is not None:
        try:
            rate = float(args.follow_rate)
        except ValueError:
            rate = math.nan
        if not (math.isfinite(rate) and 0 < rate <= 1000):
            raise InvalidConfigError(
                f"--follow-rate must be a rate in (0, 1000] Hz, got {args.follow_rate!r}"
            )
    url = args.lcm_url if args.lcm_url is not None else ""
    if url:
        check_lcm_url(url, "--lcm-url")
    return FollowOptions(channel, latency, rate, args.predictor or DEFAULT_PREDICTOR, url)


def follow_from_arguments(options: FollowOptions, args, scenario, out, stem, signals):
    """``robot --follow-lcm``'s session (:func:`~.follow.follow_on_robot`) on the checked
    ``options``, listening on their URL (:func:`~stewart_drake.station.lcm_publish.make_lcm`)."""
    from ..station.lcm_publish import make_lcm
    from . import follow

    lcm = make_lcm(options.url)
    return follow.follow_on_robot(
        scenario,
        lcm,
        options.channel,
        options.latency_s,
        rate_hz=options.rate_hz,
        predictor=options.predictor,
        duration_s=args.duration,
        first_sample_s=follow.FIRST_SAMPLE_S,
        loop_timeout_s=args.loop_timeout,
        out=out,
        stem=stem,
        signals=signals,
        realtime=args.realtime,
    )


__all__ = [
    "FollowOptions",
    "add_follow_arguments",
    "check_follow_arguments",
    "follow_from_arguments",
    "DEFAULT_RATE_HZ",
    "PREDICTORS",
    "DEFAULT_PREDICTOR",
]
