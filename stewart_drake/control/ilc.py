"""Iterative learning control: a correction of the reference learned from every cycle's error.

:class:`IterativeLearningController` sits in front of any controller of the contract
(:mod:`~.contract`): it reads the reference ``x_d`` and the encoders ``motor_angle`` and outputs
a correction of the reference (pose, rate, acceleration), which the Diagram adds to the ``x_d``
the controller tracks, so what the feedback leaves of one cycle's error is corrected in the
next. Source: "series" ILC, the closed loop as the learning filter (Bristow, Tharayil and
Alleyne, IEEE Control Systems Magazine 26(3), 2006); the phase lead and the zero-phase Q-filter
(Longman, Int. J. Control 73, 2000); the decaying gain (stochastic ILC, Saab, IEEE TAC 46(6),
2001). The update at the end of cycle j (the plain-numpy :func:`cycle_error`,
:func:`repeatability` and :func:`learn`):

    e_j(phi)   = Q[the pose error measured over the cycle (from the encoders)], at phase phi in
                 [0, 1) and led by lead / T_j, divided by the cycle's amplitude scale s_j
    w_j        = repeatability(e_j, e_{j-1})                   (per axis, in [0, 1])
    gamma_j    = gamma n / (n + j)                             (n = gain_decay_cycles)
    L_{j+1}    = Q[L_j - gamma_j w_j e_j]                      (Q: zero-phase low-pass)
    c(t)       = s_k L(phi(t)), with its rate and acceleration, during cycle k

Cycles are aligned by phase and the correction follows each cycle's amplitude. The measured
error is the forward kinematics of the encoder angles minus the reference ("pose"), or the
motor-angle error filtered per motor and mapped to the pose by J^-1 ("motor_angle"). Monitored
bound: a cycle whose measured RMS error (translation or rotation) exceeds ``bound_ratio`` times
that of the cycle its correction learned from, plus ``floor_m``, ``floor_rad``, rolls the
correction back to the best cycle's and halves the gain; after ``max_rollbacks`` learning stops,
the best correction held. Why the weight and the decaying gain, and what the learner costs:
docs/organ_motion.md, "Learning from every cycle".
"""

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.containers import namedview
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_array, as_number, check_int, check_multiple
from ..base.columns import interp_columns
from ..base.errors import InvalidConfigError
from ..base.measures import rms_translation_rotation
from ..robot import forward_kinematics, kinematics
from .contract import LearnerContext

#: What the ``ilc_status`` output holds, in order.
ILC_STATUS_NAMES = (
    "cycle",
    "learned_cycles",
    "gain",
    "rollbacks",
    "stopped",
    "E_trans_m",
    "E_rot_rad",
    "E_ref_trans_m",
    "E_ref_rot_rad",
    "best_score",
    "best_trans_m",
    "best_rot_rad",
    "E0_trans_m",
    "E0_rot_rad",
    "count",
    "rows",
)
IlcStatus = namedview("IlcStatus", ILC_STATUS_NAMES)
_CYCLE = ILC_STATUS_NAMES.index("cycle")
#: Where the learned error comes from (see the module docstring).
ERROR_MODES = ("pose", "motor_angle")


def cycle_error(geometry, theta, x_d, mode: str = "pose") -> np.ndarray:
    """The error a cycle's records measure, (r, 6).

    Args:
        geometry: the robot the learner believes in.
        theta: (r, 6) encoder angles, rad (the motor angles plus the encoders' zero errors,
            which ``geometry.encoder_offsets`` takes back). x_d: (r, 6) the reference poses at
            the same times.
        mode: "pose": forward kinematics of ``theta`` (Newton from ``x_d``) minus ``x_d``
            [rad, m]; "motor_angle": ``theta`` minus the motor angles of ``x_d``, rad.
    Returns:
        (r, 6) errors; rows whose kinematics fail are zero (nothing learned there).
    """
    theta = np.asarray(theta, dtype=float) - geometry.encoder_offsets
    if mode == "motor_angle":
        e = kinematics.ik_unchecked(geometry, x_d)[0]
        e = np.angle(np.exp(1j * (theta - e)))
    else:
        x, converged, _, _ = forward_kinematics.fk_unchecked(
            geometry, theta, x0=x_d, tol=1e-13, max_iter=20
        )
        e = np.where(converged[:, None], x - x_d, 0.0)
    return np.nan_to_num(e, nan=0.0, posinf=0.0, neginf=0.0)


#: Lowest corner of the Q-filter, Hz: below the breathing fundamental (0.1-0.5 Hz) the filter
#: removes the correction it is there to keep (and far below, its design is singular).
MIN_Q_CUTOFF_HZ = 0.1


def q_filter(cutoff_hz: float, sample_period_s: float):
    """(b, a) of the 2nd-order Butterworth low-pass at ``cutoff_hz`` on samples
    ``sample_period_s`` apart (run forwards and backwards by :func:`learn`: zero phase, the
    magnitude squared, -6 dB at the cutoff); None when the cutoff is at or above Nyquist."""
    from scipy.signal import butter

    wn = 2.0 * cutoff_hz * sample_period_s
    return None if wn >= 1.0 else butter(2, wn)


def periodic_filtfilt(ba, y: np.ndarray) -> np.ndarray:
    """Zero-phase filtering of a periodic signal (M, c): the signal is tiled three times,
    filtered forwards and backwards (``scipy.signal.filtfilt``) and the middle period kept, so
    the ends wrap instead of being padded."""
    from scipy.signal import filtfilt

    if ba is None:
        return y
    M = len(y)
    return filtfilt(*ba, np.concatenate([y, y, y]), axis=0, padtype=None)[M : 2 * M]


def resample_to_phase(
    phase: np.ndarray, values: np.ndarray, M: int, shift: float = 0.0
) -> np.ndarray:
    """(M, c) values at the phases m / M + shift (mod 1), linearly interpolated between the
    samples at ``phase`` (r,) in [0, 1) (treated as periodic)."""
    grid = (np.arange(M) / M + shift) % 1.0
    return interp_columns(grid, phase, values, period=1.0)


def learn(learned: np.ndarray, error_phase: np.ndarray, gain: float, ba) -> np.ndarray:
    """One learning step: Q[L - gain e] (the module docstring), (M, 6).

    Args:
        learned: (M, 6) the correction over the phase grid. error_phase: (M, 6) the cycle's
            error on the same grid, already led and scaled. gain: gamma. ba: the Q-filter
            (:func:`q_filter`).
    """
    return periodic_filtfilt(ba, learned - gain * error_phase)


#: Correlations of two cycles' errors up to this are taken for noise (see :func:`repeatability`).
REPEATABILITY_FLOOR = 0.3


def repeatability(e: np.ndarray, e_previous: np.ndarray) -> np.ndarray:
    """(6,) how much of each axis's error repeats from one cycle to the next, in [0, 1]: the
    correlation r of the two cycles' (filtered) errors over the phase grid, mapped to
    (r - f) / (1 - f) clipped to [0, 1] with f = :data:`REPEATABILITY_FLOOR`.

    For errors r + n_j with a repeating part r and independent noise n_j of equal power, the
    correlation is |r|^2 / (|r|^2 + |n|^2): the Wiener weight of the repeating part, so a
    learner that scales each axis's update by it learns what repeats and leaves the rest (the
    encoders' quantization and the stick-slip of the motors at rest, which differ from cycle to
    cycle) instead of accumulating it. Estimated from two cycles of errors low-passed at 25 Hz,
    a correlation scatters by about 0.1 around the true one; below the floor an axis learns
    nothing (on irregular breathing the rotations, all but non-repeating, otherwise gained 4 %
    with learning; docs/organ_motion.md).
    """
    num = np.sum(e * e_previous, axis=0)
    den = np.sqrt(np.sum(e * e, axis=0) * np.sum(e_previous * e_previous, axis=0))
    r = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    return np.clip((r - REPEATABILITY_FLOOR) / (1 - REPEATABILITY_FLOOR), 0.0, 1.0)


class IterativeLearningController(LeafSystem):
    """A correction of the reference learned from every cycle (module docstring).

    Input ports:
        ``x_d`` (18,): the reference the controller would track, [pose, rate, acceleration]
            (rad, m, /s, /s^2), as the reference source gives it to the controller.
        ``motor_angle`` (6,): the encoder angles, rad.
    Output ports:
        ``x_d_correction`` (18,): the correction of the pose, its rate and acceleration, to add
            to ``x_d`` (rad, m, /s, /s^2); computed one control period ahead (a state output:
            no feedthrough).
        ``ilc_status`` (16,): :data:`ILC_STATUS_NAMES` (cycle, cycles learned, gain, rollbacks,
            stopped, the RMS errors in m and rad of the last, the learned-from, the best and
            the first cycle, the best score, record counters).
    Discrete state: the correction (18), the status (16), the current cycle's records (mean
    encoder angles and reference poses, 12 a row, every ``sample_period_s``) and their sum, the
    learned and the best correction and the last filtered error (M x 6 each, the phase grid);
    one periodic update at the control period, the learning once per cycle (its cost:
    docs/organ_motion.md, "Learning from every cycle").

    Args:
        geometry: the robot the learner believes in (for the kinematics of the error).
        driver: the learner's settings (:class:`IlcDriver`), checked here by its own
            :meth:`IlcDriver.validate`; ``driver.period_s`` is the run's business
            (:func:`~stewart_drake.references.motion.learning_cycles`).
        period_s: the control period h, s. offset_s: the controller's sample offset, s.
        cycle_starts: (K + 1,) start of each cycle, s, increasing (the last ends the last
            cycle); nothing is recorded or corrected outside them.
        cycle_scale: (K,) amplitude of each cycle over the mean (default ones).
        floor: (m, rad) the monitored bound's additive floor on the translational and
            rotational RMS errors (the run's: one encoder count at the crank tip).
    Raises:
        InvalidConfigError: a setting out of range, cycles that are not increasing or shorter
            than four records, a record period that is not a whole multiple of period_s.
    """

    #: The name of the status output port and what it holds.
    status_port = "ilc_status"
    status_names = ILC_STATUS_NAMES

    def __init__(
        self,
        geometry,
        driver: "IlcDriver",
        period_s: float,
        offset_s: float,
        cycle_starts,
        cycle_scale=None,
        floor: tuple[float, float] = (5e-6, 5e-5),
    ):
        super().__init__()
        self.geometry = geometry
        self.h = as_number("period_s", period_s, 0.0, 1.0, lo_open=True)
        self.offset = as_number("offset_s", offset_s, 0.0, self.h)
        driver.validate(self.h, prefix="")
        self.driver = driver
        starts, scale = _checked_cycles(cycle_starts, cycle_scale)
        self.R = steps_per_record(driver.sample_period_s, self.h)
        self.step_starts = np.round(starts / self.h).astype(np.int64)
        self.steps = self.step_starts.tolist()  # Python ints for the per-step path
        lengths = np.diff(self.step_starts)
        if lengths.min() < 4 * self.R:
            raise InvalidConfigError(
                f"a cycle of {lengths.min() * self.h:g} s is shorter than "
                f"four records of {driver.sample_period_s:g} s"
            )
        self.scale = scale
        self.scale_list = scale.tolist()
        self.gain0, self.lead = float(driver.gain), float(driver.lead_s)
        self.error = driver.error
        self.bound_ratio = float(driver.bound_ratio)
        self.floor = (as_number("floor_m", floor[0], 0.0), as_number("floor_rad", floor[1], 0.0))
        self.max_rollbacks, self.learn_cycles = int(driver.max_rollbacks), int(driver.learn_cycles)
        self.decay = float(driver.gain_decay_cycles)
        self.M = max(8, int(round(float(np.median(lengths)) / self.R)))
        self.ba = q_filter(float(driver.q_cutoff_hz), driver.sample_period_s)
        self.rows_max = int(math.ceil(lengths.max() / self.R))
        self._mem, size = _memory_layout(self.rows_max, self.M)

        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._motor_angle = self.DeclareVectorInputPort("motor_angle", 6)
        self._c_index = self.DeclareDiscreteState(18)
        status = np.zeros(len(ILC_STATUS_NAMES))
        status[ILC_STATUS_NAMES.index("gain")] = self.gain0
        status[ILC_STATUS_NAMES.index("best_score")] = np.inf
        self._s_index = self.DeclareDiscreteState(status)
        self._m_index = self.DeclareDiscreteState(size)
        self.DeclareStateOutputPort("x_d_correction", self._c_index)
        self.DeclareStateOutputPort("ilc_status", self._s_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.h, offset_sec=self.offset, update=self._Update
        )

    # -- per step ------------------------------------------------------------------------------
    def _Update(self, context, discrete_state):
        n = int(round((context.get_time() - self.offset) / self.h))
        status = discrete_state.get_mutable_value(self._s_index)
        j = int(status[_CYCLE])
        S = self.steps
        if n < S[0] or j >= len(S) - 1:
            return
        memory = discrete_state.get_mutable_value(self._m_index)
        self._Record(context, memory, status, n - S[j], S[j + 1] - S[j])
        if n + 1 == S[j + 1]:
            self._EndCycle(memory, IlcStatus(status), j, S[j + 1] - S[j])
            j += 1
            status[_CYCLE] = j
        self._Correct(memory, n + 1, j, discrete_state.get_mutable_value(self._c_index))

    def _Record(self, context, memory, status, k: int, length: int) -> None:
        """Add this sample to the cycle's records (:func:`add_record`)."""
        add_record(
            self._motor_angle.Eval(context),
            self._x_d.Eval(context),
            memory[self._mem["acc"]],
            memory[self._mem["buffer"]],
            status,
            k,
            length,
            self.R,
        )

    def _Correct(self, memory, n: int, k: int, correction) -> None:
        """The correction at step n of cycle k: s_k L(phi) with its rate and acceleration; zero
        outside the cycles. Python floats on the four table rows around phi (a numpy call per
        (6,) operation would cost more than the arithmetic)."""
        S = self.steps
        if k >= len(S) - 1 or not S[k] <= n < S[k + 1]:
            correction[:] = 0.0
            return
        M, start = self.M, self._mem["learned"].start
        length = S[k + 1] - S[k]
        T = length * self.h
        pos = (n - S[k]) / length * M
        i = int(pos)
        f = pos - i
        r0, r1, r2, r3 = (
            memory[start + 6 * (m % M) : start + 6 * (m % M) + 6].tolist()
            for m in (i - 1, i, i + 1, i + 2)
        )
        s, w = self.scale_list[k], M / T
        out = [s * (b + f * (c - b)) for b, c in zip(r1, r2)]
        out += [
            s * (0.5 * (c - a) + f * (0.5 * (d - b) - 0.5 * (c - a))) * M / T
            for a, b, c, d in zip(r0, r1, r2, r3)
        ]
        out += [
            s * ((c - 2 * b + a) + f * ((d - 2 * c + b) - (c - 2 * b + a))) * w**2
            for a, b, c, d in zip(r0, r1, r2, r3)
        ]
        correction[:] = out

    # -- per cycle -----------------------------------------------------------------------------
    def _EndCycle(self, memory, status, j: int, length: int) -> None:
        """Measure the cycle, check the bound (rollback), learn; see the module docstring."""
        rows = int(status.rows)
        buffer = memory[self._mem["buffer"]].reshape(self.rows_max, 12)[:rows]
        learned = memory[self._mem["learned"]].reshape(self.M, 6)
        best = memory[self._mem["best"]].reshape(self.M, 6)
        e = cycle_error(self.geometry, buffer[:, :6], buffer[:, 6:], self.error)
        e_pose = e if self.error == "pose" else _to_pose(self.geometry, buffer[:, 6:], e)
        E = rms_translation_rotation(e_pose)
        status.E_trans_m, status.E_rot_rad = E
        if j == 0:
            status.E0_trans_m, status.E0_rot_rad = E
        E0 = (max(status.E0_trans_m, 1e-12), max(status.E0_rot_rad, 1e-12))
        score = E[0] / E0[0] + E[1] / E0[1]
        corrected = status.learned_cycles > 0
        over = corrected and (
            E[0] > self.bound_ratio * status.E_ref_trans_m + self.floor[0]
            or E[1] > self.bound_ratio * status.E_ref_rot_rad + self.floor[1]
        )
        if over:  # back to the best cycle's correction; learning goes on at half the gain
            learned[:] = best  # (held, when the rollbacks allowed are spent or learning stopped)
            status.E_ref_trans_m, status.E_ref_rot_rad = status.best_trans_m, status.best_rot_rad
            spend_rollback(status, self.max_rollbacks)
            return
        if score < status.best_score:
            best[:] = learned
            status.best_score = score
            status.best_trans_m, status.best_rot_rad = E
        if status.stopped or (self.learn_cycles and status.learned_cycles >= self.learn_cycles):
            return
        counts = np.minimum(self.R, length - self.R * np.arange(rows))
        phase = (self.R * np.arange(rows) + 0.5 * (counts - 1)) / length
        shift = self.lead / (length * self.h)
        e_phase = resample_to_phase(phase, e, self.M, shift) / self.scale[j]
        if self.error == "motor_angle":  # led in motor space, then mapped to the pose
            e_phase = _to_pose(
                self.geometry, resample_to_phase(phase, buffer[:, 6:], self.M), e_phase
            )
        previous = memory[self._mem["previous"]].reshape(self.M, 6)
        e_phase = periodic_filtfilt(self.ba, e_phase)
        weight = repeatability(e_phase, previous) if status.learned_cycles > 0 else np.ones(6)
        previous[:] = e_phase
        gain = status.gain * (
            self.decay / (self.decay + status.learned_cycles) if self.decay > 0 else 1.0
        )
        learned[:] = learn(learned, weight * e_phase, gain, self.ba)
        status.E_ref_trans_m, status.E_ref_rot_rad = E
        status.learned_cycles += 1


def spend_rollback(status, max_rollbacks: int) -> None:
    """A learner's answer to a cycle over its monitored bound, on its status (in place; the
    caller has already restored the best correction): a rollback, the gain halved, while fewer
    than ``max_rollbacks`` were made; after that learning stops (the count never exceeds its
    limit); nothing more once stopped."""
    if status.stopped:
        return
    if status.rollbacks < max_rollbacks:
        status.rollbacks += 1
        status.gain *= 0.5
    else:
        status.stopped = 1.0


def steps_per_record(sample_period_s: float, period_s: float) -> int:
    """R, the control periods per record of a learner.

    Raises:
        InvalidConfigError: ``sample_period_s`` is not a whole multiple of ``period_s``.
    """
    ratio = sample_period_s / period_s
    if not (ratio >= 1 - 1e-9 and abs(ratio - round(ratio)) < 1e-6):
        raise InvalidConfigError(
            f"sample_period_s ({sample_period_s}) must be a whole "
            f"multiple of the control period ({period_s})"
        )
    return int(round(ratio))


def add_record(
    motor_angle, x_d, acc, rows, status, k: int, length: int, R: int, count=-2, n_rows=-1
) -> None:
    """Add sample k of a stretch of ``length`` samples to a learner's records: the encoder
    angles (6) and the reference pose (the first 6 of ``x_d``) add to the running sum ``acc``
    (12,); every R samples (and at the stretch's end) their mean is stored as one row of
    ``rows`` (flat, 12 per row) and the sum restarts. ``status[count]`` counts the samples in
    the sum, ``status[n_rows]`` the rows stored (in place, like the arrays)."""
    acc[:6] += motor_angle
    acc[6:] += np.asarray(x_d)[:6]
    status[count] += 1
    if (k + 1) % R == 0 or k + 1 == length:
        row = k // R
        rows[12 * row : 12 * row + 12] = acc / status[count]
        acc[:] = 0.0
        status[count] = 0
        status[n_rows] = row + 1


def _checked_cycles(cycle_starts, cycle_scale) -> tuple[np.ndarray, np.ndarray]:
    """(starts (K + 1,) s, scale (K,)) of the learner's cycles: increasing times >= 0 and
    amplitude scales > 0 (default ones)."""
    starts = as_array("cycle_starts", cycle_starts).reshape(-1)
    if starts.size < 2 or np.any(np.diff(starts) <= 0) or starts[0] < 0:
        raise InvalidConfigError("cycle_starts must be at least two increasing times >= 0 s")
    scale = (
        np.ones(starts.size - 1)
        if cycle_scale is None
        else as_array("cycle_scale", cycle_scale, shape=(starts.size - 1,))
    )
    if np.any(scale <= 0):
        raise InvalidConfigError("cycle_scale must be > 0")
    return starts, scale


def _memory_layout(rows: int, M: int) -> tuple[dict, int]:
    """({part: slice}, size) of the learner's memory state: the records of a cycle (rows x 12),
    their running sum (12), the learned and the best correction and the last cycle's filtered
    error (M x 6 each)."""
    parts = {"buffer": rows * 12, "acc": 12, "learned": M * 6, "best": M * 6, "previous": M * 6}
    layout, start = {}, 0
    for name, size in parts.items():
        layout[name] = slice(start, start + size)
        start += size
    return layout, start


def _to_pose(geometry, x_d: np.ndarray, e_theta: np.ndarray) -> np.ndarray:
    """Motor-angle errors (r, 6) as pose errors J(x_d)^-1 e_theta (J = d theta / d x); rows
    where J is singular or x_d unreachable are zero."""
    J = kinematics.jacobian_unchecked(geometry, x_d)
    ok = np.all(np.isfinite(J), axis=(1, 2)) & (
        np.abs(np.linalg.det(np.where(np.isfinite(J), J, 0.0))) > 1e-12
    )
    out = np.zeros_like(e_theta)
    if np.any(ok):
        out[ok] = np.linalg.solve(J[ok], e_theta[ok][..., None])[..., 0]
    return out


# -- the scenario's choice ------------------------------------------------------------------
# Drake's YAML loader reads IlcDriver's field annotations: this module must not use
# ``from __future__ import annotations``.


@dataclass
class IlcDriver:
    """Learning from every cycle: a correction of the reference learned from the previous
    cycles' error (:class:`~stewart_drake.control.ilc.IterativeLearningController`), added to
    the ``x_d`` the controller tracks; needs a reference with cycles (the organ-motion library,
    a trace that repeats) or ``period_s``.

    Attributes:
        gain: learning gain gamma, in (0, 2).
        q_cutoff_hz: corner of the zero-phase Q-filter, Hz, at least :data:`MIN_Q_CUTOFF_HZ`.
        lead_s: phase lead, s (the loop's delay and lag).
        error: "pose" (forward kinematics of the encoders) or "motor_angle" (the motor-angle
            error, mapped to the pose by J^-1).
        sample_period_s: the learner's record period, s (a whole multiple of control_period_s).
        bound_ratio: no cycle's measured RMS error may exceed this times that of the cycle its
            correction learned from, plus one encoder count at the crank tip; over it, the
            correction is rolled back to the best one and the gain halved.
        max_rollbacks: rollbacks allowed; the next cycle over the bound stops learning, the best
            correction held.
        learn_cycles: learn from the first this many cycles, then hold (0: every cycle).
        gain_decay_cycles: n: the j-th update uses gain n / (n + j) (0: a constant gain); the
            correction then averages the cycles' noise out instead of following it.
        period_s: cycles of this period from t = 0 for a reference that has none of its own
            (0: the reference's).
    """

    gain: float = 0.8
    q_cutoff_hz: float = 25.0
    lead_s: float = 0.008
    error: str = "pose"
    sample_period_s: float = 0.004
    bound_ratio: float = 1.2
    max_rollbacks: int = 2
    learn_cycles: int = 0
    gain_decay_cycles: float = 4.0
    period_s: float = 0.0

    def make_learner(self, context: LearnerContext) -> IterativeLearningController:
        """The learner of this choice in a run (:class:`~.contract.LearnerContext`): aligned on
        the reference's cycles, or on ``period_s``'s when given."""
        starts, scale = context.cycles(self.period_s)
        return IterativeLearningController(
            context.geometry,
            self,
            context.period_s,
            context.offset_s,
            starts,
            scale,
            floor=context.floor,
        )

    def validate(self, control_period_s: float, prefix: str = "learning.") -> None:
        """Check every field for a control period of ``control_period_s`` (s): the one check,
        the scenario's (``prefix`` "learning.") and the learner's (no prefix).

        Raises:
            InvalidConfigError: naming the field (``prefix`` + its name) and its range.
        """
        as_number(f"{prefix}gain", self.gain, 0.0, 2.0, lo_open=True)
        if self.gain >= 2.0:
            raise InvalidConfigError(f"{prefix}gain must be below 2, got {self.gain}")
        as_number(f"{prefix}q_cutoff_hz", self.q_cutoff_hz, MIN_Q_CUTOFF_HZ)
        as_number(f"{prefix}lead_s", self.lead_s, 0.0, 1.0)
        if self.error not in ERROR_MODES:
            raise InvalidConfigError(
                f"{prefix}error must be one of {ERROR_MODES}, got {self.error!r}"
            )
        as_number(f"{prefix}sample_period_s", self.sample_period_s, 0.0, 1.0, lo_open=True)
        check_multiple(
            f"{prefix}sample_period_s", self.sample_period_s, "control_period_s", control_period_s
        )
        as_number(f"{prefix}bound_ratio", self.bound_ratio, 1.0, 100.0)
        check_int(f"{prefix}max_rollbacks", self.max_rollbacks, 0, 1000)
        check_int(f"{prefix}learn_cycles", self.learn_cycles, 0, 10**6)
        as_number(f"{prefix}gain_decay_cycles", self.gain_decay_cycles, 0.0, 1e6)
        as_number(f"{prefix}period_s", self.period_s, 0.0, 3600.0)
