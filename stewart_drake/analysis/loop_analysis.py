"""The loop as a control engineer sees it: margins, sensitivity peaks, bandwidth and the phase lag
at the breathing and cardiac frequencies, from the linear models of a scenario's robot and LQI at
a pose (:mod:`~stewart_drake.control.linear_model`).

Per pose axis the loop is broken at the plant input in task forces with the other five axes in
service (loop at a time, :func:`~stewart_drake.control.linear_model.loop_at_a_time`): L_i(z),
its gain margin (upper, and lower when the loop is conditionally stable: the LQI's integral
makes L ~ 1/s^3 at low frequency, whose phase passes -180 deg from above, so the gain may also
fall by a factor before the loop goes unstable), phase margin, delay margin, and the peaks of
S_i = 1 / (1 + L_i) and T_i = L_i / (1 + L_i). The tracking response x_i / x_d,i is the whole
closed loop's, with the reference's rate x_d_dot = i omega x_d as the controller reads it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.tables import markdown_lines
from ..control.linear_model import (
    AXES,
    DiscreteModel,
    closed_loop,
    loop_at_a_time,
    lqi_model,
    open_loop,
    plant_model,
)
from ..control.lqi.driver import LqiDriver
from ..robot import kinematics, statics
from ..robot.geometry import X_HOME
from ..run import metrics
from ..run.plan import RunPlan, make_plan
from ..run.scenario import Scenario

#: The frequencies a motion phantom must track: breathing and heartbeat, Hz.
BREATHING_HZ, CARDIAC_HZ = 0.25, 1.2
#: The analysis grid's lowest frequency, Hz, and points per decade up to the Nyquist frequency.
F_MIN_HZ, POINTS_PER_DECADE = 0.01, 400


@dataclass(frozen=True)
class LoopModels:
    """The linear models of a scenario's robot and LQI at one pose.

    Attributes:
        x0: (6,) the pose [rad, m]. h: the control period, s. J: (6, 6) d theta / d x at x0.
        plant, controller, closed, open: :func:`~.linear_model.plant_model`,
            :func:`~.linear_model.lqi_model`, :func:`~.linear_model.closed_loop`,
            :func:`~.linear_model.open_loop`.
    """

    x0: np.ndarray
    h: float
    J: np.ndarray
    plant: DiscreteModel
    controller: DiscreteModel
    closed: DiscreteModel
    open: DiscreteModel

    @property
    def spectral_radius(self) -> float:
        """Largest |eigenvalue| of the closed loop: below 1 iff it is stable (the margins of an
        unstable loop describe nothing)."""
        return float(np.abs(np.linalg.eigvals(self.closed.A)).max())


def loop_models(
    scenario: Scenario | RunPlan, x0=None, integrator: str = "sap", driver: LqiDriver | None = None
) -> LoopModels:
    """The linear models of ``scenario``'s robot and LQI at pose x0 (default home) at rest.

    The plant is the robot simulated (``plant_geometry``, with a payload the controller does not
    know), with the scenario's servo (viscous friction, current loop) and computation delay; the
    controller is the LQI the scenario configures (``driver`` overrides it: another weight),
    designed on the robot it believes in, with the encoders' rate filter on the robot as built.

    Raises:
        InvalidConfigError: the scenario's controller is not an LQI (or a tuner drives its
            weights: give ``driver``), or its plant step differs from its control period.
    """
    plan = scenario if isinstance(scenario, RunPlan) else make_plan(scenario, with_reference=False)
    s = plan.scenario
    if driver is None:
        if not isinstance(s.controller, LqiDriver):
            raise InvalidConfigError(
                f"the loop analysis needs an LQI controller (controller: !LqiDriver), got "
                f"{type(s.controller).__name__}"
            )
        driver = s.controller
    if abs(plan.plant_time_step_s - plan.control_period_s) > 1e-12:
        raise InvalidConfigError(
            f"the loop analysis needs plant.time_step = control_period_s, got "
            f"{plan.plant_time_step_s:g} s and {plan.control_period_s:g} s"
        )
    x0 = X_HOME.copy() if x0 is None else np.asarray(x0, dtype=float)
    h, servo, d = plan.control_period_s, plan.servo, plan.delay_periods
    plant = plant_model(
        plan.plant_geometry,
        x0,
        h,
        delay_periods=d,
        viscous_damping=0.0 if servo is None else servo.viscous_damping,
        current_time_constant_s=0.0 if servo is None else servo.current_time_constant_s,
        integrator=integrator,
    )
    cutoff = None if s.hardware is None else s.hardware.estimator.rate_cutoff_hz
    controller = lqi_model(plan.geometry, x0, h, driver, delay_periods=d, rate_cutoff_hz=cutoff)
    J = kinematics.jacobian(plan.plant_geometry, x0)
    return LoopModels(
        x0=x0,
        h=h,
        J=J,
        plant=plant,
        controller=controller,
        closed=closed_loop(plant, controller, J),
        open=open_loop(plant, controller, J),
    )


def frequency_grid(h: float, f_min: float = F_MIN_HZ) -> np.ndarray:
    """Log-spaced frequencies from f_min to just below the Nyquist frequency 1 / (2 h), Hz."""
    f_max = 0.999 / (2 * h)
    n = int(POINTS_PER_DECADE * np.log10(f_max / f_min)) + 1
    return np.geomspace(f_min, f_max, n)


def tracking_response(models: LoopModels, f_hz) -> np.ndarray:
    """(K, 6) complex x_i / x_d,i per axis at f (K,) Hz: the closed loop's response to a sine
    on one axis of the reference, its rate included (x_d_dot = i omega x_d, as the reference
    gives it). x_k is the pose the plant reports at the k-th sample and x_d,k the reference the
    controller reads then: the pose and reference a run logs at the same time stamp (measured
    against the Drake plant: within 0.01 dB and 0.05 deg up to 20 Hz, tests/test_linear_model.py).
    """
    f = np.atleast_1d(np.asarray(f_hz, dtype=float))
    G = models.closed.frequency_response(f)  # (K, 18 out, 18 in)
    w = 2j * np.pi * f
    k = np.arange(6)
    return G[:, k, k] + w[:, None] * G[:, k, 6 + k]


@dataclass(frozen=True)
class AxisFigures:
    """One axis's loop figures (:func:`axis_figures`); NaN where a figure does not exist.

    Attributes:
        axis: its name. crossover_hz: where |L| = 1 (the highest crossing), Hz.
        phase_margin_deg, delay_margin_ms: at that crossover (the delay that would close the
            margin: phase margin / crossover angular frequency).
        gain_margin_db: how much the loop gain may rise before instability (at the lowest
            phase crossover above the gain crossover), dB; inf if the phase never crosses.
        lower_gain_margin_db: how much it may fall (a conditionally stable loop), dB (negative),
            -inf if it may fall to zero.
        Ms, Mt: peaks of |S| and |T| (linear), at Ms_hz, Mt_hz.
        bandwidth: -3 dB of x_i / x_d,i (:class:`~.metrics.Bandwidth` over the analysis grid).
        tracking: {f (Hz): (amplitude error %, phase lag deg)} at the breathing and cardiac
            frequencies: 100 (|G| - 1) and -arg G (positive: the pose lags).
    """

    axis: str
    crossover_hz: float
    phase_margin_deg: float
    delay_margin_ms: float
    gain_margin_db: float
    lower_gain_margin_db: float
    Ms: float
    Ms_hz: float
    Mt: float
    Mt_hz: float
    bandwidth: metrics.Bandwidth
    tracking: dict = field(default_factory=dict)

    def record(self) -> dict:
        """Plain JSON values."""
        out = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "bandwidth"}
        out["bandwidth_hz"] = self.bandwidth.hz
        out["bandwidth_where"] = self.bandwidth.where
        out["tracking"] = {str(f): list(v) for f, v in self.tracking.items()}
        return out


def _crossings(f, y):
    """Frequencies where y (K,) changes sign, linearly interpolated in log f, with the index."""
    out = []
    for k in np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0):
        w = y[k] / (y[k] - y[k + 1])
        out.append((float(np.exp(np.log(f[k]) + w * np.log(f[k + 1] / f[k]))), int(k), w))
    return out


def margins(f, L):
    """Margins of a loop's frequency response L (K,) at f (K,) Hz (dense, from well below the
    crossover to the Nyquist frequency).

    At each gain crossover (|L| = 1) the phase margin is the angle between L and -1,
    180 - |arg L| with arg L in (-180, 180]; a loop may cross more than once (the robot as
    built's roll loop near its resonance), and the smallest counts. The delay margin is the
    smallest margin / angular frequency over the crossovers. At each phase crossover (arg L =
    180) the loop gain may change by 1 / |L| before L reaches -1: rises where |L| < 1 (upper),
    falls where |L| > 1 (lower, a conditionally stable loop).

    Returns:
        (crossover_hz, phase_margin_deg, delay_margin_s, gain_margin_db, lower_gain_margin_db):
        the crossover of the smallest phase margin (NaN if |L| never crosses 1); upper gain
        margin in dB (> 0, inf if none), lower in dB (< 0, -inf if none). A margin says nothing
        of a loop that is already unstable: check :attr:`LoopModels.spectral_radius`.
    """
    f, L = np.asarray(f), np.asarray(L)
    mag = np.abs(L)
    phase = np.degrees(np.unwrap(np.angle(L)))
    gain_x = _crossings(f, np.log(mag))
    upper, lower = np.inf, -np.inf
    rel = (phase + 180.0) / 360.0  # an integer where arg L = 180 mod 360
    for m in np.unique(np.round(rel)):
        for _, kp, wp in _crossings(f, rel - m):
            db = -20 * (np.log10(mag[kp]) + wp * (np.log10(mag[kp + 1]) - np.log10(mag[kp])))
            if db > 0:
                upper = min(upper, db)
            else:
                lower = max(lower, db)
    if not gain_x:
        return (np.nan, np.nan, np.nan, upper, lower)
    best, delay = (np.nan, np.inf), np.inf
    for fc, k, w in gain_x:
        ph = phase[k] + w * (phase[k + 1] - phase[k])
        pm = 180.0 - abs((ph + 180.0) % 360.0 - 180.0)
        if pm < best[1]:
            best = (fc, pm)
        delay = min(delay, np.radians(pm) / (2 * np.pi * fc))
    return (best[0], best[1], delay, upper, lower)


def axis_figures(models: LoopModels, f=None) -> list[AxisFigures]:
    """The loop figures of the six axes (:class:`AxisFigures`) on the grid f (default
    :func:`frequency_grid`)."""
    f = frequency_grid(models.h) if f is None else np.asarray(f, dtype=float)
    G = tracking_response(models, f)
    out = []
    for i, name in enumerate(AXES):
        L = loop_at_a_time(models.open, i).frequency_response(f)[:, 0, 0]
        fc, pm, delay, gm, gm_low = margins(f, L)
        S, T = 1 / (1 + L), L / (1 + L)
        kS, kT = int(np.argmax(np.abs(S))), int(np.argmax(np.abs(T)))
        G_at = tracking_response(models, [BREATHING_HZ, CARDIAC_HZ])[:, i]
        out.append(
            AxisFigures(
                axis=name,
                crossover_hz=fc,
                phase_margin_deg=pm,
                delay_margin_ms=1e3 * delay,
                gain_margin_db=gm,
                lower_gain_margin_db=gm_low,
                Ms=float(np.abs(S[kS])),
                Ms_hz=float(f[kS]),
                Mt=float(np.abs(T[kT])),
                Mt_hz=float(f[kT]),
                bandwidth=metrics.bandwidth_hz(f, np.abs(G[:, i])),
                tracking={
                    fr: (float(100 * (abs(g) - 1)), float(-np.degrees(np.angle(g))))
                    for fr, g in zip((BREATHING_HZ, CARDIAC_HZ), G_at)
                },
            )
        )
    return out


@dataclass(frozen=True)
class MultiSine:
    """A reference of sines summed on one axis about a pose: x_d = x0 + e_axis sum_k A_k
    sin(2 pi f_k t) (small-signal injection for :func:`measure_tracking`).

    Attributes:
        x0: (6,) the pose [rad, m]. axis: 0..5. frequencies_hz: (K,). amplitude: each sine's, rad
            or m. name: the label in result files.
    """

    x0: tuple
    axis: int
    frequencies_hz: tuple
    amplitude: float
    name: str = "multisine"

    def evaluate(self, t):
        """Pose, rate, acceleration at times t: three (..., 6) arrays."""
        t = np.asarray(t, dtype=float)
        w = 2 * np.pi * np.asarray(self.frequencies_hz)
        arg = t[..., None] * w
        pose = np.broadcast_to(np.asarray(self.x0, dtype=float), t.shape + (6,)).copy()
        rate, acc = np.zeros(t.shape + (6,)), np.zeros(t.shape + (6,))
        pose[..., self.axis] += self.amplitude * np.sin(arg).sum(-1)
        rate[..., self.axis] = self.amplitude * (w * np.cos(arg)).sum(-1)
        acc[..., self.axis] = -self.amplitude * (w * w * np.sin(arg)).sum(-1)
        return pose, rate, acc


def fit_sines(t, y, frequencies_hz, t_start: float) -> np.ndarray:
    """(K,) complex amplitudes c_k of y ~ sum_k Im(c_k exp(i 2 pi f_k t)) + a + b t over
    t >= t_start (least squares; the constant and the drift absorb what is left of the start
    transient)."""
    t, y = np.asarray(t), np.asarray(y)
    m = t >= t_start
    t, y = t[m], y[m]
    cols = [np.ones_like(t), t - t.mean()]
    for fk in frequencies_hz:
        cols += [np.sin(2 * np.pi * fk * t), np.cos(2 * np.pi * fk * t)]
    coef = np.linalg.lstsq(np.stack(cols, axis=1), y, rcond=None)[0]
    return coef[2::2] + 1j * coef[3::2]


def measure_tracking(
    scenario: Scenario,
    axis: int,
    frequencies_hz=(0.5, 2.0, 5.0, 10.0, 20.0),
    amplitude: float | None = None,
    x0=None,
    settle_s: float = 0.5,
    periods: float = 2.0,
) -> tuple[np.ndarray, np.ndarray]:
    """x_i / x_d,i of the nonlinear Drake plant: one run of ``scenario`` tracking a sum of small
    sines on ``axis`` about x0 (:class:`MultiSine`), each fitted on the true pose
    (:func:`fit_sines`) after ``settle_s``, over ``periods`` of the slowest.

    Args:
        amplitude: of each sine (default 0.1 mrad on an angle, 0.05 mm on a position: small,
            so the loop stays linear, and larger than the encoders' count).
    Returns:
        (f (K,) Hz, G (K,) complex): the measured response, to set beside
        :func:`tracking_response`.
    """
    from ..run.simulate import run_experiment

    f = np.asarray(frequencies_hz, dtype=float)
    x0 = X_HOME.copy() if x0 is None else np.asarray(x0, dtype=float)
    if amplitude is None:
        amplitude = 1e-4 if axis < 3 else 5e-5
    duration = settle_s + periods / f.min()
    ref = MultiSine(tuple(x0), int(axis), tuple(f), float(amplitude))
    run = dataclasses.replace(scenario, duration_s=float(np.ceil(duration / 0.01) * 0.01))
    result = run_experiment(run, reference=ref)
    c_x = fit_sines(result.t, result.x[:, axis], f, settle_s)
    return f, c_x / amplitude


# -- report ----------------------------------------------------------------------------------------


def figures_table(figures: list[AxisFigures]) -> list[str]:
    """The loop figures as a Markdown table, one row per axis."""

    def db(v):
        return "inf" if v == np.inf else "-inf" if v == -np.inf else f"{v:.1f}"

    header = ["axis", "crossover Hz", "phase margin deg", "delay margin ms"]
    header += ["gain margin dB (up / down)", "Ms (at Hz)", "Mt (at Hz)", "-3 dB bandwidth Hz"]
    header += ["0.25 Hz: amplitude %, lag deg", "1.2 Hz: amplitude %, lag deg"]
    rows = []
    for a in figures:
        tr = [a.tracking[BREATHING_HZ], a.tracking[CARDIAC_HZ]]
        rows.append(
            [a.axis, f"{a.crossover_hz:.3g}", f"{a.phase_margin_deg:.1f}"]
            + [f"{a.delay_margin_ms:.2f}"]
            + [f"{db(a.gain_margin_db)} / {db(a.lower_gain_margin_db)}"]
            + [f"{a.Ms:.2f} ({a.Ms_hz:.3g})", f"{a.Mt:.2f} ({a.Mt_hz:.3g})", a.bandwidth.text()]
            + [f"{tr[0][0]:+.2g}, {tr[0][1]:+.2g}", f"{tr[1][0]:+.2g}, {tr[1][1]:+.2g}"]
        )
    return markdown_lines(header, rows)


def plot_loop(models: LoopModels, title: str):
    """Two matplotlib Figures: the Bode plot (gain and phase of the loop L_i and of the tracking
    x_i / x_d,i per axis) and the sensitivity plot (|S_i| and |T_i| with Ms, Mt marked)."""
    import matplotlib.ticker
    from matplotlib.figure import Figure

    f = frequency_grid(models.h)
    G = tracking_response(models, f)
    loops = [loop_at_a_time(models.open, i).frequency_response(f)[:, 0, 0] for i in range(6)]
    # phi and theta, X and Y coincide at a symmetric pose: the second of each pair is dashed
    styles = [{"color": f"C{i}", "ls": "--" if i % 2 else "-"} for i in range(6)]
    bode = Figure(figsize=(12, 8))
    ax = bode.subplots(2, 2, sharex=True)
    for i, (name, L) in enumerate(zip(AXES, loops)):
        ax[0, 0].semilogx(f, 20 * np.log10(np.abs(L)), **styles[i], label=name)
        ax[1, 0].semilogx(f, np.degrees(np.unwrap(np.angle(L))) % 360 - 360, **styles[i])
        ax[0, 1].semilogx(f, 20 * np.log10(np.abs(G[:, i])), **styles[i], label=name)
        ax[1, 1].semilogx(f, np.degrees(np.unwrap(np.angle(G[:, i]))), **styles[i])
    ax[0, 0].axhline(0, color="k", lw=0.8)
    ax[1, 0].axhline(-180, color="k", lw=0.8)
    ax[0, 1].axhline(-3, color="k", ls=":", lw=1)
    ax[0, 0].set_ylim(-60, 100)
    ax[0, 1].set_ylim(-30, 10)
    ax[1, 1].set_ylim(-270, 30)
    ax[0, 0].set_title("loop at the plant input, L_i (one axis open, five closed)", fontsize=10)
    ax[0, 1].set_title("tracking, x_i / x_d,i (-3 dB dotted)", fontsize=10)
    ax[0, 0].set_ylabel("gain [dB]")
    ax[1, 0].set_ylabel("phase [deg]")
    for a in ax.flat:
        a.grid(alpha=0.3, which="both")
        a.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    for a in ax[1]:
        a.set_xlabel("frequency [Hz]")
        for fr in (BREATHING_HZ, CARDIAC_HZ):
            a.axvline(fr, color="0.6", ls="--", lw=0.8)
    ax[0, 0].legend(fontsize=8, ncol=2)
    bode.suptitle(title, fontsize=11)
    bode.tight_layout()

    sens = Figure(figsize=(12, 4.8))
    sx = sens.subplots(1, 2, sharey=True)
    for i, (name, L) in enumerate(zip(AXES, loops)):
        S, T = 1 / (1 + L), L / (1 + L)
        sx[0].semilogx(f, 20 * np.log10(np.abs(S)), **styles[i], label=name)
        sx[1].semilogx(f, 20 * np.log10(np.abs(T)), **styles[i], label=name)
        for a, M in ((sx[0], np.abs(S)), (sx[1], np.abs(T))):
            k = int(np.argmax(M))
            a.plot(f[k], 20 * np.log10(M[k]), "o", color=styles[i]["color"], ms=5)
    for a, what in (
        (sx[0], "S_i = 1 / (1 + L_i), peak Ms"),
        (sx[1], "T_i = L_i / (1 + L_i), peak Mt"),
    ):
        a.axhline(6, color="k", ls=":", lw=1)
        a.set_title(f"{what} (dots; dotted: a peak of 2, 6 dB)", fontsize=10)
        a.set_xlabel("frequency [Hz]")
        a.grid(alpha=0.3, which="both")
        a.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    sx[0].set_ylim(-80, 20)
    sx[0].set_ylabel("gain [dB]")
    sx[1].legend(fontsize=8, ncol=2)
    sens.suptitle(title, fontsize=11)
    sens.tight_layout()
    return bode, sens


# -- across the workspace and the weights ---------------------------------------------------------


def weakest_axis(figures: list[AxisFigures]) -> dict:
    """The figures of a pose that bound it: the smallest phase margin and gain margin, the
    largest Ms, the lowest bandwidth (over the six axes), each with its axis."""
    pm = min(figures, key=lambda a: a.phase_margin_deg)
    gm = min(figures, key=lambda a: a.gain_margin_db)
    ms = max(figures, key=lambda a: a.Ms)
    bw = min(figures, key=lambda a: a.bandwidth.hz if a.bandwidth.hz is not None else np.inf)
    return {
        "phase_margin_deg": pm.phase_margin_deg,
        "phase_margin_axis": pm.axis,
        "gain_margin_db": gm.gain_margin_db,
        "gain_margin_axis": gm.axis,
        "Ms": ms.Ms,
        "Ms_axis": ms.axis,
        "bandwidth_hz": bw.bandwidth.hz,
        "bandwidth_axis": bw.axis,
    }


def tilt_grid(extent_rad: float = 0.55, n: int = 9, height_m: float = float(X_HOME[5])):
    """(n * n, 6) poses rolled and pitched over [-extent, extent] rad at ``height_m``."""
    a = np.linspace(-extent_rad, extent_rad, n)
    phi, theta = np.meshgrid(a, a, indexing="ij")
    poses = np.zeros((n * n, 6))
    poses[:, 0], poses[:, 1], poses[:, 5] = phi.ravel(), theta.ravel(), height_m
    return poses


def loop_map(scenario: Scenario, poses, driver: LqiDriver | None = None) -> list[dict]:
    """The bounding figures (:func:`weakest_axis`) at each admissible pose of ``poses``
    (N, 6). Admissible as a reference held at rest is: reachable
    (:func:`~stewart_drake.robot.limits.is_reachable`), within the scenario's guard on
    singularity (cond(J) <= ``guard.cond_threshold``, 1 / sigma_max(J) >=
    ``guard.min_sigma_min_inv``), and held by the motors within ``guard.effort_margin`` of their
    limit; the parts' clearance is not checked. Each row: ``pose`` (list), the closed loop's
    ``spectral_radius`` and the figures."""
    from ..robot.limits import is_reachable

    plan = make_plan(scenario, with_reference=False)
    guard = plan.scenario.guard
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    ok = is_reachable(plan.geometry, poses).reachable
    sv = kinematics.singular_values(plan.geometry, poses[ok])
    fine = (sv[:, 0] / sv[:, -1] <= guard.cond_threshold) & (
        1.0 / sv[:, 0] >= guard.min_sigma_min_inv
    )
    ok[np.flatnonzero(ok)[~fine]] = False
    if plan.torque_limit_Nm is not None and ok.any():
        T = statics.holding_torques(plan.geometry, poses[ok])
        held = np.abs(T).max(axis=1) <= guard.effort_margin * plan.torque_limit_Nm
        ok[np.flatnonzero(ok)[~held]] = False
    rows = []
    for x0 in poses[ok]:
        models = loop_models(plan, x0, driver=driver)
        figures = axis_figures(models, _map_grid(plan.control_period_s))
        rows.append(
            {
                "pose": x0.tolist(),
                "spectral_radius": models.spectral_radius,
                **weakest_axis(figures),
            }
        )
    return rows


def weakest_pose(rows: list[dict]) -> dict:
    """The row of :func:`loop_map` whose loop comes nearest to -1: an unstable closed loop
    first, else the largest Ms (1 / Ms is the smallest distance of any axis's L to -1, a figure
    that, unlike a phase margin, a loop crossing 0 dB several times cannot make ambiguous)."""
    return max(rows, key=lambda r: (r["spectral_radius"] >= 1, r["Ms"]))


def _map_grid(h: float) -> np.ndarray:
    """A coarser grid for maps (100 points per decade): margins to about 0.1 deg."""
    f_max = 0.999 / (2 * h)
    return np.geomspace(F_MIN_HZ, f_max, int(100 * np.log10(f_max / F_MIN_HZ)) + 1)


def weight_sweep(scenario: Scenario, ratios=(0.01, 0.1, 1.0, 10.0, 100.0), x0=None) -> list[dict]:
    """The loop figures at pose x0 (default home) for LQIs of weight ratio omega_Q / omega_R in
    ``ratios`` (omega_R = 1; only the ratio sets the gain): the trade-off a user tunes. Each
    row: ``ratio``, ``spectral_radius`` and ``stable`` of the closed loop, and the six axes'
    :meth:`AxisFigures.record`."""
    plan = make_plan(scenario, with_reference=False)
    rows = []
    for r in ratios:
        driver = scenario.lqi(omega_Q=float(r), omega_R=1.0)  # the scenario's LQI, or the default
        models = loop_models(plan, x0, driver=driver)
        rho = models.spectral_radius
        rows.append(
            {
                "ratio": float(r),
                "spectral_radius": rho,
                "stable": rho < 1,
                "axes": [a.record() for a in axis_figures(models)],
            }
        )
    return rows


def plot_map(rows: list[dict], title: str):
    """A Figure of the smallest phase margin and the largest Ms over the six axes at each pose
    of a :func:`tilt_grid` map (:func:`loop_map` rows), the weakest pose (:func:`weakest_pose`)
    circled."""
    from matplotlib.figure import Figure

    poses = np.array([r["pose"] for r in rows])
    fig = Figure(figsize=(12, 5))
    axes = fig.subplots(1, 2)
    weakest = rows.index(weakest_pose(rows))
    for ax, key, label, cmap in (
        (axes[0], "phase_margin_deg", "smallest phase margin over the axes [deg]", "viridis"),
        (axes[1], "Ms", "largest Ms over the axes", "magma_r"),
    ):
        values = np.array([r[key] for r in rows], dtype=float)
        sc = ax.scatter(
            np.degrees(poses[:, 0]), np.degrees(poses[:, 1]), c=values, s=260, marker="s", cmap=cmap
        )
        fig.colorbar(sc, ax=ax, label=label)
        ax.plot(
            np.degrees(poses[weakest, 0]),
            np.degrees(poses[weakest, 1]),
            "o",
            mfc="none",
            mec="r",
            ms=20,
            mew=2,
        )
        ax.set_xlabel("roll phi [deg]")
        ax.set_ylabel("pitch theta [deg]")
        ax.set_aspect("equal")
    fig.suptitle(f"{title} (red circle: the weakest pose, largest Ms)", fontsize=11)
    fig.tight_layout()
    return fig
