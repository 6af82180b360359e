"""The error budget of servos as they are: ``robot MOTION --emulate --budget``.

:func:`~stewart_drake.analysis.error_budget.error_budget` simulates the host's controller on the
robot as built; this one measures the robot's own session, the one ``robot --emulate`` runs,
against the realistic bus emulator (its servos, encoders, gears, windings and bus drawn from the
scenario's ``emulator`` seed, never the controller's model: docs/robot.md, "Servos as they
are"). First the session with every departure the draw gives, then once again with each source
(:data:`SOURCES`) made what the controller believes (its scale 1) or taken away (0), the others
left as drawn. A source's share is sqrt(e_all^2 - e_without^2) per axis, as the simulated
budget's (0 where taking it away did not lower the error); the shares are not additive.

The true pose is the emulator's plant (every plant step); the encoder pose what the robot read.
On the loop's clock (``emulator.clock: loop``) the plant moves one control period at each
command whenever it arrives: the bus's timing cannot show there, and its row is not run (said
in the budget's assumptions). The emulated robot is its drawing's geometry: no row for
geometry (``calibrate`` and ``robot_as_built`` are the simulated budget's ``model`` row).
"""

from __future__ import annotations

import contextlib
import copy
import io
import tempfile
from pathlib import Path

import numpy as np

#: The sources of servos as they are, in order: {name: (the emulator's fields that make it the
#: controller's own or take it away, what would lower it)}.
SOURCES = {
    "motor constant": (
        {"kt_scale": 1.0},
        "each motor's K_t identified (servo identify) and given to the controller",
    ),
    "rotor inertia": ({"rotor_inertia_scale": 1.0}, "the rotors' inertia identified"),
    "friction": (
        {"friction_scale": 0.0},
        "friction the feed-forward knows better (friction_adaptation_s), a drive with less",
    ),
    "current loop": ({"current_lag_scale": 0.0}, "a faster current loop (the servo's)"),
    "backlash": ({"backlash_rad": 0.0}, "a gear without play, or an encoder on the crank"),
    "encoder noise": ({"encoder_noise_counts": 0.0}, "an encoder with less transition noise"),
    "encoder non-linearity": (
        {"encoder_nonlinearity_counts": 0.0},
        "the encoders' harmonic calibrated out",
    ),
    "temperature": ({"temperature_rise_K": 0.0}, "the lengths compensated for temperature"),
    "mass": ({"mass_scale": 1.0}, "the platform's mass measured (payload_scale)"),
    "bus timing": (
        {"return_delay_us": 0.0, "latency_timer_ms": 0.0, "reply_jitter_us": 0.0},
        "Return Delay Time 0 and the adapter's latency timer at 1 ms (docs/hardware_bus.md)",
    ),
}


def _errors(scenario, x0, out, say) -> tuple[np.ndarray, np.ndarray, tuple]:
    """One session of ``scenario`` on its emulator resting at ``x0``, its logs in ``out``:
    (true errors (n, 6), encoder errors (m, 6), the window (start, end) s): the motion's last
    three quarters (its first quarter and the homing before it left out)."""
    from .emulator_process import EMULATED_LOOP_TIMEOUT_S, start_emulator, truth_and_reading
    from .session import run_on_robot

    held: dict = {}
    emulator = start_emulator(scenario, x0)
    # the sessions' deadline-miss lines (on the loop's clock, the emulator's step) kept off the
    # terminal: the budget says how each session ended
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            run = run_on_robot(
                scenario,
                loop_timeout_s=EMULATED_LOOP_TIMEOUT_S,
                out=out,
                progress=False,
                say=lambda line: None,
                before_torque=lambda sd, simulator: held.update(sd=sd),
            )
    finally:
        emulator.close()
    if not run.ok:
        say(f"  the session ended before its end: {run.reason}")
        return np.full((1, 6), np.nan), np.full((1, 6), np.nan), (np.nan, np.nan)
    sd = held["sd"]
    end = float(sd.plan.duration_s)
    window = (end - 0.75 * float(scenario.duration_s), end)
    e_true, e_read = truth_and_reading(
        sd, emulator.truth(), window, loop_clock=emulator.period_s is not None
    )
    return e_true, e_read, window


def emulated_budget(scenario, x0, say=None):
    """The error budget of ``scenario``'s robot on servos as the realistic emulator draws them
    (module docstring), resting at ``x0`` (6,) [rad, m] before each session.

    Returns:
        an :class:`~stewart_drake.analysis.error_budget.ErrorBudget` whose rows are
        :data:`SOURCES` (measured by the emulator; NaN for a row not measured, why in its
        ``assumptions``).
    Raises:
        InvalidConfigError: a scenario without a bus, or whose emulator is not realistic (an
            ideal emulator has no departure to budget).
    """
    from ..base.errors import InvalidConfigError

    if scenario.bus is None:
        raise InvalidConfigError("--budget on the emulator needs a bus scenario (a 'bus:' section)")
    if scenario.emulator.servos != "realistic":
        raise InvalidConfigError(
            "--budget measures servos as they are: emulator.servos must be realistic (ideal "
            "servos are the controller's own model, with no departure to budget)"
        )
    say = say or (lambda line: None)
    loop_clock = scenario.emulator.clock == "loop"
    say(f"every departure, as the seed {scenario.emulator.seed} draws it ...")
    with tempfile.TemporaryDirectory() as out:
        return _budget(scenario, x0, out, say, loop_clock)


def _budget(scenario, x0, out: str, say, loop_clock: bool):
    """:func:`emulated_budget`'s sessions, their logs in ``out``."""
    from ..analysis.error_budget import ErrorBudget, axis_rms, quantization_floor, source_share

    e_true, e_read, window = _errors(scenario, x0, out, say)
    total = axis_rms(e_true)
    rows, without, assumptions = {}, {}, {"measured by": "the realistic bus emulator"}
    for name, (fields, _) in SOURCES.items():
        if name == "bus timing" and loop_clock:
            rows[name] = np.full(6, np.nan)
            assumptions[name] = "not run: on the loop's clock the bus's timing cannot show"
            continue
        variant = copy.deepcopy(scenario)
        for field, value in fields.items():
            setattr(variant.emulator, field, value)
        variant.validate()
        say(f"without its {name} ({', '.join(f'{k} {v:g}' for k, v in fields.items())}) ...")
        without[name] = axis_rms(_errors(variant, x0, out, say)[0])
        rows[name] = source_share(total, without[name])
    return ErrorBudget(
        floor=quantization_floor(scenario),
        total=total,
        encoder_pose=axis_rms(e_read),
        rows=rows,
        without=without,
        window_s=window,
        assumptions=assumptions,
        lowers={name: lower for name, (_, lower) in SOURCES.items()},
        measured="emulated",
    )


def write_budget(budget, out: Path) -> list[Path]:
    """``budget`` as ``out/robot_budget.md`` (its table) and ``.json`` (its record), written
    atomically (the tool's own files); returns their paths."""
    import json

    from ..base.fileio import atomic_write

    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "robot_budget.md", out / "robot_budget.json"]
    text = ("\n".join(budget.lines()) + "\n").encode()
    atomic_write(paths[0], lambda fh: fh.write(text))
    data = json.dumps(budget.record(), indent=1, default=float).encode()
    atomic_write(paths[1], lambda fh: fh.write(data))
    return paths


__all__ = ["SOURCES", "emulated_budget", "write_budget"]
