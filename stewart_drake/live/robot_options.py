"""The ``robot`` command's options of its session (the port, a dry run or a calibration, the
homing, the hold, the duration, the watchdog) and of what drives it (the emulator, real-time
scheduling, the surrogate's stage, Meshcat, teleoperation); the command is :mod:`.command`."""

from __future__ import annotations

import argparse
import math

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
        type=pose6,
        nargs="?",
        const=[0.0, 0.0, 0.0, 0.0, 0.0, 0.28],
        default=None,
        metavar="POSE",
        help="rehearse on the bus emulator (a pseudo-terminal, the robot's Drake plant at real "
        "time behind it) resting at POSE phi,theta,psi,X,Y,Z (default 0,0,0,0,0,0.28)",
    )
    rob.add_argument(
        "--realtime",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run the control loop on SCHED_FIFO priority 50, pinned to a core, its memory "
        "locked, Python's garbage collected between periods (default; what the OS refuses is "
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
    rob.add_argument("--meshcat", action="store_true", help="show the measured robot in Meshcat")
    rob.add_argument(
        "--teleop",
        action="store_true",
        help="drive the robot from Meshcat's sliders, from where it rests (until Ctrl-C, or "
        "--duration s)",
    )


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
]
