"""How accurate is the plant: one scenario on Drake's SAP plant and on MuJoCo, at several steps.

A scenario starts at rest at a pose, assembled, under constant motor torques: zero (a free fall
of the mechanism) or a multiple of the virtual-work holding torques (a rise). :func:`simulate`
runs it on an engine (:class:`DrakeEngine`, :class:`MujocoEngine`, same methods) and returns a
:class:`Run`: platform poses at sample times, the relative energy change, the largest
loop-closure error and the wall time of the stepping. ``benchmarks/accuracy.py`` compares each
step with the same engine at :data:`REFERENCE_STEP_S` and writes docs/accuracy.md.

Energy: E = kinetic + potential (each engine's own: ``CalcKineticEnergy`` /
``CalcPotentialEnergy`` in Drake, ``mjData.energy`` in MuJoCo) minus the work of the constant
torques, W = sum_i T_i (theta_i(t) - theta_i(0)). Exact dynamics keep E constant; the relative
change is (E(t) - E(0)) / KE(t), the share of the kinetic energy the motion should have that the
integrator lost (< 0) or made up (> 0).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..robot import kinematics, statics
from ..robot.geometry import X_HOME, StewartGeometry
from ..run.plan import robot_geometry

#: Plant steps of the study, s, and the step of each engine's reference solution.
STEPS_S = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5)
REFERENCE_STEP_S = 1e-5
#: Times at which platform poses are compared, s.
SAMPLE_TIMES_S = (0.05, 0.1)
#: Loop closure is measured this often, s (a whole multiple of every step above).
CHECK_PERIOD_S = 1e-3
#: A tilted start pose inside every limit: roll 8.6, pitch -5.7, yaw 5.7 deg, off-centre.
X_TILTED = np.array([0.15, -0.10, 0.10, 0.02, -0.01, 0.29])


@dataclass(frozen=True)
class OpenLoopCase:
    """Start at rest at ``x0`` (6,) [rad, m] under ``torque_scale`` x the holding torques there."""

    name: str
    x0: tuple
    torque_scale: float

    def torques(self, geometry: StewartGeometry) -> np.ndarray:
        """(6,) constant motor torques, N m (virtual work, ``statics.holding_torques``)."""
        return self.torque_scale * statics.holding_torques(geometry, np.asarray(self.x0))


#: Zero-torque falls and rises under 1.2 x the holding torques, from home and tilted.
SCENARIOS = (
    OpenLoopCase("fall_home", tuple(X_HOME), 0.0),
    OpenLoopCase("fall_tilted", tuple(X_TILTED), 0.0),
    OpenLoopCase("rise_home", tuple(X_HOME), 1.2),
    OpenLoopCase("rise_tilted", tuple(X_TILTED), 1.2),
)


@dataclass
class Run:
    """One simulated scenario.

    Attributes:
        engine: engine name.  scenario: scenario name.  time_step_s: s.
        t: (k,) sample times, s.  x: (k, 6) platform poses there [rad, m].
        energy_change: relative energy change at the last sample (module docstring).
        max_closure_m: largest loop-closure error over the run (every CHECK_PERIOD_S), m.
        wall_s: wall time spent stepping, s.  sim_s: simulated time, s.
    """

    engine: str
    scenario: str
    time_step_s: float
    t: np.ndarray
    x: np.ndarray
    energy_change: float
    max_closure_m: float
    wall_s: float
    sim_s: float


class DrakeEngine:
    """The Drake plant of :func:`.plant.add_stewart_plant` under constant torques, run by
    Drake's Simulator (gravity: Drake's default 9.81 m/s^2); ``rod_model`` one of
    :data:`~stewart_drake.plant.sdf.ROD_MODELS` (named "drake_sap" with rods as bodies,
    "drake_sap_distance" with rods as distance constraints)."""

    def __init__(
        self, geometry: StewartGeometry, time_step: float, torques, rod_model: str = "bodies"
    ):
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder
        from pydrake.systems.primitives import ConstantVectorSource

        from ..plant.plant import add_stewart_plant

        self.name = "drake_sap" if rod_model == "bodies" else f"drake_sap_{rod_model}"
        builder = DiagramBuilder()
        self.plant, _, self.handles = add_stewart_plant(
            builder, geometry, time_step, rod_model=rod_model
        )
        source = builder.AddSystem(ConstantVectorSource(np.asarray(torques, dtype=float)))
        builder.Connect(source.get_output_port(), self.handles.actuation_port)
        self.simulator = Simulator(builder.Build())
        self.context = self.plant.GetMyMutableContextFromRoot(self.simulator.get_mutable_context())

    def assemble(self, x) -> None:
        from ..plant.closed_chain import assemble

        assemble(self.plant, self.context, self.handles, x)
        self.simulator.Initialize()

    def advance_to(self, t: float) -> None:
        self.simulator.AdvanceTo(t)

    def pose(self) -> np.ndarray:
        from ..plant.plant import platform_pose

        return platform_pose(self.plant, self.context, self.handles)[0]

    def closure(self) -> float:
        from ..plant.closed_chain import loop_closure_errors

        return float(loop_closure_errors(self.plant, self.context, self.handles).max())

    def energies(self) -> tuple[float, float]:
        """(kinetic, potential) energy in J."""
        return (
            self.plant.CalcKineticEnergy(self.context),
            self.plant.CalcPotentialEnergy(self.context),
        )

    def motor_angles(self) -> np.ndarray:
        return np.array([joint.get_angle(self.context) for joint in self.handles.motors])


class MujocoEngine:
    """The MJCF of :func:`stewart_drake.plant.mjcf.write_mjcf` under constant torques,
    ``mj_step``."""

    def __init__(
        self, geometry: StewartGeometry, time_step: float, torques, integrator: str | None = None
    ):
        from ..plant import mjcf

        self._mjcf = mjcf
        self._mujoco = mjcf.import_mujoco()
        self.integrator = integrator or mjcf.DEFAULT_INTEGRATOR
        self.name = f"mujoco_{self.integrator.lower()}"
        self.geometry, self.time_step = geometry, time_step
        self.model = mjcf.load_model(geometry, time_step=time_step, integrator=self.integrator)
        self.model.opt.enableflags |= self._mujoco.mjtEnableBit.mjENBL_ENERGY
        self.data = self._mujoco.MjData(self.model)
        self.torques = np.asarray(torques, dtype=float)

    def assemble(self, x) -> None:
        self._mjcf.assemble(self.model, self.data, self.geometry, x)
        self.data.ctrl[:] = self.torques
        self._steps = 0

    def advance_to(self, t: float) -> None:
        target = round(t / self.time_step)
        step = self._mujoco.mj_step
        for _ in range(target - self._steps):
            step(self.model, self.data)
        self._steps = target

    def pose(self) -> np.ndarray:
        return self._mjcf.platform_pose(self.model, self.data)

    def closure(self) -> float:
        return float(self._mjcf.loop_closure_errors(self.model, self.data).max())

    def energies(self) -> tuple[float, float]:
        """(kinetic, potential) energy in J of the current state."""
        self._mujoco.mj_forward(self.model, self.data)
        return float(self.data.energy[1]), float(self.data.energy[0])

    def motor_angles(self) -> np.ndarray:
        return self._mjcf.motor_angles(self.model, self.data)


#: The engines by name: (geometry, time step, constant torques) -> an engine.
ENGINES: dict[str, Callable[..., DrakeEngine | MujocoEngine]] = {
    "drake_sap": DrakeEngine,
    "drake_sap_distance": lambda g, h, T: DrakeEngine(g, h, T, "distance"),
    "mujoco_rk4": lambda g, h, T: MujocoEngine(g, h, T, "RK4"),
    "mujoco_implicitfast": lambda g, h, T: MujocoEngine(g, h, T, "implicitfast"),
}


def simulate(
    engine: str,
    scenario: OpenLoopCase,
    time_step: float,
    geometry: StewartGeometry | None = None,
    sample_times=SAMPLE_TIMES_S,
) -> Run:
    """Run ``scenario`` on ``engine`` (a key of :data:`ENGINES`) at ``time_step`` s.

    Returns:
        :class:`Run` with poses at ``sample_times`` (s, increasing, multiples of
        CHECK_PERIOD_S), the energy change and closure error at the last one.
    Raises:
        InvalidConfigError: MuJoCo missing for a MuJoCo engine; a bad time step.
        UnreachablePoseError: the scenario's start pose cannot be reached.
    """
    geometry = geometry or StewartGeometry()
    torques = scenario.torques(geometry)
    sim = ENGINES[engine](geometry, time_step, torques)
    sim.assemble(np.asarray(scenario.x0))
    theta0 = sim.motor_angles()
    E0 = sum(sim.energies())
    sample_times = np.asarray(sample_times, dtype=float)
    n_checks = int(round(sample_times[-1] / CHECK_PERIOD_S))
    wanted = {int(round(t / CHECK_PERIOD_S)): k for k, t in enumerate(sample_times)}
    x = np.empty((len(sample_times), 6))
    closure, wall = sim.closure(), 0.0
    for k in range(1, n_checks + 1):
        t0 = time.perf_counter()
        sim.advance_to(k * CHECK_PERIOD_S)
        wall += time.perf_counter() - t0
        closure = max(closure, sim.closure())
        if k in wanted:
            x[wanted[k]] = sim.pose()
    kinetic, potential = sim.energies()
    work = float(torques @ (sim.motor_angles() - theta0))
    return Run(
        engine=getattr(sim, "name", engine),
        scenario=scenario.name,
        time_step_s=time_step,
        t=sample_times,
        x=x,
        energy_change=(kinetic + potential - work - E0) / kinetic,
        max_closure_m=closure,
        wall_s=wall,
        sim_s=float(sample_times[-1]),
    )


def pose_errors(x, x_ref) -> tuple[np.ndarray, np.ndarray]:
    """Position error |p - p_ref| in m and rotation angle of R_ref^T R in rad, each (...)."""
    from scipy.spatial.transform import Rotation

    x, x_ref = np.asarray(x, dtype=float), np.asarray(x_ref, dtype=float)
    R = kinematics.rotation_rpy(x[..., :3])
    R_ref = kinematics.rotation_rpy(x_ref[..., :3])
    R_rel = np.swapaxes(R_ref, -1, -2) @ R
    angle = Rotation.from_matrix(R_rel.reshape(-1, 3, 3)).magnitude().reshape(R_rel.shape[:-2])
    return np.linalg.norm(x[..., 3:] - x_ref[..., 3:], axis=-1), angle


def observed_order(steps, errors, floor: float = 1e-13) -> float:
    """Least-squares slope of log(error) against log(step) (numpy.polyfit).

    Points with error <= ``floor`` (round-off) are left out; NaN if fewer than 3 remain.
    """
    steps, errors = np.asarray(steps, dtype=float), np.asarray(errors, dtype=float)
    keep = errors > floor
    if keep.sum() < 3:
        return float("nan")
    return float(np.polyfit(np.log(steps[keep]), np.log(errors[keep]), 1)[0])


def paper_run(time_step: float, duration_s: float = 2.0, rod_model: str = "bodies") -> dict:
    """The paper manoeuvre in closed loop (LQI at 1 kHz) on a plant of step ``time_step`` s,
    rods modelled as ``rod_model`` (:data:`~stewart_drake.plant.sdf.ROD_MODELS`).

    Returns:
        dict: ``rms_error`` (6,) over the second half [rad, m], ``max_closure_m``,
        ``wall_per_sim_s`` (wall s per simulated s), ``max_pitch_rad`` the largest |pitch| of
        the rods' BallRpyJoints read from the logged plant states, and
        ``max_pitch_no_spin_rad`` the same from :func:`.ball_joints.rod_ball_rpy` of the logged
        poses (rods without spin); their difference is the spin the rods pick up (NaN when the
        rods are no bodies: they have no ball joints).
    Raises:
        InvalidConfigError: 1 ms is not a whole multiple of ``time_step``.
    """
    from ..plant import ball_joints
    from ..run.result import collect_result
    from ..run.scenario import Scenario
    from ..run.simulate import build_simulator
    from ..station import guard

    config = Scenario(duration_s=duration_s, rod_model=rod_model)
    config.plant.time_step = time_step
    config.state_log_period_s = config.log_period_s  # the largest pitch over every sample
    sd, simulator = build_simulator(config)
    wall0 = time.perf_counter()
    guard.advance(sd, simulator, lambda: simulator.AdvanceTo(duration_s))
    wall = time.perf_counter() - wall0
    root = simulator.get_context()
    result = collect_result(sd, root, wall)
    states = sd.loggers["state"].FindLog(root).data().T
    context = sd.plant.CreateDefaultContext()
    nq = sd.plant.num_positions()
    pitch = 0.0 if sd.handles.rod_balls else float("nan")
    for state in states if sd.handles.rod_balls else ():
        sd.plant.SetPositions(context, state[:nq])
        pitch = max(pitch, max(abs(joint.get_angles(context)[1]) for joint in sd.handles.rod_balls))
    geometry = robot_geometry(config)
    no_spin = np.abs(ball_joints.rod_ball_rpy(geometry, result.x[:, :6])[..., 1]).max()
    return {
        "rms_error": np.asarray(result.metrics["rms_error"]),
        "max_closure_m": result.metrics["max_closure_m"],
        "wall_per_sim_s": wall / duration_s,
        "max_pitch_rad": float(pitch),
        "max_pitch_no_spin_rad": float(no_spin),
    }
