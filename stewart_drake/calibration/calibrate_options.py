"""The options of ``stewart-drake calibrate`` (:mod:`stewart_drake.live.calibrate_command`): the
modes and the files they take, the identification's settings and the rehearsal's, with the
argument types that check them (a tracker's noise with its units, the rest at each pose) before
any work."""

from __future__ import annotations

import argparse

from ..base.errors import InvalidConfigError
from ..base.units import length_and_angle
from ..execution.options import int_at_least, positive_float


def add_mode_arguments(cal, robot_scenario: str) -> None:
    """The modes (identify by default; ``--plan``, ``--rehearse``, ``--join``, ``--register``)
    and the files ``--join`` and ``--rehearse --bus`` take."""
    mode = cal.add_mutually_exclusive_group()
    mode.add_argument(
        "--plan",
        type=int_at_least(12),
        default=None,
        metavar="N",
        help="choose N poses to measure (greedy D-optimal over the admissible set) and write "
        "the path through them to --out, a reference the robot command drives (default: identify)",
    )
    mode.add_argument(
        "--rehearse",
        action="store_true",
        help="draw a robot as built, measure it with an emulated tracker, identify it and "
        "print the readings' prediction before and after on 50 other poses",
    )
    mode.add_argument(
        "--join",
        nargs=2,
        default=None,
        metavar=("ENCODERS.csv", "TRACKER.csv"),
        help="join the encoder log `stewart-drake robot POSES.csv` wrote (robot_poses_encoders"
        ".csv) and the tracker's file (time [s] on the robot computer's clock, phi [rad] .. "
        "Z [m]) over the windows of --plan-file into the measurements file --out (default: "
        "none: identify)",
    )
    mode.add_argument(
        "--register",
        default=None,
        metavar="MEASURED.csv",
        help="register a tracker: fit its frame and the marker's offset on the platform to its "
        "measurement of the registration motion (`stewart-drake robot registration`; its "
        "--param as the robot ran it) and write them to --out (REG.yaml), for verify's "
        "--registration; that run is not judged (default: identify)",
    )
    cal.add_argument(
        "--plan-file",
        default=None,
        metavar="POSES.csv",
        help="with --join: the path --plan wrote (its windows file beside it) (default: none)",
    )
    cal.add_argument(
        "--tracker-clock-offset",
        default=None,
        metavar="SECONDS|estimate",
        help="with --join: s added to the tracker's times to put them on the robot computer's "
        "clock, or estimate to find them from the motion the robot and the tracker both saw "
        "(default: 0, the tracker stamps on the robot computer's clock)",
    )
    cal.add_argument(
        "--bus",
        default=None,
        metavar="FOLDER",
        help="with --rehearse: rehearse over the bus emulator, the robot driving the path "
        "through the poses (chosen as --plan chooses them, or as --select says), an emulated "
        "tracker following it, "
        "every file kept in FOLDER (the scenario's "
        f"bus; default scenario: {robot_scenario})",
    )


def add_identification_arguments(cal) -> None:
    """The identification's options: the tracker's noise, what stays nominal, the outliers."""
    cal.add_argument(
        "--noise",
        type=noise_argument,
        default="5um,20urad",
        metavar="LENGTH,ANGLE",
        help="the tracker's noise, one standard deviation per axis, with units (at most 1 mm "
        "and 10 mrad)",
    )
    cal.add_argument(
        "--min-singular",
        type=positive_float,
        default=1.0,
        help="name the combinations of parameters whose scaled singular value is below this "
        "as known mostly from the tolerances (1: the data know them less well than the "
        "drawing; the tolerances' prior holds them near nominal)",
    )
    cal.add_argument(
        "--outlier-threshold",
        type=positive_float,
        default=4.0,
        help="flag a reading whose studentized residual is beyond this",
    )
    cal.add_argument(
        "--robust",
        action="store_true",
        help="the soft-L1 loss instead of squares (the default drop of outliers is better "
        "at blunders: docs/calibration.md)",
    )
    cal.add_argument(
        "--drop-outliers",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="drop the poses that hold a flagged reading and identify again, until none is "
        "flagged (at most 10 rounds); --no-drop-outliers keeps them",
    )


def add_rehearsal_arguments(cal) -> None:
    """``--plan``'s and ``--rehearse``'s options."""
    cal.add_argument(
        "--poses",
        type=int_at_least(12),
        default=60,
        help="with --rehearse: poses measured",
    )
    cal.add_argument(
        "--select",
        choices=["random", "chosen"],
        default=None,
        help="with --rehearse: the poses drawn at random or chosen (greedy D-optimal) "
        "(default: random; with --bus chosen, as --plan chooses them)",
    )
    cal.add_argument(
        "--seed",
        type=int_at_least(0),
        default=0,
        help="with --rehearse: the robot drawn and the noise; with --plan: the candidates",
    )
    cal.add_argument(
        "--save-measurements",
        default=None,
        metavar="FILE.csv",
        help="with --rehearse: also write the emulated measurements, a file calibrate reads "
        "(default: none)",
    )
    cal.add_argument(
        "--candidates",
        type=int_at_least(50),
        default=2000,
        help="with --plan and --rehearse: admissible poses drawn to choose from",
    )
    cal.add_argument(
        "--dwell",
        type=dwell_argument,
        default=3.0,
        help=f"with --plan and --rehearse --bus: s the robot rests at each pose (its first "
        f"second to settle; {MIN_DWELL_S:g} to {MAX_DWELL_S:g} s)",
    )


#: The rest at each planned pose, s: its first second settles, the rest is averaged; past a
#: minute a pose adds drift (temperature), not accuracy, and 1e5 s made paths of days.
MIN_DWELL_S, MAX_DWELL_S = 1.5, 60.0
#: The largest tracker noise, one standard deviation (m, rad): a tracker worse than this
#: cannot calibrate a robot built to tenths of a millimetre.
MAX_NOISE = (1e-3, 1e-2)


def dwell_argument(text: str) -> float:
    """An argparse type: the rest at each pose, s, in [MIN_DWELL_S, MAX_DWELL_S]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not MIN_DWELL_S <= value <= MAX_DWELL_S:
        raise argparse.ArgumentTypeError(
            f"must be in [{MIN_DWELL_S:g}, {MAX_DWELL_S:g}] s (the first second settles), "
            f"got {text}"
        )
    return value


def noise_argument(text: str) -> tuple[float, float]:
    """An argparse type: the tracker's noise, ``LENGTH,ANGLE`` with units (5um,20urad), as
    (m, rad), each at most :data:`MAX_NOISE` (0: a perfect tracker), read by the one reader of
    a length with an angle (:func:`~stewart_drake.base.units.length_and_angle`)."""
    try:
        return length_and_angle(
            text,
            "--noise",
            MAX_NOISE,
            "at most 1 mm and 10 mrad (a tracker worse than that cannot calibrate the robot)",
            example="5um,20urad",
            zero=True,
        )
    except InvalidConfigError as error:
        raise argparse.ArgumentTypeError(f"expected a length and an angle: {error}") from None


__all__ = [
    "MIN_DWELL_S",
    "MAX_DWELL_S",
    "MAX_NOISE",
    "add_mode_arguments",
    "add_identification_arguments",
    "add_rehearsal_arguments",
    "dwell_argument",
    "noise_argument",
]
