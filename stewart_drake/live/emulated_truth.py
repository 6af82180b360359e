"""What the robot did against what its encoders say it did, on the bus emulator: the true pose of
the emulator's plant and the pose the encoders read, each against the reference, beside the
encoders' floor.

On a real robot only the encoders' pose exists (and a tracker's, ``verify``). On the emulator
the plant behind the bus is known at every one of its steps
(:meth:`~.emulator_process.EmulatorProcess.truth`), so a rehearsal can say how far the robot's
own figures are from the motion it really made: :func:`truth_and_reading` pairs them on the
run's clock, :func:`truth_lines` says them.
"""

from __future__ import annotations

import numpy as np

from ..base.measures import peak_per_axis, rms_per_axis

AXES = ("phi", "theta", "psi", "X", "Y", "Z")


def truth_and_reading(sd, truth, window, loop_clock: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(true errors (n, 6), encoder errors (m, 6)) over the run's ``window`` (start, end) s,
    rad and m: the emulator's plant at each of its steps against the reference at the Diagram
    time of its wall-clock time, and the pose the driver measured each period against the
    reference at that period.

    Args:
        sd: the run's :class:`~stewart_drake.run.diagram.StewartDiagram` (its station's driver
            kept every period's reading and wall-clock start).
        truth: (t (k,) perf_counter s, x (k, 12)) of the emulator
            (:meth:`~.emulator_process.EmulatorProcess.truth`).
        window: (start, end) Diagram time, s.
        loop_clock: the emulator on the loop's clock: ``truth``'s times are the loop's since
            its first command, the Diagram's.
    """
    driver = sd.station.driver
    t_periods = driver.readings()[0]
    t_true, x_true = truth
    if loop_clock:
        inside = np.ones(len(t_true), dtype=bool)
        t_run = t_true + t_periods[0]
    else:
        walls = driver.timing.rows()[:, 0]
        n = min(len(walls), len(t_periods))
        inside = (t_true >= walls[0]) & (t_true <= walls[n - 1])
        t_run = np.interp(t_true[inside], walls[:n], t_periods[:n])
    keep = (t_run >= window[0]) & (t_run <= window[1])
    e_true = x_true[inside][keep, :6] - sd.trajectory.evaluate(t_run[keep])[0]
    read = (t_periods >= window[0]) & (t_periods <= window[1])
    e_read = driver.pose_readings()[read] - sd.trajectory.evaluate(t_periods[read])[0]
    return e_true, e_read


def truth_lines(sd, truth, window, floor, emulator=None) -> list[str]:
    """The true and the encoders' RMS (peak) error per axis over ``window``, beside the
    encoders' floor (6,) [rad, m] (:func:`~stewart_drake.analysis.error_budget.
    quantization_floor`), and what the encoders cannot see; mrad and mm. With the
    ``emulator`` (:class:`~.emulator_process.EmulatorProcess`, closed): its clock, and on the
    wall clock how far its plant fell behind (its figures then the emulator's, not a robot's)."""
    loop_clock = emulator is not None and emulator.period_s is not None
    e_true, e_read = truth_and_reading(sd, truth, window, loop_clock)
    if len(e_true) == 0 or len(e_read) == 0:
        return ["the emulator's true pose: no step of its plant inside the measured window"]

    def cells(e):
        return [f"{1e3 * r:.3g} ({1e3 * p:.3g})" for r, p in zip(rms_per_axis(e), peak_per_axis(e))]

    true, read = cells(e_true), cells(e_read)
    lines = [
        f"on the emulator, t in [{window[0]:g}, {window[1]:g}] s, RMS (peak), mrad | mm:",
        f"  {'':>6}  {'true pose':>18}  {'encoders read':>18}  {'floor':>7}",
    ]
    for k, axis in enumerate(AXES):
        lines.append(f"  {axis:>6}  {true[k]:>18}  {read[k]:>18}  {1e3 * floor[k]:7.3g}")
    lines.append(
        "  the true pose is the emulator's plant; the encoders cannot see a crank within its "
        "count (the floor: half a count, uniform, through J^-1) nor what bends between the "
        "cranks and the platform (the emulated robot is rigid)"
    )
    if loop_clock:
        lines.append(
            "  the emulator's plant on the loop's clock: carried one control period at each "
            "command (emulator.clock: loop), immune to this machine's speed"
        )
    elif emulator is not None and emulator.slipped_s > 0:
        lines.append(
            f"  the emulator's plant fell {emulator.slipped_s:.3f} s behind the wall clock "
            "(this machine could not run it in real time): its figures are the emulator's, not "
            "a robot's; emulator.clock: loop carries it on the loop's clock instead"
        )
    return lines
