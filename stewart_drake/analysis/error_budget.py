"""The error budget of the robot on its servo bus: how far from a motion the platform is, source
by source, and how far the encoders let it know.

What the encoders let the robot know is :func:`quantization_floor`: every crank read to within
half a count (uniform, independent), mapped to the pose by J^-1 at the pose (RMS per axis): the
floor under any figure the robot gives of itself.

What the robot makes is :func:`error_budget`: the motion simulated on the robot as built at the
bus's period (the scenario's own controller, its encoders, delay, current loop, friction,
backlash and the robot's mass as built), its true pose's RMS error per axis; then once again
with each source taken away, the others left as they are:

* **encoders**: read exactly (2^30 counts a turn) instead of at the scenario's counts;
* **period and delay**: a 1 ms period and no computation delay (the same controller, its
  bandwidths kept);
* **current loop**: a current loop without lag;
* **friction**: no dry or viscous friction in the servos, and none believed by the controller;
* **backlash**: no play in the gears (only run when the scenario has some);
* **model**: the robot as the controller believes it (no ``payload_scale``, ``robot_as_built``
  or ``robot_tolerances``; only run when the scenario has one).

A source's share is sqrt(e_all^2 - e_without^2) per axis (0 where taking it away did not lower
the error): what that source adds on top of the others. The shares are not additive (friction
and the encoders act together at every reversal): they say which source to work on, not a sum.
The simulation at the bus's period is what predicts the robot (docs/robot.md measures it against
the bus emulator). Why not a linear budget through the loop's model: the crank servo's friction
compensation and the cranks' stiction set the error at a phantom's speeds, and a linear model has
neither (tried: it put the encoders' share at twice what the robot does).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InvalidConfigError
from ..base.measures import rms_per_axis
from ..base.tables import markdown_lines
from ..robot import forward_kinematics, kinematics
from ..robot.geometry import X_HOME

AXES = ("phi", "theta", "psi", "X", "Y", "Z")
#: The sources of the budget, in order, with what would lower each.
SOURCES = {
    "encoders": "finer encoders (counts a turn) or a reduction between the encoder and the crank",
    "period and delay": "a shorter control_period_s",
    "current loop": "a faster current loop (the servo's)",
    "friction": "friction the feed-forward knows better (friction_adaptation_s), a drive with less",
    "backlash": "a gear without play",
    "model": "the robot as built known to the controller (calibrate, payload_scale)",
}


def quantization_floor(scenario, x=None) -> np.ndarray:
    """(6,) RMS per axis [rad, m] of the pose the encoders give at pose ``x`` (default home):
    each crank within half a count, uniform and independent, through J^-1.

    Args:
        scenario: a Scenario or plan of the robot as built (its encoders: ``hardware``, or on
            the servo bus the bus's servos).
    Raises:
        InvalidConfigError: the ideal robot (no encoders: nothing to quantize).
        UnreachablePoseError: x is not a pose of the robot.
    """
    from ..run.plan import make_plan

    plan = make_plan(scenario, with_reference=False)
    hw = plan.scenario.hardware
    if hw is None:
        raise InvalidConfigError(
            "the ideal robot reads its cranks exactly: no encoders to budget (give a scenario "
            "with hardware, or one on the servo bus)"
        )
    x = X_HOME if x is None else np.asarray(x, dtype=float)
    return forward_kinematics.encoder_floor(plan.geometry, x, hw.encoders.quantum_rad)


@dataclass
class ErrorBudget:
    """The budget of a motion (:func:`error_budget`); SI units, per axis (6,) [rad, m].

    Attributes:
        floor: :func:`quantization_floor` at the motion's centre: what the encoders know.
        total: the true pose's RMS error with every source (the simulated robot).
        encoder_pose: the RMS error of the pose the encoders read (what the robot reports of
            itself), over the same window.
        rows: {source: (6,) its share, sqrt(total^2 - without^2)} (:data:`SOURCES`; zeros for a
            source the scenario does not have).
        without: {source: (6,) the true pose's RMS error with that source taken away}.
        window_s: (start, end) of the measured window, s. assumptions: {name: value}.
    """

    floor: np.ndarray
    total: np.ndarray
    encoder_pose: np.ndarray
    rows: dict
    without: dict
    window_s: tuple
    assumptions: dict = field(default_factory=dict)
    #: {source: what would lower it} (the simulated budget's :data:`SOURCES`).
    lowers: dict = field(default_factory=lambda: dict(SOURCES))
    #: how the true pose was had: "simulated" (:func:`error_budget`) or "emulated" (the
    #: realistic bus emulator: :mod:`stewart_drake.live.emulated_budget`).
    measured: str = "simulated"

    def dominant(self) -> tuple[str, str]:
        """(the source of the largest translation share, of the largest rotation share)."""
        names = list(self.rows)
        # a row not measured (NaN: its run did not end) dominates nothing
        tr = np.nan_to_num([np.linalg.norm(self.rows[n][3:]) for n in names], nan=-1.0)
        rot = np.nan_to_num([np.linalg.norm(self.rows[n][:3]) for n in names], nan=-1.0)
        return names[int(np.argmax(tr))], names[int(np.argmax(rot))]

    def lines(self) -> list[str]:
        """The budget as a Markdown table, um and urad, with what dominates and lowers it."""
        header = [None, *(f"{a} [{'urad' if k < 3 else 'um'}]" for k, a in enumerate(AXES))]

        def row(name, v, lower=""):
            return [name, *("-" if c != c else f"{1e6 * c:.3g}" for c in v), lower]

        rows = [row(f"**true pose**, every source ({self.measured})", self.total)]
        rows += [row(f"share of {name}", v, self.lowers[name]) for name, v in self.rows.items()]
        rows.append(row("encoders' floor (what they can know)", self.floor))
        rows.append(row("**encoder pose** (what the robot reads)", self.encoder_pose))
        out = markdown_lines([*header, "what lowers it"], rows)
        tr, rot = self.dominant()
        out.append("")
        out += [
            f"Not measured, {name}: {self.assumptions.get(name, 'its run did not end')}."
            for name, v in self.rows.items()
            if np.all(np.isnan(v))
        ]
        out.append(f"Dominant: {tr} in translation, {rot} in rotation.")
        return out

    def record(self) -> dict:
        """Plain JSON values: every figure, rad and m."""
        return {
            "floor": self.floor.tolist(),
            "total": self.total.tolist(),
            "encoder_pose": self.encoder_pose.tolist(),
            "rows": {k: v.tolist() for k, v in self.rows.items()},
            "without": {k: v.tolist() for k, v in self.without.items()},
            "window_s": list(self.window_s),
            "assumptions": self.assumptions,
            "measured": self.measured,
        }


#: The longest span one of the budget's simulations may take, s (each runs about as long on a
#: quiet machine; the budget runs one with every source and one without each).
MAX_SPAN_S = 300.0


def error_budget(
    scenario,
    reference,
    duration_s: float | None = None,
    skip_s: float | None = None,
    say=None,
) -> ErrorBudget:
    """The budget of ``reference`` on the robot of ``scenario`` (module docstring): one
    simulation with every source, then one without each that the scenario has.

    Args:
        scenario: a Scenario or plan of the robot as built (``hardware``, or a bus).
        reference: an object with ``evaluate(t)`` (the motion), a reference's configuration
            (made on the scenario's geometry), or a library motion's name.
        duration_s: the simulated span, s (default five of the motion's periods, or 20 s).
        skip_s: the start not measured, s (default the first period, or 4 s).
        say: called with a line before each simulation (progress), or None.
    Raises:
        InvalidConfigError: the ideal robot (no encoders to budget), a window outside the span,
            a span over :data:`MAX_SPAN_S` (before any simulation).
        UnreachablePoseError, MotorLimitError, ...: the reference's check refused the motion.
        SimulationDivergedError: a simulation diverged.
    """
    from ..run.plan import make_plan

    plan = make_plan(scenario, with_reference=False)
    base = plan.scenario
    hw = base.hardware
    if hw is None:
        raise InvalidConfigError(
            "the ideal robot reads its cranks exactly and has no servos: no error budget (give "
            "a scenario with hardware, or one on the servo bus, e.g. paper_bus)"
        )
    from ..references.motion import ReferenceConfig
    from ..references.organ.library import OrganMotionReference

    if isinstance(reference, str):
        reference = OrganMotionReference(motion=reference)
    if isinstance(reference, ReferenceConfig):
        reference = reference.make(plan.geometry, 0.0, None)
    period = float(getattr(reference, "period_s", 0.0) or 0.0)
    span = duration_s or (5 * period if period > 0 else 20.0)
    skip = skip_s if skip_s is not None else (period if period > 0 else 4.0)
    if not 0 <= skip < span:
        raise InvalidConfigError(f"skip_s ({skip:g} s) must lie within the span ({span:g} s)")
    if span > MAX_SPAN_S:
        what = f"{span:g} s of the motion" + ("" if duration_s else " (five of its periods)")
        raise InvalidConfigError(
            f"the budget would simulate {what} up to {1 + len(SOURCES)} times, beyond "
            f"{MAX_SPAN_S:g} s a run: give a motion of a shorter period (--param period=...)"
        )
    base = dataclasses.replace(base, bus=None, duration_s=span, learning=None)
    motors = hw.motors

    def with_motors(**changes):
        return dict(hardware=dataclasses.replace(hw, motors=dataclasses.replace(motors, **changes)))

    variants = {
        "encoders": dict(
            hardware=dataclasses.replace(
                hw, encoders=dataclasses.replace(hw.encoders, counts_per_rev=2**30)
            )
        ),
        "period and delay": dict(
            control_period_s=1e-3,
            log_period_s=1e-3,
            state_log_period_s=1e-2,
            hardware=dataclasses.replace(hw, computation_delay_periods=0),
        ),
        "current loop": with_motors(current_time_constant_s=0.0),
        "friction": {
            **with_motors(coulomb_friction_Nm=0.0, viscous_damping=0.0),
            "controller": _believing_no_friction(base.controller),
        },
        "backlash": with_motors(backlash_rad=0.0),
        "model": dict(payload_scale=1.0, robot_as_built=None, robot_tolerances=None),
    }
    if motors.backlash_rad == 0.0:
        variants.pop("backlash")
    if base.payload_scale == 1.0 and base.robot_as_built is None and base.robot_tolerances is None:
        variants.pop("model")

    def simulate(name, scenario):
        if say is not None:
            say(f"simulating {span:g} s of the motion, {name} ...")
        return _errors(scenario, reference, skip)

    total, encoder_pose, centre = simulate("every source", base)
    without, rows = {}, {}
    for name in SOURCES:
        if name not in variants:
            rows[name] = np.zeros(6)
            continue
        changed = dataclasses.replace(base, **variants[name])
        without[name] = simulate(f"without its {name}", changed)[0]
        rows[name] = source_share(total, without[name])
    return ErrorBudget(
        floor=quantization_floor(plan, centre),
        total=total,
        encoder_pose=encoder_pose,
        rows=rows,
        without=without,
        window_s=(skip, span),
        assumptions={
            "centre": centre.tolist(),
            "control_period_s": base.control_period_s,
            "delay_periods": hw.computation_delay_periods,
            "counts_per_rev": hw.encoders.counts_per_rev,
            "controller": type(base.controller).__name__,
        },
    )


def axis_rms(e) -> np.ndarray:
    """Per-axis RMS of a pose error ``e`` (n, 6) [rad, m] over its rows: (6,); NaN for no row
    (a run that measured nothing has no error to give)."""
    e = np.asarray(e, dtype=float)
    return rms_per_axis(e) if len(e) else np.full(e.shape[-1], np.nan)


def source_share(total, without) -> np.ndarray:
    """A source's share of the error, per axis: sqrt(total^2 - without^2), ``total`` the RMS
    error (6,) with every source and ``without`` with that one taken away; 0 where taking it away
    did not lower the error (the sources interact: the shares are not additive)."""
    return np.sqrt(np.maximum(np.square(total) - np.square(without), 0.0))


def _believing_no_friction(driver):
    """The controller ``driver`` believing the servos have no dry friction (the crank servo's
    ``friction_scale`` 0, the LQI's ``friction_compensation_Nm`` 0); another as it is."""
    for name in ("friction_scale", "friction_compensation_Nm"):
        if hasattr(driver, name):
            return dataclasses.replace(driver, **{name: 0.0})
    return driver


def _errors(scenario, reference, skip: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the true pose's RMS error (6,), the encoder pose's (6,), the motion's mean pose (6,))
    of one simulation over t >= skip. The encoder pose: the forward kinematics of the true
    pose's crank angles, as the encoders read them (their zero errors, whole counts)."""
    from ..robot.forward_kinematics import fk
    from ..run.plan import make_plan
    from ..run.simulate import run_experiment

    result = run_experiment(scenario, reference=reference)
    keep = result.t >= skip
    x_true = np.asarray(result.x[keep, :6], dtype=float)
    x_d = np.asarray(result.x_d[keep, :6], dtype=float)
    plan = make_plan(scenario, with_reference=False)
    built, believed = plan.plant_geometry, plan.geometry
    q = scenario.hardware.encoders.quantum_rad
    counts = np.round((kinematics.ik(built, x_true) + built.encoder_offsets) / q)
    read = counts * q - believed.encoder_offsets
    x_read = np.empty_like(x_true)
    x_k = x_true[0]
    for i, theta in enumerate(read):
        x_k, _ = fk(believed, theta, x0=x_k)
        x_read[i] = x_k

    return axis_rms(x_true - x_d), axis_rms(x_read - x_d), x_d.mean(axis=0)
