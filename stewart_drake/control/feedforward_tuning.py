"""Feed-forward tuning with basis functions: a correction learned as a function of the reference.

:class:`FeedforwardTuningLearner` learns a correction of the reference as a linear combination
of basis functions of the reference, so it needs no motion that repeats (the per-cycle learner,
:mod:`~.ilc`, does) and a model learned on one trace can start the next
(:func:`~.feedforward_basis.save_learned`, :func:`~.feedforward_basis.load_learned`). Source:
feed-forward tuning with basis functions, Bolder and Oomen, "Rational basis functions in
iterative learning control", IEEE TCST 23(4), 2015; van Zundert and Oomen, "On inversion-based
approaches for feedforward and ILC", Mechatronics 50, 2018, for varying tasks:

    phi(t)   = [1, x_d_dot (6), x_d_ddot (6), x_d_dddot (6),
                tanh(omega_i(t - l) / omega_0) for the six motors i and lags l in LAGS_S]
                                                  (p = 19 + 6 len(LAGS_S) basis functions)
    c(t)     = -Q[phi](t) theta                   (6 pose axes; Q: the zero-phase Q-filter)

with omega = J(x_d) x_d_dot the motor rates the reference asks for. The run is cut into
stretches of ``stretch_s``; at the end of stretch k, with e the error the encoders measured over
it (forward kinematics of the recorded angles minus the reference, averaged over each record of
``sample_period_s``) and Phi the filtered basis averaged over the same records:

    A_k         = beta A_{k-1} + Phi^T Phi          (beta = 1 - 1 / memory_stretches)
    theta_{k+1} = theta_k + gamma (A_k + lambda_k I)^-1 Phi^T e

with lambda_k = ``ridge`` trace(A_k) / p and the basis functions scaled by their RMS over the
first stretch. A correction is kept only while it is estimated better than none (``bound_ratio``
at a stretch's end, :data:`MID_STRETCH_RATIO` every ``check_period_s``, ``max_rollbacks``), a
step is taken only where it generalises, outliers (``outlier_mad``, ``outlier_guard_s``) are
left out of the fit and the correction is not extrapolated: docs/organ_motion.md, "Learning
motion that does not repeat" and "Never worse than no correction". The last stretch's measured
and estimated errors and the counts of fallbacks and skipped updates are in the
``learning_status`` output.
"""

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.containers import namedview
from pydrake.systems.framework import LeafSystem

from ..base.checks import as_number, check_int, check_multiple
from ..base.errors import InvalidConfigError, StewartError
from ..base.measures import rms_per_axis, rms_translation_rotation
from ..robot.forward_kinematics import encoder_pose_noise
from .contract import LearnerContext
from .feedforward_basis import (
    LAGS_S,
    basis_size,
    load_learned,
    reference_basis,
)
from .ilc import (
    MIN_Q_CUTOFF_HZ,
    add_record,
    cycle_error,
    spend_rollback,
    steps_per_record,
)

#: Within a stretch, a correction is dropped at once over this ratio (module docstring).
MID_STRETCH_RATIO = 1.5
#: The basis functions that can extrapolate (the reference's rate, acceleration and jerk: the
#: columns after the constant); the constant and the smooth signs are bounded by one.
_DYNAMIC = slice(1, 19)

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
    "skipped",
    "outliers",
    "dropped",
    "count",
    "rows",
)
FeedforwardStatus = namedview("FeedforwardStatus", FF_STATUS_NAMES)
_STRETCH = FF_STATUS_NAMES.index("stretch")


class FeedforwardTuningLearner(LeafSystem):
    """A correction of the reference learned as a function of the reference (module docstring).

    Input ports:
        ``x_d`` (18,): the reference the controller would track (rad, m, /s, /s^2).
        ``motor_angle`` (6,): the encoder angles, rad.
    Output ports:
        ``x_d_correction`` (18,): the correction of the pose, its rate and acceleration, to add
            to ``x_d``; computed one control period ahead (a state output: no feedthrough).
        ``learning_status`` (14,): :data:`FF_STATUS_NAMES` (the stretch, updates, gain,
            fallbacks to no correction, stopped, the last stretch's measured and estimated
            uncorrected RMS errors in m and rad, skipped updates, outliers, record counters).
        ``theta`` (p x 6,): the learned weights, in SI units of the basis (row-major (p, 6)).
    Discrete state: the correction (18), the status, theta, the information matrix A (p x p,
    scaled basis), each scaled basis function's trusted range (p) and the stretch's records
    (mean encoder angles and reference poses, 12 a row); the basis is a per-stretch cache.

    Args:
        geometry: the robot the learner believes in.
        driver: the learner's settings (:class:`FeedforwardTuning`), checked here by its own
            :meth:`FeedforwardTuning.validate`; ``driver.learn`` False holds the model (the
            bound is still monitored).
        reference: the reference (an object with ``evaluate(t)`` -> pose, rate, acceleration,
            each (n, 6); an ``end_time`` if it has one).
        period_s: the control period h, s. offset_s: the controller's sample offset, s.
        duration_s: the run's length, s.
        floor: (m, rad) one encoder count at the crank tip as a translation and a rotation
            (kept for the status).
        theta0: (p, 6) initial weights in SI units, trusted over every range; None reads
            ``driver.learned_from`` (:func:`~.feedforward_basis.load_learned`), else zeros.
        quantum_rad: one encoder count, rad (0: exact angles): the noise below which an update
            is skipped.
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
        quantum_rad: float = 0.0,
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
        self.memory = float(driver.memory_stretches)
        self.beta = 1.0 - 1.0 / self.memory
        self.ridge, self.q_cutoff = float(driver.ridge), float(driver.q_cutoff_hz)
        self.rate_scale = float(driver.rate_scale_rad_s)
        self.bound_ratio = float(driver.bound_ratio)
        self.floor = (as_number("floor_m", floor[0], 0.0), as_number("floor_rad", floor[1], 0.0))
        self.max_rollbacks = int(driver.max_rollbacks)
        self.quantum = as_number("quantum_rad", quantum_rad, 0.0)
        self.outlier_mad = float(driver.outlier_mad)
        self.outlier_guard = int(math.ceil(float(driver.outlier_guard_s) / driver.sample_period_s))
        self.check_rows = max(1, int(round(float(driver.check_period_s) / driver.sample_period_s)))
        self.learn = bool(driver.learn)
        self.p = basis_size()
        if theta0 is None and driver.learned_from:
            theta0 = load_learned(driver.learned_from)
        trusted = np.full(self.p + 6, np.inf if theta0 is not None else 0.0)
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
        scale = rms_per_axis(phi0)
        self.scale = np.where(scale > 1e-12, scale, 1.0)

        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._motor_angle = self.DeclareVectorInputPort("motor_angle", 6)
        self._c_index = self.DeclareDiscreteState(18)
        status = np.zeros(len(FF_STATUS_NAMES))
        status[FF_STATUS_NAMES.index("gain")] = self.gain0
        self._s_index = self.DeclareDiscreteState(status)
        self._t_index = self.DeclareDiscreteState(theta0.reshape(-1))
        self._w_index = self.DeclareDiscreteState(trusted)
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

    def _trust(self, phi: np.ndarray, trusted: np.ndarray) -> np.ndarray:
        """(n,) w = clip(2 - r, 0, 1): r the largest ratio of a scaled dynamic basis function
        to the largest magnitude fitted (``trusted``, p) at each sample of ``phi`` (n, p)."""
        ratio = np.abs(phi[:, _DYNAMIC] / self.scale[_DYNAMIC])
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(ratio > 0.0, ratio / trusted[_DYNAMIC], 0.0)
        return np.clip(2.0 - np.max(ratio, axis=1), 0.0, 1.0)

    def _table(self, k: int, theta: np.ndarray, trusted: np.ndarray) -> np.ndarray:
        """(S_{k+1} - S_k, 18) the correction c = -w Q[phi] theta over stretch k (w: the trust,
        :meth:`_trust`), with its rate and acceleration (central differences)."""
        cached = self._table_cache
        if (
            cached is not None
            and cached[0] == k
            and np.array_equal(cached[1], theta)
            and np.array_equal(cached[3], trusted)
        ):
            return cached[2]
        phi = self._basis(k)
        c_max = trusted[self.p :]
        c = np.clip(-(self._trust(phi, trusted[: self.p])[:, None] * (phi @ theta)), -c_max, c_max)
        if len(c) > 2:
            rate = np.gradient(c, self.h, axis=0)
            acc = np.gradient(rate, self.h, axis=0)
        else:
            rate = acc = np.zeros_like(c)
        table = np.concatenate([c, rate, acc], axis=1)
        self._table_cache = (k, theta.copy(), table, trusted.copy())
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
        elif (n + 1 - S[k]) % (self.R * self.check_rows) == 0 and np.any(theta != 0.0):
            self._Check(discrete_state, records, FeedforwardStatus(status), k)
        correction = discrete_state.get_mutable_value(self._c_index)
        if k < len(S) - 1 and S[k] <= n + 1 < S[k + 1]:
            trusted = discrete_state.get_value(self._w_index)
            correction[:] = self._table(k, theta.reshape(self.p, 6), trusted)[n + 1 - S[k]]
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
    def _measured(self, discrete_state, records, status, k: int) -> tuple:
        """The stretch's records so far: (reference poses (r, 6), e (r, 6) the error the
        encoders measured, d (r, 6) the estimate without the correction, the basis (n, p) at
        its samples, each sample's record (n,), the basis averaged per record (r, p))."""
        rows = int(status.rows)
        buffer = records[: rows * 12].reshape(rows, 12)
        theta = discrete_state.get_value(self._t_index).reshape(self.p, 6)
        trusted = discrete_state.get_value(self._w_index)
        e = cycle_error(self.geometry, buffer[:, :6], buffer[:, 6:], "pose")
        phi = self._basis(k)[: min(len(self._basis(k)), rows * self.R)]
        idx = np.minimum(np.arange(len(phi)) // self.R, rows - 1)
        counts = np.bincount(idx, minlength=rows)
        phi_r = np.zeros((rows, self.p))
        np.add.at(phi_r, idx, phi)
        phi_r /= counts[:, None]
        applied = self._per_record(phi, idx, rows, theta, trusted)
        return buffer[:, 6:], e, e + applied, phi, idx, phi_r

    def _worse(self, status, e: np.ndarray, d: np.ndarray, ratio: float | None = None) -> bool:
        """Whether the correction did worse than none over the records (the measured RMS ``e``
        above ``bound_ratio`` times the estimate ``d`` in translation or rotation); the status
        gets both."""
        E, D = rms_translation_rotation(e), rms_translation_rotation(d)
        status.E_trans_m, status.E_rot_rad = E
        status.D_trans_m, status.D_rot_rad = D
        r = self.bound_ratio if ratio is None else ratio
        return E[0] > r * D[0] or E[1] > r * D[1]

    def _fall_back(self, discrete_state, status) -> None:
        """No correction from the next step: theta, the information and the trusted ranges
        cleared, a fallback spent (:func:`~.ilc.spend_rollback`)."""
        discrete_state.get_mutable_value(self._t_index)[:] = 0.0
        discrete_state.get_mutable_value(self._a_index)[:] = 0.0
        discrete_state.get_mutable_value(self._w_index)[:] = 0.0
        spend_rollback(status, self.max_rollbacks)
        status.dropped = 1.0

    def _Check(self, discrete_state, records, status, k: int) -> None:
        """Within a stretch, every ``check_period_s``: fall back to no correction as soon as the
        stretch so far did worse than none."""
        _, e, d, *_ = self._measured(discrete_state, records, status, k)
        if self._worse(status, e, d, MID_STRETCH_RATIO):
            self._fall_back(discrete_state, status)

    def _EndStretch(self, discrete_state, records, status, k: int) -> None:
        """Measure the stretch, fall back to no correction when it did worse than none, learn
        from the stretch's stationary records when the step is worth it (module docstring)."""
        poses, e, d, phi, idx, phi_r = self._measured(discrete_state, records, status, k)
        theta = discrete_state.get_mutable_value(self._t_index).reshape(self.p, 6)
        if status.dropped:  # part of the stretch ran with the correction dropped: not learned
            status.dropped = 0.0
            return
        if np.any(theta != 0.0) and self._worse(status, e, d):
            self._fall_back(discrete_state, status)
            status.dropped = 0.0
            return
        if not np.any(theta != 0.0):
            self._worse(status, e, d)  # the status's figures (equal: nothing applied)
        if status.stopped or not self.learn:
            return
        rows = len(e)
        trusted = discrete_state.get_mutable_value(self._w_index)
        A = discrete_state.get_mutable_value(self._a_index).reshape(self.p, self.p)
        resolution = self._resolution(poses)
        keep = np.ones(rows, dtype=bool)
        for _ in range(2):  # fit, leave out what the fit does not explain, fit again
            phi_s = phi_r[keep] / self.scale
            A_new = self.beta * A + phi_s.T @ phi_s
            lam = self.ridge * np.trace(A_new) / self.p
            step = np.linalg.solve(A_new + lam * np.eye(self.p), phi_s.T @ e[keep])
            if keep.all():
                keep = self._stationary(e - (phi_r / self.scale) @ step, resolution)
                status.outliers += rows - int(np.sum(keep))
                if np.sum(keep) < self.p:
                    return
                if keep.all():
                    break
        theta_new = theta + status.gain * step / self.scale[:, None]
        trusted_new = self._ranges(trusted, phi, idx, d, keep)
        noise = self._fit_noise(resolution, phi_s.shape[0] * min(k + 1, self.memory))
        # In sample, over the stretch's stationary records: worth more than the noise, and
        # better than none.
        c_r = self._per_record(phi, idx, rows, theta_new, trusted_new)
        now, new, none = (rms_translation_rotation(v[keep]) for v in (e, d - c_r, d))
        worth = any(now[i] - new[i] > noise[i] for i in (0, 1))
        better = new[0] <= none[0] and new[1] <= none[1]
        if worth and better:  # out of sample: fitted on the first half, tried on the second
            first = keep & (np.arange(rows) < rows // 2)
            second = keep & ~first
            if np.sum(first) >= self.p and np.sum(second) > 0:
                phi_1 = phi_r[first] / self.scale
                A_1 = self.beta * A + phi_1.T @ phi_1
                lam_1 = self.ridge * np.trace(A_1) / self.p
                step_1 = np.linalg.solve(A_1 + lam_1 * np.eye(self.p), phi_1.T @ e[first])
                theta_1 = theta + status.gain * step_1 / self.scale[:, None]
                trusted_1 = self._ranges(trusted, phi, idx, d, first)
                c_1 = self._per_record(phi, idx, rows, theta_1, trusted_1)
                held, held_none = (
                    rms_translation_rotation((d - c_1)[second]),
                    rms_translation_rotation(d[second]),
                )
                better = held[0] <= held_none[0] and held[1] <= held_none[1]
        if not (worth and better):
            status.skipped += 1
            A[:] = A_new  # what was seen is remembered; the weights and their ranges stay
            return
        A[:] = A_new
        trusted[:] = trusted_new
        theta[:] = theta_new
        status.updates += 1

    def _ranges(self, trusted, phi, idx, d, keep) -> np.ndarray:
        """``trusted`` (p + 6,) widened by the records ``keep`` (r,) bool: the largest magnitude
        of each scaled basis function at their samples, and of each axis of their error
        without the correction ``d`` (r, 6) (the largest correction allowed)."""
        out = trusted.copy()
        inside = np.isin(idx, np.flatnonzero(keep))
        out[: self.p] = np.maximum(trusted[: self.p], np.max(np.abs(phi[inside] / self.scale), 0))
        out[self.p :] = np.maximum(trusted[self.p :], np.max(np.abs(d[keep]), axis=0))
        return out

    def _per_record(self, phi, idx, rows: int, theta, trusted) -> np.ndarray:
        """(r, 6) the correction of ``theta`` with the ranges ``trusted``, averaged over each
        record (as applied: weighted by the trust, clipped to the largest error fitted)."""
        c = self._trust(phi, trusted[: self.p])[:, None] * (phi @ theta)
        c = np.clip(c, -trusted[self.p :], trusted[self.p :])
        c_r = np.zeros((rows, 6))
        np.add.at(c_r, idx, c)
        return c_r / np.bincount(idx, minlength=rows)[:, None]

    def _stationary(self, residual: np.ndarray, resolution: tuple[float, float]) -> np.ndarray:
        """(r,) bool: the records whose ``residual`` (r, 6), the error the fit leaves, is within
        ``outlier_mad`` robust standard deviations of its median on every axis (1.4826 x the
        median absolute deviation, at least the encoders' ``resolution`` (m, rad) per axis), and
        not within ``outlier_guard_s`` of one that is not."""
        centre = np.median(residual, axis=0)
        sigma = 1.4826 * np.median(np.abs(residual - centre), axis=0)
        least = np.repeat([resolution[1], resolution[0]], 3) / math.sqrt(3.0)
        sigma = np.maximum(sigma, np.maximum(least, 1e-12))
        out = np.any(np.abs(residual - centre) > self.outlier_mad * sigma, axis=1)
        if np.any(out) and self.outlier_guard > 0:
            g = self.outlier_guard
            out = np.convolve(out.astype(float), np.ones(2 * g + 1), mode="same") > 0
        return ~out

    def _resolution(self, poses: np.ndarray) -> tuple[float, float]:
        """(m, rad) the measured pose's resolution at the stretch's reference ``poses``
        (:func:`~stewart_drake.robot.forward_kinematics.encoder_pose_noise`; zeros for exact
        angles or a pose where it is not defined)."""
        if self.quantum <= 0.0 or len(poses) == 0:
            return (0.0, 0.0)
        try:
            return encoder_pose_noise(self.geometry, poses, self.quantum, max_poses=50)
        except StewartError:  # a singular or unreachable pose
            return (0.0, 0.0)

    def _fit_noise(self, resolution: tuple[float, float], n: float) -> tuple[float, float]:
        """(m, rad) the RMS the encoders' rounding leaves in a fitted correction: the measured
        pose's ``resolution`` times sqrt(p / n), for the ``n`` records the information holds."""
        factor = math.sqrt(self.p / max(n, 1.0))
        return (resolution[0] * factor, resolution[1] * factor)


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
        bound_ratio: a stretch run with a correction whose error exceeds this times the estimate of
            its error without it falls back to no correction (1: never worse than none).
        max_rollbacks: fallbacks to no correction allowed; the next one stops learning.
        outlier_mad: a record whose uncorrected error is further than this many robust
            standard deviations from the stretch's median is left out of the fit.
        outlier_guard_s: the records this close to an outlier are left out too, s.
        check_period_s: within a stretch, how often the correction is checked against none
            (one over ``MID_STRETCH_RATIO`` times none is dropped at once), s.
        learned_from: an .npz a previous run saved (:func:`~.feedforward_basis.save_learned`)
            to start from ("": from zero); read as numbers only.
        learn: False holds the model of ``learned_from`` without learning.
    """

    stretch_s: float = 5.0
    gain: float = 1.0
    memory_stretches: float = 10.0
    ridge: float = 1e-3
    q_cutoff_hz: float = 25.0
    rate_scale_rad_s: float = 0.002
    sample_period_s: float = 0.004
    bound_ratio: float = 1.01
    max_rollbacks: int = 2
    outlier_mad: float = 10.0
    outlier_guard_s: float = 0.1
    check_period_s: float = 0.5
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
            quantum_rad=context.encoder_quantum_rad,
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
        as_number(f"{prefix}outlier_mad", self.outlier_mad, 1.0, 1e6)
        as_number(f"{prefix}outlier_guard_s", self.outlier_guard_s, 0.0, 60.0)
        as_number(f"{prefix}check_period_s", self.check_period_s, 0.0, 3600.0, lo_open=True)
        if not isinstance(self.learned_from, str):
            raise InvalidConfigError(f"{prefix}learned_from must be a path, got a value")
        if not self.learn and not (self.learned_from or has_model):
            raise InvalidConfigError(f"{prefix}learn: false needs {prefix}learned_from")
