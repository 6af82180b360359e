"""The ``stewart-drake reproduce`` run: a motion checked against the robot, shrunk on request
(:func:`scale_to_fit`), run on the robot as built with or without learning (:func:`run`) and
measured (:func:`~.fidelity.fidelity`): :func:`reproduce` gives a :class:`Reproduction`, which
:mod:`~.fidelity_report` writes up.

:func:`reproduce` checks a motion against the robot (the one validator,
:func:`~stewart_drake.run.plan.check_reference`), shrinks it on request, runs the robot as built
with or without learning, and measures it from the plant's poses (the true platform), never the
controller's estimate.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.errors import InvalidConfigError
from ..references.motion import Reference
from .fidelity import fidelity, startup_figures

if TYPE_CHECKING:  # for the annotation only: the functions import experiments when they run
    from ..run.result import RunResult

# -- a reproduction ----------------------------------------------------------------------------


@dataclass
class Reproduction:
    """A motion reproduced by the robot and measured (:func:`reproduce`).

    Attributes:
        name: the motion's name. reference: the reference run (scaled when it had to be).
        scale: the scale applied to fit the robot (1: as given).
        result: the :class:`~.simulate.RunResult` (true pose, reference, torques).
        cycle_starts: (K + 1,) the cycles of the run, s (empty for a reference without).
        learn_cycles: cycles learned from (0: no learning).
        fidelity: :func:`fidelity` over the evaluation window (the last ``eval_cycles``).
        learner: (n, k) the learner's status log, or None; its columns are
            ``learner_names`` (:data:`~stewart_drake.control.ilc.ILC_STATUS_NAMES` or
            :data:`~stewart_drake.control.feedforward_tuning.FF_STATUS_NAMES`).
        learned: (p, 6) the weights a feed-forward learner ended with (for
            :func:`~stewart_drake.control.feedforward_basis.save_learned`), or None.
        check: the validator's summary of the reference. wall_s: wall time of the run, s.
        learning: how the run learned, in words (:func:`learning_words`).
        learned_from: the model file a feed-forward learner started from or held, or "".
        startup: the run before the measured window, t = 0 to its start: {"window_s": (0,
            start), "rms_translation_m", "rms_rotation_rad", "peak_translation_m",
            "peak_rotation_rad"} from the true platform pose (zeros when the window starts at 0).
        geometry: the robot the run was made on. plan: the run's
            :class:`~stewart_drake.run.plan.RunPlan` (its scenario with the run's duration and
            learner), or None. encoder_quantum_rad: one count of its
            encoders, rad (0: the angles are read exactly); for :meth:`resolution`.
        compared: what :attr:`fidelity` compares, in words, for the verdict's line ("": the
            robot's true pose against the reference it ran, :meth:`comparison`).
    """

    name: str
    reference: Reference
    scale: float
    result: RunResult
    cycle_starts: np.ndarray
    learn_cycles: int
    fidelity: dict
    learner: np.ndarray | None = None
    learner_names: tuple = ()
    learned: np.ndarray | None = None
    check: str = ""
    wall_s: float = 0.0
    notes: list = field(default_factory=list)
    learning: str = ""
    learned_from: str = ""
    startup: dict = field(default_factory=dict)
    geometry: Any = None
    plan: Any = None
    encoder_quantum_rad: float = 0.0
    compared: str = ""

    def comparison(self) -> str:
        """What :attr:`fidelity` compares, in words, as a verdict names it
        (:func:`~.fidelity.verdict`): :attr:`compared`, else "the robot's true pose against the
        reference (<name>)"."""
        return self.compared or f"the robot's true pose against the reference ({self.name})"

    def resolution(self) -> tuple[float, float]:
        """(m, rad) the RMS error the encoders' rounding puts in the measured pose at the
        reference's poses in the measured window
        (:func:`~stewart_drake.robot.forward_kinematics.encoder_pose_noise`); (0, 0) for a
        robot that reads its angles exactly, NaN where a pose of the window is singular."""
        from ..base.errors import StewartError
        from ..robot.forward_kinematics import encoder_pose_noise

        w0, w1 = self.fidelity["window_s"]
        r = self.result
        poses = np.asarray(r.x_d[(r.t >= w0) & (r.t <= w1), :6], dtype=float)
        if self.encoder_quantum_rad <= 0.0 or self.geometry is None or len(poses) == 0:
            return (0.0, 0.0)
        try:
            return encoder_pose_noise(self.geometry, poses, self.encoder_quantum_rad, max_poses=200)
        except StewartError:
            return (float("nan"), float("nan"))


def learning_words(learning, learn_cycles: int = 0) -> str:
    """How a run with the scenario's ``learning`` learns, in words for a report: "no learning",
    "learning from N cycles, then held" (per cycle), "feed-forward learned over the run",
    "feed-forward started from <file>, learning over the run" or "feed-forward <file> held,
    not learning"."""
    from ..control.feedforward_tuning import FeedforwardTuning

    if isinstance(learning, FeedforwardTuning):
        model = Path(learning.learned_from).name
        if not learning.learned_from:
            return "feed-forward learned over the run"
        if learning.learn:
            return f"feed-forward started from {model}, learning over the run"
        return f"feed-forward {model} held, not learning"
    if learn_cycles:
        return f"learning from {learn_cycles} cycles, then held"
    return "no learning"


def scale_to_fit(scenario, reference: Reference, tol: float = 0.005) -> tuple[Reference, float]:
    """The largest scale in (0, 1] at which ``reference``, shrunk about its centre
    (:class:`~stewart_drake.references.organ.combinators.ScaledReference`), passes every check of
    :func:`~stewart_drake.run.plan.check_reference` on the
    scenario's robot (reach, joint limits, singularity, clearance, motor torque and speed), by
    bisection to within ``tol``.

    Returns:
        (reference, scale): the reference itself and 1.0 when it passes as it is.
    Raises:
        InvalidConfigError: not even a scale of ``tol`` passes (the centre itself is refused:
            move it).
    """
    from ..references.organ.combinators import ScaledReference
    from ..run.plan import check_reference, make_plan

    plan = make_plan(scenario, with_reference=False)

    def fits(s: float) -> bool:
        candidate = reference if s == 1.0 else ScaledReference(reference, s)
        try:
            report = check_reference(plan, candidate, raise_refused=False)
        except Exception:  # noqa: BLE001 - unreachable poses raise even when reporting
            return False
        return report.ok

    if fits(1.0):
        return reference, 1.0
    lo, hi = 0.0, 1.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    if lo < tol:
        raise InvalidConfigError(
            f"{getattr(reference, 'name', 'the reference')} cannot be "
            f"scaled to fit: even at {tol:g} of its size a check refuses "
            f"it; move its centre"
        )
    return ScaledReference(reference, lo), lo


_fit = scale_to_fit  # reproduce's argument of that name is a flag


def run(
    scenario,
    reference: Reference | None,
    progress: bool = False,
    desc: str = "simulating",
    report=None,
):
    """Simulate ``scenario`` on ``reference`` (checked first unless its check's ``report`` is
    given, guarded; None: a checked plan's own, not checked again): (:class:`~.simulate.RunResult`,
    the learner's status log (n + 1, k) or None, wall s, the learned weights (p, 6) of a
    feed-forward learner at the end or None).

    The learner's log has a row at each of the result's ``t_state`` (every
    ``state_log_period_s``) and ends with its state at the end of the run (the loggers' last
    sample is one period earlier: the update of a cycle's last sample would otherwise be
    missing)."""
    from ..run.simulate import run_experiment

    # A reproduction reads the pose, the torques and the status, not the controller's integral
    # or error estimate: a 25-minute trace is 72 MB lighter without them.
    result = run_experiment(
        scenario, progress, reference=reference, report=report, controller_logs=False, desc=desc
    )
    return result, result.learner_status, result.metrics["wall_s"], result.learned


def run_cycles(reference: Reference, learn_cycles: int, eval_cycles: int) -> int:
    """Cycles a reproduction runs: the learned ones (or one to settle without learning) and
    then the evaluated ones."""
    return max(learn_cycles, 1) + eval_cycles


def _check_counts(learn_cycles, eval_cycles) -> None:
    """Refuse cycle counts that are not integers >= 0, and no cycle to measure."""
    for name, value in (("learn_cycles", learn_cycles), ("eval_cycles", eval_cycles)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise InvalidConfigError(f"{name} must be an integer >= 0, got {value!r}")
    if eval_cycles < 1:
        raise InvalidConfigError("eval_cycles must be at least 1")


#: The longest run of a library motion reproduce makes, s: its cycles are counted over this
#: time.
MAX_REPRODUCE_S = 3600.0


def _reference_starts(reference: Reference, learn_cycles: int) -> np.ndarray:
    """(K + 1,) the starts of the reference's cycles over its length (or
    :data:`MAX_REPRODUCE_S`), s; empty for a reference without cycles, which only a run without
    learning accepts."""
    from ..references.motion import reference_cycles

    end = getattr(reference, "end_time", None)
    try:
        starts, _ = reference_cycles(reference, end if end is not None else MAX_REPRODUCE_S)
    except InvalidConfigError:
        if learn_cycles:
            raise
        starts = np.zeros(0)
    return starts


def _duration(
    scenario, reference, starts, learn_cycles: int, eval_cycles: int, duration_s: float | None
) -> tuple[float, bool]:
    """(the run's length, s: the trace's length (at most), :func:`run_cycles` cycles or
    ``duration_s``, else the scenario's; True when a recorded trace runs whole (without
    learning))."""
    name = getattr(reference, "name", "reference")
    end = getattr(reference, "end_time", None)
    total = run_cycles(reference, learn_cycles, eval_cycles)
    whole = end is not None and not learn_cycles  # a recorded trace: all of it
    if not whole and starts.size > 0 and duration_s is not None:
        raise InvalidConfigError(
            f"{name} runs whole cycles ({total} asked for): set the number of cycles, not a "
            f"duration (a duration is for a trace run whole or a reference without cycles)"
        )
    if not whole and end is None and 0 < starts.size <= total:
        raise InvalidConfigError(
            f"{total} cycles of {name} asked for; it gives {starts.size - 1} whole cycles in "
            f"{MAX_REPRODUCE_S:g} s, the longest run reproduce makes: ask for fewer cycles"
        )
    if whole and end is not None:
        return float(min(duration_s or end, end)), whole
    if starts.size > total:
        return float(starts[total]), whole
    if learn_cycles and starts.size <= learn_cycles + 1:
        raise InvalidConfigError(
            f"{name} holds {max(starts.size - 1, 0)} cycles: too few to "
            f"learn from {learn_cycles} and measure one more"
        )
    return float(duration_s or end or scenario.duration_s), whole


def _learning(scenario, learn_cycles: int, feedforward=None):
    """The run's learner: ``feedforward`` when given, else a copy of the scenario's
    ``learning`` (or the default :class:`~stewart_drake.control.ilc.IlcDriver`) learning from
    ``learn_cycles`` cycles, or None (0: no learning). The scenario's own is not changed."""
    from ..control.ilc import IlcDriver

    if feedforward is not None:
        return feedforward
    if learn_cycles:
        return replace(scenario.learning or IlcDriver(), learn_cycles=learn_cycles)
    return None


def _status_names(learning) -> tuple:
    """The columns of the status log of the learner ``learning`` chooses (() for none)."""
    from ..control.feedforward_tuning import FF_STATUS_NAMES, FeedforwardTuning
    from ..control.ilc import ILC_STATUS_NAMES

    if learning is None:
        return ()
    return FF_STATUS_NAMES if isinstance(learning, FeedforwardTuning) else ILC_STATUS_NAMES


def _measured_window(starts, duration: float, whole: bool, eval_cycles: int) -> tuple[float, float]:
    """(start, end) of the window measured, s: after a whole trace's first cycle (or tenth), or
    the last ``eval_cycles`` cycles (the last nine tenths of a run without them)."""
    if whole:  # after the first cycle (or tenth) to the end
        return (starts[1] if starts.size > 2 else 0.1 * duration, duration)
    if starts.size > eval_cycles:
        return (starts[-eval_cycles - 1], starts[-1])
    return (0.1 * duration, duration)


def _harmonic_frequencies(reference: Reference) -> dict:
    """{"breathing": Hz, "cardiac": Hz}: the fundamentals whose harmonics :func:`fidelity`
    analyses, those of a reference that repeats ({} for one that does not)."""
    repeats = getattr(reference, "repeat_period_s", None) is not None
    frequencies = getattr(reference, "frequencies_hz", None)
    return frequencies() if repeats and callable(frequencies) else {}


def _measure(result, reference, starts, duration: float, whole: bool, eval_cycles: int) -> dict:
    """:func:`~.fidelity.fidelity` of a run over its measured window
    (:func:`_measured_window`), with the reference's harmonics (:func:`_harmonic_frequencies`)
    and its cycles ``starts`` (s)."""
    window = _measured_window(starts, duration, whole, eval_cycles)
    freq = _harmonic_frequencies(reference)
    return fidelity(result.t, result.x, result.x_d, window, freq, starts)


def _startup(result, window: tuple[float, float]) -> dict:
    """The figures of the run before its measured ``window`` (s): RMS and peak error of the
    true platform pose over [0, window start) (:attr:`Reproduction.startup`,
    :func:`~.fidelity.startup_figures`)."""
    return startup_figures(result.t, result.x, result.x_d, window[0])


def _learning_record(learning, learn_cycles: int) -> dict:
    """What a :class:`Reproduction` records of the scenario's ``learning``: the columns of its
    status log, how it learned in words, the model file it started from."""
    return {
        "learner_names": _status_names(learning),
        "learning": learning_words(learning, learn_cycles),
        "learned_from": str(getattr(learning, "learned_from", "") or ""),
    }


def reproduce(
    scenario,
    reference=None,
    learn_cycles: int = 0,
    eval_cycles: int = 2,
    scale_to_fit: bool = False,
    duration_s: float | None = None,
    progress: bool = False,
    feedforward=None,
    on_checked=None,
) -> Reproduction:
    """Check a motion against the robot, run it, measure it.

    The run lasts :func:`run_cycles` cycles, measured over the last ``eval_cycles``; a trace (a
    reference with an ``end_time``) runs whole (or ``duration_s``), measured after its first
    cycle (or first tenth). The one validator checks the whole run first
    (:func:`~stewart_drake.run.plan.check_reference`); a refused reference raises, or is shrunk
    by :func:`scale_to_fit`. ``learn_cycles`` learns (the scenario's ``learning`` or
    :class:`~stewart_drake.run.scenario.IlcDriver`) then holds the correction; ``feedforward``
    learns over the whole run instead (any motion; docs/organ_motion.md).

    Args:
        scenario: the robot and its controller (not changed: the run's duration and learner
            are set on a copy, :attr:`Reproduction.plan`'s scenario).
        reference: the motion (default the scenario's).
        learn_cycles: cycles to learn from (0: none). eval_cycles: cycles measured after.
        scale_to_fit: shrink a refused motion instead of refusing it.
        duration_s: length of a run on a reference without cycles, s.
        feedforward: a :class:`~stewart_drake.control.feedforward_tuning.FeedforwardTuning`
            to learn with, or None.
        on_checked: called (no arguments) once every check passed, before the run is built.
    Returns:
        :class:`Reproduction`.
    Raises:
        UnreachablePoseError, JointLimitError, SingularPoseError, InterferenceError,
        MotorLimitError: the validator's refusal (without ``scale_to_fit``).
        InvalidConfigError: learning on a reference that does not repeat, a bad count, a run
            that needs more memory than the machine has (checked before the reference is).
        SimulationDivergedError: the guard stopped the run.
    """
    from ..references.trajectories import as_trajectory
    from ..run.memory import check_run_memory
    from ..run.plan import checked_plan, make_plan, run_reference

    _check_counts(learn_cycles, eval_cycles)
    reference = as_trajectory(reference) if reference is not None else run_reference(scenario)
    name = getattr(reference, "name", "reference")
    starts = _reference_starts(reference, learn_cycles if feedforward is None else 0)
    duration, whole = _duration(scenario, reference, starts, learn_cycles, eval_cycles, duration_s)
    scenario = replace(
        scenario, duration_s=duration, learning=_learning(scenario, learn_cycles, feedforward)
    )
    check_run_memory(scenario)  # before the reference is checked at every control period
    plan = make_plan(scenario, reference=reference)  # validated once, here
    reference, scale = _fit(plan, reference) if scale_to_fit else (reference, 1.0)
    plan = checked_plan(plan, reference=reference, progress=progress)  # the run's, checked once
    if on_checked is not None:
        on_checked()
    result, learner, wall, learned = run(plan, None, progress, f"reproducing {name}")
    starts = starts[starts <= scenario.duration_s + 1e-9]
    window = _measured_window(starts, scenario.duration_s, whole, eval_cycles)
    quantum = 0.0 if scenario.hardware is None else scenario.hardware.encoders.quantum_rad
    return Reproduction(
        name=name,
        reference=reference,
        scale=scale,
        result=result,
        cycle_starts=starts,
        learn_cycles=learn_cycles,
        fidelity=_measure(result, reference, starts, scenario.duration_s, whole, eval_cycles),
        learner=learner,
        learned=learned,
        check=plan.report.summary() if plan.report is not None else "",
        wall_s=wall,
        startup=_startup(result, window),
        geometry=plan.geometry,
        plan=plan,
        encoder_quantum_rad=quantum,
        **_learning_record(scenario.learning, learn_cycles),
    )


def measured_against(rep: Reproduction, reference: Reference, compared: str) -> Reproduction:
    """``rep``'s run measured against another ``reference``, over the same window: the robot's
    true pose (the plant's) against, e.g., the true motion that the reference it ran was
    predicting (``reproduce --stream``), where ``rep``'s own figures are against what the robot
    was given. A verdict on ``rep`` judges the controller; on this, the motion reproduced.

    Args:
        rep: a :class:`Reproduction`. reference: a :class:`~.motion.Reference` defined over
            the run (``evaluate(t)`` -> pose, rate, acceleration, each (n, 6) rad and m).
        compared: what the figures compare, in words, for the verdict's line
            (:attr:`Reproduction.compared`).
    Returns:
        a copy of ``rep`` whose ``name``, ``reference``, ``result.x_d`` ((N, 18) ``reference``'s
        pose, rate and acceleration at ``result.t``, in the log's dtype), ``cycle_starts``
        (``reference``'s cycles within the run), ``fidelity`` (:func:`~.fidelity.fidelity` over
        ``rep``'s window, with ``reference``'s harmonics), ``startup`` (before that window) and
        ``compared`` are ``reference``'s; the run, its learner, its check and its scale are
        ``rep``'s.
    Raises:
        InvalidConfigError: as :func:`~.fidelity.fidelity`.
    """
    r = rep.result
    t = np.asarray(r.t, dtype=float)
    x_d = np.concatenate([np.reshape(a, (t.size, 6)) for a in reference.evaluate(t)], axis=1)
    result = replace(r, x_d=x_d.astype(np.asarray(r.x_d).dtype))
    starts = _reference_starts(reference, 0)
    starts = starts[starts <= t[-1] + 1e-9]
    window = (float(rep.fidelity["window_s"][0]), float(rep.fidelity["window_s"][1]))
    freq = _harmonic_frequencies(reference)
    return replace(
        rep,
        name=getattr(reference, "name", rep.name),
        reference=reference,
        result=result,
        cycle_starts=starts,
        fidelity=fidelity(t, result.x, result.x_d, window, freq, starts),
        startup=_startup(result, window),
        compared=compared,
    )


__all__ = [
    "Reproduction",
    "learning_words",
    "scale_to_fit",
    "run",
    "run_cycles",
    "MAX_REPRODUCE_S",
    "reproduce",
    "measured_against",
]
