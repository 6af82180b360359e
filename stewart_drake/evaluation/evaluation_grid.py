"""The evaluation's grid: its controllers, references and conditions, typed.

A :class:`Case` is one run of the grid: a :class:`GridController` (a name and the controller
and tuner choices it runs with) on a named reference under a condition, from a base scenario;
:func:`case_config` is the one place a case becomes a :class:`~.scenario.Scenario`.
:mod:`.evaluation` runs the cases, :mod:`.evaluation_report` writes what they give.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

from ..base.errors import InvalidConfigError
from ..control.tuning import AnnTunerDriver, TunerChoice
from ..references.trajectories import NamedReference
from ..robot.kinematics import AXIS_NAMES
from ..run.scenario import ControllerChoice, Scenario, named_controllers
from ..run.scenario_io import DEFAULT_SCENARIO, load_scenario
from ..station.station import SensorNoise, ToolDisturbance
from ..tuner.collection import PAPER_WEIGHTS

#: The fixed LQIs of the grid by name: (omega_Q, omega_R), the paper's nine pairs.
FIXED_WEIGHTS = {f"lqi_{q:g}_{r:g}": (q, r) for q in PAPER_WEIGHTS for r in PAPER_WEIGHTS}
FIXED_LQI = tuple(FIXED_WEIGHTS)
#: The ANN-tuned LQIs of the grid by name: the file of the tuner's weights, in
#: ``stewart_drake/data/`` (best-cost labels, the paper's labels).
ANN_WEIGHTS = {"ann_best_cost": "ann_tuner.npz", "ann_paper": "ann_tuner_paper.npz"}
#: The controller choices run with their defaults (the PD), by their short names: not the LQI
#: (the grid's fixed and tuned weights are its), nor the crank servo (the bus's controller:
#: the grid asks the paper's question, of the LQI's weights on the robot at 1 ms).
DEFAULT_DRIVERS = {
    name: kind for name, kind in named_controllers().items() if name not in ("lqi", "servo")
}
CONTROLLERS = FIXED_LQI + tuple(DEFAULT_DRIVERS) + tuple(ANN_WEIGHTS)
#: The controllers of ``evaluate --quick``: one of each kind, enough to draw every table and plot.
QUICK_CONTROLLERS = ("lqi_1_1", "pd", "ann_best_cost")
#: Sensor noise of the "noise" condition on the ideal robot: 0.1 mrad, 0.05 mm, 0.01 rad/s,
#: 5 mm/s (1 sigma); on the robot as built, encoder noise of ENCODER_NOISE_COUNTS (1 sigma).
NOISE_STD = (1e-4,) * 3 + (5e-5,) * 3 + (1e-2,) * 3 + (5e-3,) * 3
ENCODER_NOISE_COUNTS = 2.0
#: The scenario every case starts from (a shipped name or a path): the robot as built.
DEFAULT_BASE = DEFAULT_SCENARIO
#: Encoder resolutions of the encoder table (bits: 2^bits counts per crank turn), run with the
#: five distinct weight ratios omega_Q / omega_R on the paper manoeuvre.
ENCODER_BITS = (12, 14, 16, 17, 20)
RATIO_LQI = ("lqi_10_0.1", "lqi_10_1", "lqi_1_1", "lqi_1_10", "lqi_0.1_10")
#: Tool disturbances (world frame, on the tool tip) while holding home: from t = 1 s on.
DISTURBANCES = {
    "push 5 N": ToolDisturbance("push", 5.0, [1.0, 0.0, 0.0]),
    "twist 0.2 N m": ToolDisturbance("twist", 0.2, [0.0, 0.0, 1.0]),
    "contact 2 Hz": ToolDisturbance("contact", 3.0, [0.0, 0.0, -1.0], frequency_hz=2.0),
}
#: Motor torque limit of the "saturation" condition, N m. It runs on the Z step, whose transient
#: asks for 1.5 to 7.6 N m. On the paper manoeuvre, which needs at most 0.41 N m once on its
#: way, any limit below that loses the platform (it rolls past phi = 0.52 rad and falls: physics,
#: not the controller), and any limit above it never acts.
TORQUE_LIMIT_NM = 0.6


def _noise(scenario: Scenario) -> None:
    if scenario.hardware is not None:
        scenario.hardware.encoders.noise_counts = ENCODER_NOISE_COUNTS
    else:
        scenario.sensor_noise = SensorNoise(std=list(NOISE_STD))


def _set(**fields):
    return lambda scenario: [setattr(scenario, k, v) for k, v in fields.items()]


def _encoder_bits(bits: int):
    def apply(scenario: Scenario) -> None:
        if scenario.hardware is None:
            raise InvalidConfigError("the encoder conditions need a scenario with hardware")
        scenario.hardware.encoders.counts_per_rev = 2**bits

    return apply


#: Conditions: a change of the scenario and the reference it runs on (robustness is on the paper
#: manoeuvre but for the saturation, see TORQUE_LIMIT_NM, and the tool disturbances, while
#: holding home).
CONDITIONS = {
    "nominal": (None, None),
    "payload+20%": (_set(payload_scale=1.2), "paper"),
    "payload-20%": (_set(payload_scale=0.8), "paper"),
    "noise": (_noise, "paper"),
    f"saturation {TORQUE_LIMIT_NM:g} N m": (_set(torque_limit_Nm=TORQUE_LIMIT_NM), "step_Z"),
    **{name: (_set(disturbance=d), "home") for name, d in DISTURBANCES.items()},
}


def encoder_condition(bits: int) -> str:
    """The name of the encoder condition of ``bits`` (2^bits counts per crank turn)."""
    return f"encoders {bits}-bit"


#: The encoder conditions, run only by RATIO_LQI (the encoder table).
ENCODER_CONDITIONS = {encoder_condition(b): (_encoder_bits(b), "paper") for b in ENCODER_BITS}
#: Simulated seconds per reference.
SCENARIO_DURATION_S = {
    "paper": 10.0,
    "helix": 4.0,
    "sweep_Z": 9.0,
    "sweep_phi": 9.0,
    **{f"step_{a}": 2.5 for a in AXIS_NAMES},
}
#: Simulated seconds of the runs that only hold home (the tool disturbances).
HOLD_DURATION_S = 3.0


@dataclass(frozen=True)
class GridController:
    """One controller of the grid, typed: what runs on the base scenario.

    Attributes:
        name: its name in the grid (``--controllers``, the report's rows), e.g. "lqi_1_1".
        controller: the scenario's controller choice it runs with.
        tuner: the tuner choice, or None (fixed weights).
        ratio: omega_Q / omega_R of a fixed LQI (the plots draw one line per ratio), or None.
    """

    name: str
    controller: ControllerChoice
    tuner: TunerChoice | None = None
    ratio: float | None = None


def grid_controller(name: str, base: Scenario) -> GridController:
    """The controller of the grid called ``name`` on ``base``: a fixed LQI keeps the base's LQI
    options (riccati, scales, ...) at its weights (:meth:`~.scenario.Scenario.lqi`); an ANN one
    tunes the base's controller.

    Raises:
        InvalidConfigError: unknown name (the message lists the known ones).
    """
    check_controllers([name])
    if name in FIXED_WEIGHTS:
        q, r = FIXED_WEIGHTS[name]
        return GridController(name, base.lqi(omega_Q=q, omega_R=r), ratio=q / r)
    if name in DEFAULT_DRIVERS:
        return GridController(name, DEFAULT_DRIVERS[name]())
    from ..control.tuner.ann import DEFAULT_TUNER_PATH

    path = DEFAULT_TUNER_PATH.with_name(ANN_WEIGHTS[name])
    return GridController(name, base.controller, AnnTunerDriver(weights=str(path)))


def check_controllers(names) -> None:
    """Refuse a name that is not a controller of the grid, before anything runs.

    Raises:
        InvalidConfigError: the first unknown name, with the known ones.
    """
    for name in names:
        if name not in CONTROLLERS:
            raise InvalidConfigError(
                f"unknown controller {name!r}; choose from {', '.join(CONTROLLERS)}"
            )


@dataclass(frozen=True)
class Case:
    """One run of the grid: a controller on a reference (a name of
    :data:`~stewart_drake.references.trajectories.TRAJECTORIES`) under a condition, for a
    duration (s), starting from the scenario ``base`` (a shipped name or a path)."""

    controller: GridController
    reference: str
    condition: str = "nominal"
    duration_s: float = 10.0
    base: str = DEFAULT_BASE

    @property
    def key(self) -> str:
        """The case for display: ``controller | reference | condition``."""
        return f"{self.controller.name} | {self.reference} | {self.condition}"

    def record(self) -> dict:
        """The case as its row stores it (plain JSON; the controller by name)."""
        return {
            "controller": self.controller.name,
            "scenario": self.reference,
            "condition": self.condition,
            "duration_s": self.duration_s,
            "base": self.base,
        }


def make_case(
    controller: str,
    reference: str,
    condition: str = "nominal",
    duration_s: float = 10.0,
    base: str = DEFAULT_BASE,
) -> Case:
    """The :class:`Case` of the grid's controller called ``controller`` on ``base``.

    Raises:
        InvalidConfigError: an unknown controller; MissingFileError: no such base scenario.
    """
    return Case(
        grid_controller(controller, load_scenario(base)), reference, condition, duration_s, base
    )


def cases(quick: bool = False, controllers=CONTROLLERS, base: str = DEFAULT_BASE) -> list[Case]:
    """The evaluation grid.

    Every controller runs every reference in nominal conditions, and each other condition on its
    reference (:data:`CONDITIONS`); on a base with hardware the five weight ratios also run the
    encoder resolutions (:data:`ENCODER_CONDITIONS`). ``quick`` shortens every run to 1 s
    (sweeps and disturbances 2 s) for tests and notebooks: the tables are then only a smoke
    test, not figures to quote.
    """

    def duration(reference):
        if quick:
            return 2.0 if reference.startswith("sweep") or reference == "home" else 1.0
        return SCENARIO_DURATION_S.get(reference, HOLD_DURATION_S)

    scenario = load_scenario(base)
    hardware = scenario.hardware is not None
    out = []
    for name in controllers:
        c = grid_controller(name, scenario)
        for reference in SCENARIO_DURATION_S:
            out.append(Case(c, reference, "nominal", duration(reference), base))
        conditions = dict(
            CONDITIONS, **(ENCODER_CONDITIONS if hardware and name in RATIO_LQI else {})
        )
        for condition, (_, where) in conditions.items():
            if where is not None:
                out.append(Case(c, where, condition, duration(where), base))
    return out


def case_config(case: Case) -> Scenario:
    """The scenario of one case: the base scenario with the case's reference, duration,
    controller and condition."""
    scenario = load_scenario(case.base)
    scenario.reference = NamedReference(case.reference)
    scenario.duration_s = case.duration_s
    scenario.use_controller(dataclasses.replace(case.controller.controller), case.controller.tuner)
    change = {**CONDITIONS, **ENCODER_CONDITIONS}[case.condition][0]
    if change is not None:
        change(scenario)
    return scenario.validate()


def case_id(case: Case) -> str:
    """The case's job id and file stem: ``controller__reference__condition``, filename-safe."""
    return re.sub(
        r"[^A-Za-z0-9.+-]+", "_", f"{case.controller.name}__{case.reference}__{case.condition}"
    )


def index_rows(rows) -> dict:
    """{(controller, reference, condition): row} of the grid's rows."""
    return {
        (r["case"]["controller"], r["case"]["scenario"], r["case"]["condition"]): r for r in rows
    }
