"""Feed-forward tuning with basis functions: a correction learned as a function of the reference.

The per-cycle learner (:mod:`~.ilc`) learns a correction indexed by the phase of a cycle, so it
needs motion that repeats: what does not repeat per breath (a heartbeat not locked to the
breath, irregular breaths, a drifting baseline, a real patient's trace) is never learned. The
error the feedback leaves is, however, mostly a function of the reference itself: the loop's lag
and its dynamics (the reference's rate, acceleration and jerk) and, at every reversal of a
motor, the transient while its integrator winds through the Coulomb friction (the sign of each
motor's rate, before and after the reversal). :class:`FeedforwardTuningLearner` therefore learns
the correction as a linear combination of such basis functions of the reference (feed-forward
tuning with basis functions: Bolder and Oomen, "Rational basis functions in iterative learning
control", IEEE TCST 23(4), 2015; van Zundert and Oomen, "On inversion-based approaches for
feedforward and ILC", Mechatronics 50, 2018, for varying tasks):

    phi(t)   = [1, x_d_dot (6), x_d_ddot (6), x_d_dddot (6),
                tanh(omega_i(t - l) / omega_0) for the six motors i and lags l in LAGS_S]
                                                  (p = 19 + 6 len(LAGS_S) basis functions)
    c(t)     = -Q[phi](t) theta                   (6 pose axes; Q: the zero-phase Q-filter)

with omega = J(x_d) x_d_dot the motor rates the reference asks for. Because the basis is a
function of the reference and not of time, what is learned on one stretch of motion applies to
any other, one the learner has not seen included: a model learned on one trace can start the
next (:func:`save_learned`, :func:`load_learned`).

The run is cut into stretches of ``stretch_s`` (not cycles: nothing needs to repeat). At the end
of stretch k, with e the error the encoders measured over it (forward kinematics of the recorded
angles minus the reference, averaged over each record of ``sample_period_s``) and Phi the
filtered basis averaged over the same records:

    A_k         = beta A_{k-1} + Phi^T Phi          (beta = 1 - 1 / memory_stretches)
    theta_{k+1} = theta_k + gamma (A_k + lambda_k I)^-1 Phi^T e

(a recursive least-squares step on the error: with the closed loop's complementary sensitivity
about one below its bandwidth, e = d - Phi theta_k, so theta converges to the least-squares fit
of the error the loop would leave uncorrected, d; the memory averages the noise of the encoders
out over the stretches; lambda_k = ``ridge`` trace(A_k) / p keeps a basis function the motion
does not excite at zero). The basis functions are scaled by their RMS over the first stretch, so
the ridge weighs them alike.

Monitored bound: the error the stretch would have had without the correction is estimated as
d = e + Phi theta_k; a stretch run with a correction whose measured RMS error (translation or
rotation) exceeds ``bound_ratio`` times that estimate plus one encoder count at the crank tip
rolls theta back to the best one so far (lowest error over estimate) and halves the gain; after
``max_rollbacks`` rollbacks the next one stops learning (the count never exceeds its limit).
"""

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.common.containers import namedview
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_number, check_int, check_multiple
from ..base.errors import CorruptFileError, InvalidConfigError
from ..robot import kinematics
from .contract import LearnerContext
from .ilc import (
    MIN_Q_CUTOFF_HZ,
    add_record,
    cycle_error,
    rms_pose_error,
    spend_rollback,
    steps_per_record,
)

#: Lags of the motors' rate signs in the basis, s (positive: the past; negative: the future,
#: which the feed-forward knows): the friction transient after a reversal lasts ~0.1 s.
LAGS_S = (-0.02, 0.0, 0.005, 0.01, 0.02, 0.04, 0.08, 0.16)
#: What the ``learning_status`` output holds, in order.
FF_STATUS_NAMES = (
    "stretch",
    "updates",
    "gain",
    "rollbacks",
    "stopped",
    "E_trans_m",
    "E_rot_rad",
    "D_trans_m",
    "D_rot_rad",
    "best_score",
    "count",
    "rows",
)
FeedforwardStatus = namedview("FeedforwardStatus", FF_STATUS_NAMES)
_STRETCH = FF_STATUS_NAMES.index("stretch")
#: Version of the learned-model file (:func:`save_learned`).
LEARNED_FORMAT = 1
_KIND = "learned feed-forward model (.npz)"
#: Largest learned-model file, bytes, on disk and after decompression: the weights are
#: p x 6 float64 (a few kB), so anything near this bound is not one.
MAX_LEARNED_BYTES = 1e6


def basis_size(lags=LAGS_S) -> int:
    """p: the number of basis functions (module docstring)."""
    return 19 + 6 * len(lags)


def reference_basis(
    geometry, pose, rate, acceleration, h: float, rate_scale: float, lags=LAGS_S
) -> np.ndarray:
    """The basis functions phi of the module docstring on an even grid of step ``h``, (n, p).

    Args:
        geometry: the robot (for the motors' rates J(x_d) x_d_dot).
        pose, rate, acceleration: (n, 6) the reference on the grid, rad, m and their rates.
        h: the grid's step, s. rate_scale: omega_0, rad/s (the width of the smooth sign).
        lags: the signs' lags, s (rounded to the grid).
    Returns:
        (n, p); the lagged signs hold their first (last) value beyond the grid's ends, so the
        grid should extend max(lags) before and -min(lags) after the times used.
    """
    pose = np.asarray(pose, dtype=float)
    rate = np.asarray(rate, dtype=float)
    acceleration = np.asarray(acceleration, dtype=float)
    n = len(pose)
    jerk = np.gradient(acceleration, h, axis=0) if n > 1 else np.zeros_like(acceleration)
    J = kinematics.jacobian_unchecked(geometry, pose)
    omega = np.nan_to_num(np.einsum("nij,nj->ni", J, rate), nan=0.0, posinf=0.0, neginf=0.0)
    sign = np.tanh(omega / rate_scale)
    parts = [np.ones((n, 1)), rate, acceleration, jerk]
    for lag in lags:
        m = int(round(lag / h))
        z = np.empty_like(sign)
        if m > 0:
            z[m:], z[:m] = sign[:-m], sign[0]
        elif m < 0:
            z[:m], z[m:] = sign[-m:], sign[-1]
        else:
            z[:] = sign
        parts.append(z)
    return np.concatenate(parts, axis=1)


class FeedforwardTuningLearner(LeafSystem):
    """A correction of the reference learned as a function of the reference (module docstring).

    Input ports:
        ``x_d`` (18,): the reference the controller would track (rad, m, /s, /s^2).
        ``motor_angle`` (6,): the encoder angles, rad.
    Output ports:
        ``x_d_correction`` (18,): the correction of the pose, its rate and acceleration, to add
            to ``x_d``; computed one control period ahead (a state output: no feedthrough).
        ``learning_status`` (12,): :data:`FF_STATUS_NAMES`: the stretch, updates made, the gain,
            rollbacks, stopped (0/1), the last stretch's measured RMS errors (m, rad) and the
            estimate of those without the correction, the best score, record counters.
        ``theta`` (p x 6,): the learned weights, in SI units of the basis (row-major (p, 6)).
    Discrete state: the correction (18), the status, theta, the best theta and the information
    matrix A (p x p, scaled basis), and the current stretch's records (rows of mean encoder
    angles and reference poses, 12 each). The basis and the correction over a stretch are a
    function of the reference, the stretch and theta only; they are computed once per stretch
    (vectorized) and kept as a cache of that function, not as state.

    Args:
        geometry: the robot the learner believes in.
        driver: the learner's settings (:class:`FeedforwardTuning`: stretch, gain, memory,
            ridge, Q-filter, the smooth signs' width, record period, bound, rollbacks, the model
            to start from, whether to learn), checked here by its own
            :meth:`FeedforwardTuning.validate` (its messages name each field);
            ``driver.learn`` False holds the model (the bound is still monitored).
        reference: the reference (an object with ``evaluate(t)`` -> pose, rate, acceleration,
            each (n, 6); an ``end_time`` if it has one).
        period_s: the control period h, s. offset_s: the controller's sample offset, s.
        duration_s: the run's length, s.
        floor: (m, rad) the monitored bound's additive floor on the translational and
            rotational RMS errors (the run's: one encoder count at the crank tip).
        theta0: (p, 6) initial weights in SI units (a model learned before); None reads
            ``driver.learned_from`` (:func:`load_learned`), or starts from zeros without one.
    Raises:
        InvalidConfigError: a setting out of range, a stretch shorter than four records.
        CorruptFileError: ``driver.learned_from`` is not a model of this basis.
    """

    #: The name of the status output port and what it holds.
    status_port = "learning_status"
    status_names = FF_STATUS_NAMES

    def __init__(
        self,
        geometry,
        driver: "FeedforwardTuning",
        reference,
        period_s: float,
        offset_s: float,
        duration_s: float,
        floor: tuple[float, float] = (5e-6, 5e-5),
        theta0=None,
    ):
        super().__init__()
        self.geometry, self.reference = geometry, reference
        self.h = as_number("period_s", period_s, 0.0, 1.0, lo_open=True)
        self.offset = as_number("offset_s", offset_s, 0.0, self.h)
        duration = as_number("duration_s", duration_s, 0.0, lo_open=True)
        driver.validate(self.h, prefix="", has_model=theta0 is not None)
        self.driver = driver
        self.R = steps_per_record(driver.sample_period_s, self.h)
        L = int(round(float(driver.stretch_s) / self.h))
        if L < 4 * self.R:
            raise InvalidConfigError(
                f"stretch_s ({float(driver.stretch_s):g} s) is shorter than four records of "
                f"{driver.sample_period_s:g} s"
            )
        n_steps = int(math.floor(duration / self.h + 1e-9)) + 1
        self.steps = list(range(0, n_steps, L)) + [n_steps]
        self.L = L
        self.gain0 = float(driver.gain)
        self.beta = 1.0 - 1.0 / float(driver.memory_stretches)
        self.ridge, self.q_cutoff = float(driver.ridge), float(driver.q_cutoff_hz)
        self.rate_scale = float(driver.rate_scale_rad_s)
        self.bound_ratio = float(driver.bound_ratio)
        self.floor = (as_number("floor_m", floor[0], 0.0), as_number("floor_rad", floor[1], 0.0))
        self.max_rollbacks = int(driver.max_rollbacks)
        self.learn = bool(driver.learn)
        self.p = basis_size()
        if theta0 is None and driver.learned_from:
            theta0 = load_learned(driver.learned_from)
        theta0 = np.zeros((self.p, 6)) if theta0 is None else np.asarray(theta0, dtype=float)
        if theta0.shape != (self.p, 6) or not np.all(np.isfinite(theta0)):
            raise InvalidConfigError(
                f"theta0 must be ({self.p}, 6) finite weights, got shape {theta0.shape}"
            )
        self.rows_max = int(math.ceil(L / self.R))
        self._pad = max(LAGS_S) + 0.2  # the lags and the Q-filter's transient
        self._lead = -min(LAGS_S) + 0.2
        self._basis_cache: dict = {}
        self._table_cache: tuple | None = None
        # the basis scales: RMS over the first stretch (a basis function at rest scales to one)
        phi0 = self._basis(0)
        scale = np.sqrt(np.mean(phi0**2, axis=0))
        self.scale = np.where(scale > 1e-12, scale, 1.0)

        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._motor_angle = self.DeclareVectorInputPort("motor_angle", 6)
        self._c_index = self.DeclareDiscreteState(18)
        status = np.zeros(len(FF_STATUS_NAMES))
        status[FF_STATUS_NAMES.index("gain")] = self.gain0
        status[FF_STATUS_NAMES.index("best_score")] = np.inf
        self._s_index = self.DeclareDiscreteState(status)
        self._t_index = self.DeclareDiscreteState(theta0.reshape(-1))
        self._b_index = self.DeclareDiscreteState(theta0.reshape(-1))
        self._a_index = self.DeclareDiscreteState(self.p * self.p)
        self._r_index = self.DeclareDiscreteState(self.rows_max * 12 + 12)
        self.DeclareStateOutputPort("x_d_correction", self._c_index)
        self.DeclareStateOutputPort("learning_status", self._s_index)
        self.DeclareStateOutputPort("theta", self._t_index)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self.h, offset_sec=self.offset, update=self._Update
        )

    # -- the basis and the correction of a stretch (pure functions of k and theta) -------------
    def _basis(self, k: int) -> np.ndarray:
        """(S_{k+1} - S_k, p) the Q-filtered basis at the steps of stretch k (cached)."""
        if k in self._basis_cache:
            return self._basis_cache[k]
        from scipy.signal import butter, filtfilt

        S0, S1 = self.steps[k], self.steps[k + 1]
        before, after = int(round(self._pad / self.h)), int(round(self._lead / self.h))
        n = np.arange(S0 - before, S1 + after)
        t = self.offset + n * self.h
        end = getattr(self.reference, "end_time", None)
        t = np.clip(t, 0.0, end if end is not None else np.inf)
        pose, rate, acc = (np.asarray(a, dtype=float) for a in self.reference.evaluate(t))
        rate = np.where((n * self.h + self.offset < 0)[:, None], 0.0, rate)
        phi = reference_basis(self.geometry, pose, rate, acc, self.h, self.rate_scale)
        wn = 2.0 * self.q_cutoff * self.h
        if wn < 1.0:
            phi = filtfilt(*butter(2, wn), phi, axis=0)
        phi = phi[before : before + S1 - S0]
        self._basis_cache = {key: v for key, v in self._basis_cache.items() if key >= k - 1}
        self._basis_cache[k] = phi
        return phi

    def _table(self, k: int, theta: np.ndarray) -> np.ndarray:
        """(S_{k+1} - S_k, 18) the correction c = -Q[phi] theta over stretch k, with its rate
        and acceleration (central differences of the filtered correction)."""
        cached = self._table_cache
        if cached is not None and cached[0] == k and np.array_equal(cached[1], theta):
            return cached[2]
        c = -self._basis(k) @ theta
        if len(c) > 2:
            rate = np.gradient(c, self.h, axis=0)
            acc = np.gradient(rate, self.h, axis=0)
        else:
            rate = acc = np.zeros_like(c)
        table = np.concatenate([c, rate, acc], axis=1)
        self._table_cache = (k, theta.copy(), table)
        return table

    # -- per step ------------------------------------------------------------------------------
    def _Update(self, context, discrete_state):
        n = int(round((context.get_time() - self.offset) / self.h))
        status = discrete_state.get_mutable_value(self._s_index)
        k = int(status[_STRETCH])
        S = self.steps
        if k >= len(S) - 1:
            return
        records = discrete_state.get_mutable_value(self._r_index)
        self._Record(context, records, status, n - S[k], S[k + 1] - S[k])
        theta = discrete_state.get_mutable_value(self._t_index)
        if n + 1 == S[k + 1]:
            self._EndStretch(discrete_state, records, FeedforwardStatus(status), k)
            k += 1
            status[_STRETCH] = k
        correction = discrete_state.get_mutable_value(self._c_index)
        if k < len(S) - 1 and S[k] <= n + 1 < S[k + 1]:
            correction[:] = self._table(k, theta.reshape(self.p, 6))[n + 1 - S[k]]
        else:
            correction[:] = 0.0

    def _Record(self, context, records, status, i: int, length: int) -> None:
        """Add this sample to the stretch's records (:func:`~.ilc.add_record`)."""
        add_record(
            self._motor_angle.Eval(context),
            self._x_d.Eval(context),
            records[-12:],
            records[:-12],
            status,
            i,
            length,
            self.R,
        )

    # -- per stretch ---------------------------------------------------------------------------
    def _EndStretch(self, discrete_state, records, status, k: int) -> None:
        """Measure the stretch, check the bound (rollback), learn (module docstring)."""
        rows = int(status.rows)
        buffer = records[: rows * 12].reshape(rows, 12)
        theta_v = discrete_state.get_mutable_value(self._t_index)
        best_v = discrete_state.get_mutable_value(self._b_index)
        theta, best = theta_v.reshape(self.p, 6), best_v.reshape(self.p, 6)
        e = cycle_error(self.geometry, buffer[:, :6], buffer[:, 6:], "pose")
        phi = self._basis(k)
        length = len(phi)
        counts = np.minimum(self.R, length - self.R * np.arange(rows))
        idx = np.repeat(np.arange(rows), counts)
        phi_r = np.zeros((rows, self.p))
        np.add.at(phi_r, idx, phi)
        phi_r /= counts[:, None]
        d = e + phi_r @ theta  # the stretch's error had it run uncorrected (loop ~ 1)
        E, D = rms_pose_error(e), rms_pose_error(d)
        status.E_trans_m, status.E_rot_rad = E
        status.D_trans_m, status.D_rot_rad = D
        corrected = bool(np.any(theta != 0.0))
        if corrected and (
            E[0] > self.bound_ratio * D[0] + self.floor[0]
            or E[1] > self.bound_ratio * D[1] + self.floor[1]
        ):
            theta[:] = best
            spend_rollback(status, self.max_rollbacks)
            return
        score = E[0] / max(D[0], 1e-12) + E[1] / max(D[1], 1e-12)
        if corrected and score < status.best_score:
            best[:] = theta
            status.best_score = score
        if status.stopped or not self.learn:
            return
        A = discrete_state.get_mutable_value(self._a_index).reshape(self.p, self.p)
        phi_s = phi_r / self.scale
        A[:] = self.beta * A + phi_s.T @ phi_s
        lam = self.ridge * np.trace(A) / self.p
        step = np.linalg.solve(A + lam * np.eye(self.p), phi_s.T @ e)
        theta += status.gain * step / self.scale[:, None]
        status.updates += 1


# -- the learned model as a file ------------------------------------------------------------


def save_learned(path, theta, geometry_name: str = "") -> Path:
    """Write learned weights (p, 6) to an .npz (numbers only) that :func:`load_learned` reads,
    with the basis it belongs to (the lags, its size and the file format)."""
    from ..base.fileio import atomic_write

    theta = np.asarray(theta, dtype=float).reshape(basis_size(), 6)
    path = Path(path)

    def write(f):
        np.savez(
            f,
            format=np.int64(LEARNED_FORMAT),
            theta=theta,
            lags_s=np.asarray(LAGS_S),
            geometry=np.asarray(geometry_name),
        )

    atomic_write(path, write)
    return path


def load_learned(path) -> np.ndarray:
    """The (p, 6) weights of a file :func:`save_learned` wrote, read through
    :class:`~stewart_drake.base.fileio.CheckedNpz` (a regular file of at most
    :data:`MAX_LEARNED_BYTES`, each entry's header checked before it is loaded, no pickles).

    Returns:
        (p, 6) float64 weights theta, p = :func:`basis_size`.
    Raises:
        CorruptFileError: naming the file: not a readable ``.npz`` (a FIFO, too large, an
            entry whose header claims more than it holds); ``format`` not one integer;
            ``theta`` or ``lags_s`` not real numbers (text, complex); a model of another basis;
            weights not all finite.
        OSError: the file cannot be read (missing, permissions).
    """
    from ..base.fileio import CheckedNpz

    path = Path(path)
    data = CheckedNpz(path, _KIND, "write it with --save-learned", MAX_LEARNED_BYTES)
    fmt = data.integer("format")
    theta, lags = data.array("theta"), data.array("lags_s")
    same_basis = lags.shape == (len(LAGS_S),) and np.allclose(lags, LAGS_S)
    if fmt != LEARNED_FORMAT or not same_basis or theta.shape != (basis_size(), 6):
        raise CorruptFileError(
            path,
            _KIND,
            f"a model of another basis (format {fmt}, weights {theta.shape})",
            "learn it again with this version",
        )
    if not np.all(np.isfinite(theta)):
        raise CorruptFileError(path, _KIND, "the weights are not all finite")
    return theta


# -- the scenario's choice ------------------------------------------------------------------
# Drake's YAML loader reads FeedforwardTuning's field annotations: this module must not use
# ``from __future__ import annotations``.


@dataclass
class FeedforwardTuning:
    """Learning a feed-forward correction as a function of the reference
    (:class:`FeedforwardTuningLearner`): for motion that does not repeat (recorded traces,
    irregular breathing, a heartbeat not locked to the breath), and for a model learned on one
    motion to start another.

    Attributes:
        stretch_s: length of a learning stretch, s.
        gain: gamma, in (0, 2).
        memory_stretches: stretches the information remembers (>= 1).
        ridge: the ridge's fraction of the information's mean diagonal.
        q_cutoff_hz: the Q-filter's corner, Hz.
        rate_scale_rad_s: width of the motors' smooth rate sign, rad/s.
        sample_period_s: the record period, s (a whole multiple of control_period_s).
        bound_ratio: no stretch run with a correction may exceed this times the estimate of its
            error without it, plus one encoder count at the crank tip.
        max_rollbacks: rollbacks allowed; the next stretch over the bound stops learning.
        learned_from: an .npz a previous run saved (:func:`save_learned`) to start from ("":
            from zero); read as numbers only.
        learn: False holds the model of ``learned_from`` without learning.
    """

    stretch_s: float = 5.0
    gain: float = 1.0
    memory_stretches: float = 10.0
    ridge: float = 1e-3
    q_cutoff_hz: float = 25.0
    rate_scale_rad_s: float = 0.002
    sample_period_s: float = 0.004
    bound_ratio: float = 1.2
    max_rollbacks: int = 2
    learned_from: str = ""
    learn: bool = True

    def make_learner(self, context: LearnerContext) -> FeedforwardTuningLearner:
        """The learner of this choice in a run (:class:`~.contract.LearnerContext`): the
        correction as a function of the reference."""
        return FeedforwardTuningLearner(
            context.geometry,
            self,
            context.reference,
            context.period_s,
            context.offset_s,
            context.duration_s,
            floor=context.floor,
        )

    def validate(
        self, control_period_s: float, prefix: str = "learning.", *, has_model: bool = False
    ) -> None:
        """Check every field for a control period of ``control_period_s`` (s): the one check,
        the scenario's (``prefix`` "learning.") and the learner's (no prefix, ``has_model``
        when it is given a model in memory, which ``learn: false`` may hold instead of
        ``learned_from``'s).

        Raises:
            InvalidConfigError: naming the field (``prefix`` + its name) and its range.
        """
        as_number(f"{prefix}stretch_s", self.stretch_s, 0.0, 3600.0, lo_open=True)
        as_number(f"{prefix}gain", self.gain, 0.0, 2.0, lo_open=True)
        if self.gain >= 2.0:
            raise InvalidConfigError(f"{prefix}gain must be below 2, got {self.gain}")
        as_number(f"{prefix}memory_stretches", self.memory_stretches, 1.0, 1e6)
        as_number(f"{prefix}ridge", self.ridge, 0.0, 1e3)
        as_number(f"{prefix}q_cutoff_hz", self.q_cutoff_hz, MIN_Q_CUTOFF_HZ)
        as_number(f"{prefix}rate_scale_rad_s", self.rate_scale_rad_s, 0.0, 10.0, lo_open=True)
        as_number(f"{prefix}sample_period_s", self.sample_period_s, 0.0, 1.0, lo_open=True)
        check_multiple(
            f"{prefix}sample_period_s", self.sample_period_s, "control_period_s", control_period_s
        )
        as_number(f"{prefix}bound_ratio", self.bound_ratio, 1.0, 100.0)
        check_int(f"{prefix}max_rollbacks", self.max_rollbacks, 0, 1000)
        if not isinstance(self.learned_from, str):
            raise InvalidConfigError(f"{prefix}learned_from must be a path, got a value")
        if not self.learn and not (self.learned_from or has_model):
            raise InvalidConfigError(f"{prefix}learn: false needs {prefix}learned_from")
