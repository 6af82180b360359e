"""The ``robot`` command's options of its session (the port, a dry run or a calibration, the
homing, the hold, the duration, the watchdog) and of what drives it (the emulator, real-time
scheduling, the surrogate's stage, Meshcat, teleoperation); the command is :mod:`.command`."""

from __future__ import annotations

import argparse
import math
from typing import NamedTuple

from ..execution.options import positive_float


def add_session_arguments(rob) -> None:
    """``robot``'s options of the session: the port, a dry run or a calibration, the homing,
    the hold, the duration and our watchdog."""
    rob.add_argument(
        "--port", default=None, help="the servos' serial port (default: the scenario's bus.port)"
    )
    rob.add_argument(
        "--dry-run",
        action="store_true",
        help="read the bus with the torque off, print the pose and its verdict, stop",
    )
    rob.add_argument(
        "--calibrate",
        type=float,
        default=None,
        metavar="DEG",
        help="read the zero_counts with every crank held at DEG degrees (0: horizontal), "
        "torque off; print them and stop (default: no calibration)",
    )
    rob.add_argument(
        "--home-s",
        type=positive_float,
        default=3.0,
        help="seconds of the homing lead-in from the measured pose to the reference's start",
    )
    rob.add_argument(
        "--hold",
        type=float,
        default=0.0,
        help="seconds the reference's last pose is held before the torque goes off",
    )
    rob.add_argument(
        "--duration",
        type=positive_float,
        default=None,
        help="s of the reference (default: a trace's or CSV's whole length, else the scenario's "
        "duration_s)",
    )
    rob.add_argument(
        "--loop-timeout",
        type=positive_float,
        default=0.1,
        help="our watchdog: the torque goes off when no control period completes for this long, s",
    )


def add_drive_arguments(rob) -> None:
    """``robot``'s options of what drives it and on what: the emulator, real-time scheduling,
    the surrogate's stage, Meshcat and teleoperation."""
    rob.add_argument(
        "--emulate",
        type=emulate_choice,
        nargs="?",
        const=EmulateChoice(None, REST_POSE),
        default=None,
        metavar="SERVOS@POSE",
        help="rehearse on the bus emulator (a pseudo-terminal, the robot's Drake plant at real "
        "time behind it): SERVOS realistic (the scenario's emulator section: servos, bus "
        "timing and robot as built, drawn from its seed; the default) or ideal (the "
        "controller's own model), resting at POSE phi,theta,psi,X,Y,Z (default "
        "0,0,0,0,0,0.28); either alone, or both as ideal@0,0,0,0,0,0.3",
    )
    rob.add_argument(
        "--realtime",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run the control loop on SCHED_FIFO priority 50, pinned to a core, its memory "
        "locked, Python's garbage collected between periods, the cores' idle states held "
        "shallow (PM QoS) (default; what the OS refuses is "
        "said in one line and the run goes on; with --emulate the emulator's process too)",
    )
    rob.add_argument(
        "--surrogate",
        default=None,
        metavar="EXTERNAL",
        help="drive the external surrogate's stage (the bus's seventh servo, bus.surrogate; "
        "with --emulate the default stage if the scenario names none) along this trace on the "
        "platform's clock: a 2-column file (time, displacement in mm: IntERAct's Resp/ files) "
        "or a headed file of one axis; the run's relative latency is measured from the encoders",
    )
    rob.add_argument(
        "--budget",
        action="store_true",
        help="with --emulate and a motion: the error budget of servos as they are, one "
        "session with every departure the emulator draws, then one without each (minutes); "
        "printed and written as OUT/robot_budget.md and .json",
    )
    rob.add_argument("--meshcat", action="store_true", help="show the measured robot in Meshcat")
    rob.add_argument(
        "--teleop",
        action="store_true",
        help="drive the robot from Meshcat's sliders, from where it rests (until Ctrl-C, or "
        "--duration s)",
    )


#: Where an emulated robot rests by default: phi, theta, psi (rad), X, Y, Z (m).
REST_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.28)


class EmulateChoice(NamedTuple):
    """``--emulate``'s value: which servos (None: the scenario's ``emulator.servos``) and the
    pose the robot rests at (rad, m)."""

    servos: str | None
    pose: tuple


def emulate_choice(text: str) -> EmulateChoice:
    """``realistic``, ``ideal``, a POSE (:func:`pose6`), or ``SERVOS@POSE``."""
    from ..station.bus.emulator_config import SERVOS

    servos, _, pose = text.partition("@") if "@" in text else (text, "", "")
    if servos in SERVOS:
        return EmulateChoice(servos, tuple(pose6(pose)) if pose else REST_POSE)
    if "@" in text:
        raise argparse.ArgumentTypeError(
            f"give SERVOS@POSE with SERVOS one of {', '.join(SERVOS)}, got {servos!r}"
        )
    if "," in text:  # a pose: its own words
        return EmulateChoice(None, tuple(pose6(text)))
    try:
        return EmulateChoice(None, tuple(pose6(text)))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"give {' or '.join(SERVOS)}, a POSE phi,theta,psi,X,Y,Z in rad and m, or both as "
            f"ideal@POSE, got {text!r}"
        ) from None


def pose6(text: str) -> list[float]:
    """Six comma-separated finite numbers phi,theta,psi,X,Y,Z (rad, m)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(
            f"give six finite numbers phi,theta,psi,X,Y,Z in rad and m, got {text!r}"
        )
    return values


__all__ = [
    "add_session_arguments",
    "add_drive_arguments",
    "pose6",
    "emulate_choice",
    "EmulateChoice",
    "REST_POSE",
]
