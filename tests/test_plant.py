"""The Drake plant: discrete SAP, loops closed, SDF in sync, statics agree with kinematics."""

import logging

import numpy as np
import pytest
from pydrake.multibody.plant import DiscreteContactSolver
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.plant.closed_chain import assemble, loop_closure_errors
from stewart_drake.plant.plant import add_stewart_plant, make_plant, platform_pose
from stewart_drake.plant.sdf import REFERENCE_SDF, write_sdf
from stewart_drake.robot import statics


def test_committed_sdf_equals_generated():
    assert REFERENCE_SDF.read_text() == write_sdf(), (
        "sdf/rotary_stewart.sdf is stale: run `stewart-drake sdf` to regenerate it"
    )


def test_plant_is_discrete_sap_with_six_ball_constraints():
    plant, context, handles, _, _ = make_plant()
    assert plant.is_discrete() if hasattr(plant, "is_discrete") else plant.time_step() > 0
    assert plant.time_step() == pytest.approx(1e-3)
    assert plant.get_discrete_contact_solver() == DiscreteContactSolver.kSap
    assert plant.num_constraints() == 6
    assert plant.num_actuators() == 6


def test_continuous_plant_is_refused():
    with pytest.raises(InvalidConfigError, match="discrete"):
        add_stewart_plant(DiagramBuilder(), time_step=0.0)


def test_sdf_loads_without_inertia_warning(caplog):
    with caplog.at_level(logging.WARNING):
        make_plant()
    assert not [r for r in caplog.records if "inertia" in r.getMessage().lower()]


def test_default_context_is_assembled_at_home():
    plant, context, handles, _, _ = make_plant()
    assert loop_closure_errors(plant, context, handles).max() < 1e-9


def test_assemble_closes_loops_and_measures_back(geometry, random_poses):
    plant, context, handles, _, _ = make_plant()
    rng = np.random.default_rng(3)
    for x in random_poses[:25]:
        x_dot = rng.normal(size=6) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
        assemble(plant, context, handles, x, x_dot)
        assert loop_closure_errors(plant, context, handles).max() < 1e-9
        x_m, x_dot_m = platform_pose(plant, context, handles)
        np.testing.assert_allclose(x_m, x, atol=1e-12)
        np.testing.assert_allclose(x_dot_m, x_dot, atol=1e-12)


def _hold(geometry, x, T, duration=0.5, rods="bodies"):
    builder = DiagramBuilder()
    plant, _, handles = add_stewart_plant(builder, geometry, rod_model=rods)
    source = builder.AddSystem(ConstantVectorSource(T))
    builder.Connect(source.get_output_port(), handles.actuation_port)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    assemble(plant, context, handles, x)
    simulator.AdvanceTo(duration)
    return platform_pose(plant, context, handles)[0], loop_closure_errors(plant, context, handles)


def test_plant_holds_random_poses_with_virtual_work_torques(geometry, random_poses):
    for x in random_poses[:4]:
        x_end, closure = _hold(geometry, x, statics.holding_torques(geometry, x))
        assert np.abs(x_end[3:] - x[3:]).max() < 1e-4  # < 0.1 mm drift in 0.5 s
        assert np.abs(x_end[:3] - x[:3]).max() < 1e-3
        assert closure.max() < 1e-5


def test_platform_only_torques_do_not_hold(geometry):
    """The loop closes on physics, not by accident: 35 % too little torque lets it sag."""
    x = np.array([0, 0, 0, 0, 0, 0.30])
    x_end, _ = _hold(geometry, x, 0.65 * statics.holding_torques(geometry, x), duration=0.3)
    assert x_end[5] < x[5] - 5e-3


# -- rods as distance constraints ----------------------------------------------------------------


def test_distance_rods_leave_the_cranks_and_platform_with_six_constraints_and_the_rods_mass(
    geometry,
):
    """12 velocities and 6 distance constraints; the rods' mass is carried at their ends: the
    robot's total mass and the moving parts' centre of mass at home equal the bodies plant's."""
    from stewart_drake.plant.plant import DISTANCE_NQ, DISTANCE_NV

    bodies, b_context, b_handles, _, _ = make_plant(geometry)
    plant, context, handles, _, _ = make_plant(geometry, rod_model="distance")
    assert (plant.num_positions(), plant.num_velocities()) == (DISTANCE_NQ, DISTANCE_NV)
    assert plant.num_constraints() == 6 and handles.rods == () and handles.rod_balls == ()
    assert plant.CalcTotalMass(context) == pytest.approx(bodies.CalcTotalMass(b_context), 1e-12)
    com_b = bodies.CalcCenterOfMassPositionInWorld(b_context)
    np.testing.assert_allclose(plant.CalcCenterOfMassPositionInWorld(context), com_b, atol=1e-12)
    crank = plant.GetBodyByName("crank_0").default_mass()
    assert crank == pytest.approx(geometry.crank_mass + geometry.rod_mass / 2)
    assert loop_closure_errors(plant, context, handles).max() < 1e-12


def test_distance_rods_hold_random_poses_with_virtual_work_torques(geometry, random_poses):
    for x in random_poses[:3]:
        x_end, closure = _hold(geometry, x, statics.holding_torques(geometry, x), rods="distance")
        assert np.abs(x_end[3:] - x[3:]).max() < 1e-4
        assert np.abs(x_end[:3] - x[:3]).max() < 1e-3
        assert closure.max() < 1e-6


def test_distance_rods_do_not_hold_with_platform_only_torques(geometry):
    x = np.array([0, 0, 0, 0, 0, 0.30])
    x_end, closure = _hold(
        geometry, x, 0.65 * statics.holding_torques(geometry, x), duration=0.3, rods="distance"
    )
    assert x_end[5] < x[5] - 5e-3 and closure.max() < 1e-5  # 1.5 um falling 10 cm


def test_a_distance_plant_run_is_drawn_with_rods_from_crank_tip_to_platform_joint(
    geometry, random_poses
):
    from stewart_drake.plant.closed_chain import assembled_positions, rod_bodies_positions

    plant, context, handles, _, _ = make_plant(geometry, rod_model="distance")
    bodies, b_context, b_handles, _, _ = make_plant(geometry)
    states = []
    for x in random_poses[:5]:
        assemble(plant, context, handles, x)
        states.append(plant.GetPositionsAndVelocities(context).copy())
    q = rod_bodies_positions(geometry, np.array(states))
    np.testing.assert_allclose(
        q, assembled_positions(bodies, b_handles, random_poses[:5]), atol=1e-9
    )
    bodies.SetPositions(b_context, q[0])
    assert loop_closure_errors(bodies, b_context, b_handles).max() < 1e-9


def test_unknown_rod_models_and_files_with_distance_rods_are_refused():
    with pytest.raises(InvalidConfigError, match="rod_model must be one of"):
        make_plant(rod_model="springs")
    with pytest.raises(InvalidConfigError, match="sdf_file models the rods as bodies"):
        add_stewart_plant(DiagramBuilder(), sdf_file=REFERENCE_SDF, rod_model="distance")


@pytest.mark.parametrize("rod_model", ["bodies", "distance"])
def test_the_closure_from_positions_alone_is_drakes(geometry, random_poses, rod_model):
    """LoopClosure (no Context) against Drake's kinematics, on configurations knocked off their
    closure by 1 cm and 0.01 rad in every coordinate (0.1 mm to a few cm of error)."""
    from stewart_drake.plant.closed_chain import LoopClosure

    plant, context, handles, _, _ = make_plant(geometry, rod_model=rod_model)
    closure = LoopClosure(handles)
    rng = np.random.default_rng(5)
    for x in random_poses[:5]:
        assemble(plant, context, handles, x)
        q = plant.GetPositions(context) + rng.normal(size=plant.num_positions()) * 1e-2
        plant.SetPositions(context, q)
        drake = loop_closure_errors(plant, context, handles)
        assert drake.min() > 1e-4
        np.testing.assert_allclose(closure(q), drake, atol=1e-12)
