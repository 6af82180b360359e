"""plant/backlash.py: the gearheads' play, as the Drake plant builds it (read back from the plant),
as it moves (the crank crosses the play under a torque no rigid gear would let through, as a
crank with no gear at all, and stops at the limits Drake was given), as the encoders read it
(the crank's angle, not the rotor's), and as a scenario gives it (the YAML field, its bounds);
without play, the plant is today's, array for array."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.plant.backlash import crank_angles, crank_rates
from stewart_drake.plant.closed_chain import assemble
from stewart_drake.plant.plant import add_stewart_plant
from stewart_drake.robot.geometry import X_HOME, StewartGeometry
from stewart_drake.robot.servo import MAX_BACKLASH_RAD, ServoModel
from stewart_drake.robot.statics import holding_torques
from stewart_drake.run.diagram import held_station
from stewart_drake.run.plan import make_plan
from stewart_drake.run.scenario import dump_scenario
from stewart_drake.run.scenario_io import load_scenario

#: 0.5 deg, a planetary gearhead's class of play.
B = float(np.radians(0.5))


def _scenario(backlash_rad=None):
    overrides = [] if backlash_rad is None else [f"hardware.motors.backlash_rad={backlash_rad!r}"]
    return load_scenario("paper_hardware", overrides)


def test_no_backlash_builds_today_s_plant_and_runs_it_to_the_same_arrays():
    """A servo with backlash 0 (the default, or said) builds the SDF's plant: no rotor, no play
    joint, the same positions, velocities and bodies; held for 50 ms under the holding torques
    the two stations' states are the same arrays, to the bit."""
    states = []
    for scenario in (_scenario(), _scenario(0.0)):
        station, simulator, _ = held_station(scenario)
        plant = station.plant
        assert (plant.num_positions(), plant.num_velocities(), plant.num_bodies()) == (31, 30, 15)
        assert station.handles.plays == () and not plant.HasBodyNamed("rotor_0")
        simulator.AdvanceTo(0.05)
        states.append(
            plant.get_state_output_port()
            .Eval(plant.GetMyContextFromRoot(simulator.get_context()))
            .copy()
        )
    assert np.array_equal(states[0], states[1])


def _play_plant(backlash_rad: float, gravity: float = 0.0):
    """A plant of the robot with the default servo and ``backlash_rad`` of play, assembled at
    home, its actuators at zero: (plant, handles, simulator, plant context)."""
    builder = DiagramBuilder()
    servo = ServoModel(backlash_rad=backlash_rad) if backlash_rad > 0 else None
    geometry = StewartGeometry(
        gravity=gravity, motor_reflected_inertia=0.0 if servo is None else servo.reflected_inertia
    )
    plant, _, handles = add_stewart_plant(builder, geometry, servo=servo)
    simulator = Simulator(builder.Build())
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    assemble(plant, context, handles, X_HOME)
    plant.get_actuation_input_port().FixValue(context, np.zeros(plant.num_actuators()))
    if handles.desired_state_port is not None:
        handles.desired_state_port.FixValue(context, np.zeros(handles.desired_state_port.size()))
    return plant, handles, simulator, context


def test_the_plant_carries_the_play_where_drake_applies_it():
    """Read back from the plant: each leg has a massless rotor on the actuated joint motor_i
    (the actuator, the reflected inertia and the viscous friction on it), and the crank on the
    rotor through play_i, a revolute joint about the same axis limited to -b/2 .. +b/2."""
    servo = ServoModel(backlash_rad=B)
    plant, handles, _, _ = _play_plant(B)
    assert (plant.num_positions(), plant.num_velocities(), plant.num_bodies()) == (37, 36, 21)
    for i, (motor, play) in enumerate(zip(handles.motors, handles.plays)):
        rotor = plant.GetBodyByName(f"rotor_{i}")
        assert motor.child_body().index() == rotor.index() and motor.parent_body().name() == "base"
        assert play.parent_body().index() == rotor.index()
        assert play.child_body().index() == handles.crank_indices[i]
        assert np.array_equal(play.revolute_axis(), motor.revolute_axis())
        assert (
            play.position_lower_limits()[0] == -B / 2 and play.position_upper_limits()[0] == B / 2
        )
        assert rotor.default_mass() == 0.0 and play.default_damping() == 0.0
        assert motor.default_damping() == servo.viscous_damping
        last = plant.GetJointActuatorByName(f"friction_{i}")
        assert last.joint().index() == motor.index()
        assert last.default_reflected_inertia() == pytest.approx(servo.reflected_inertia)
    # The loops are closed as the SDF closes them: assembled at home, no gap.
    context = plant.CreateDefaultContext()
    assert crank_angles(plant, context, handles) == pytest.approx(
        [joint.get_angle(context) for joint in handles.motors]
    )


def _push_crank_0(plant, handles, simulator, context, torque: float, times) -> list:
    """Apply ``torque`` N m to crank 0's free joint (its play, or without play its motor
    joint) and read how far it has turned since, rad, at ``times``."""
    tau = np.zeros(plant.num_velocities())
    free = handles.plays[0] if handles.plays else handles.motors[0]
    tau[free.velocity_start()] = torque
    plant.get_applied_generalized_force_input_port().FixValue(context, tau)
    q0 = free.get_angle(context)
    out = []
    for t in times:
        simulator.AdvanceTo(t)
        out.append(free.get_angle(context) - q0)
    return out


def _locked(plant, handles, simulator, context, keep_free):
    for joint in handles.motors[1:] + handles.plays[1:]:
        joint.Lock(context)
    if not keep_free:  # crank 0's motor joint too: the rotor held
        handles.motors[0].Lock(context)
    simulator.Initialize()


def test_the_crank_crosses_the_play_at_zero_gear_torque_and_stops_at_its_limits():
    """Without gravity, the other five cranks and crank 0's rotor locked, 1 mN m on crank 0:
    with a rigid gear it cannot move; with the play it moves exactly as the same crank with no
    gear at all (its motor joint free, no rotor inertia, no friction: the same angles to 1e-9
    rad while inside the play, so nothing acts through the gear there) until it meets the stop
    at +b/2, where it stays; pushed back, it crosses to -b/2. The limits are those read back
    from Drake's joint."""
    times = [0.01, 0.02, 0.05, 0.1, 0.2, 0.3]
    rigid = _play_plant(0.0)
    _locked(*rigid, keep_free=False)
    assert np.abs(_push_crank_0(*rigid, 1e-3, [0.3])).max() < 1e-12
    free = _play_plant(0.0)
    _locked(*free, keep_free=True)
    no_gear = _push_crank_0(*free, 1e-3, times)
    plant, handles, simulator, context = play = _play_plant(B)
    _locked(*play, keep_free=False)
    crossing = _push_crank_0(*play, 1e-3, times)
    assert 0 < crossing[-1] < B / 2  # still inside the play at 0.3 s
    np.testing.assert_allclose(crossing, no_gear, rtol=1e-6, atol=1e-12)
    stop = handles.plays[0].position_upper_limits()[0]
    at_stop = _push_crank_0(*play, 1e-3, [1.0, 1.5])
    assert handles.plays[0].get_angle(context) == pytest.approx(stop, abs=1e-6)
    assert at_stop[1] - at_stop[0] == pytest.approx(0.0, abs=1e-9)  # it stays there
    assert handles.motors[0].get_angle(context) == handles.motors[1].get_angle(context)
    _push_crank_0(*play, -1e-3, [3.0])
    assert handles.plays[0].get_angle(context) == pytest.approx(
        handles.plays[0].position_lower_limits()[0], abs=1e-6
    )


def test_the_encoders_read_the_crank_not_the_rotor():
    """The station's motor_angle is the crank's absolute angle (rotor + play), quantized;
    motor_rate is its rate: turning the rotor one way and the play the other leaves both
    unchanged, moving the play alone moves them by as much."""
    station, simulator, station_context = held_station(_scenario(B))
    plant, handles = station.plant, station.handles
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    q = station.plan.scenario.hardware.encoders.quantum_rad
    angle = station.GetOutputPort("motor_angle")
    before = angle.Eval(station_context).copy()
    cranks = crank_angles(plant, context, handles)
    np.testing.assert_array_equal(before, q * np.floor(cranks / q + 0.5))
    for k, (motor, play) in enumerate(zip(handles.motors, handles.plays)):
        play.set_angle(context, 0.001 * (k - 2.5))
        motor.set_angle(context, cranks[k] - play.get_angle(context))
        play.set_angular_rate(context, 0.1 * k)
        motor.set_angular_rate(context, 0.2)
    np.testing.assert_array_equal(angle.Eval(station_context), before)
    np.testing.assert_allclose(
        station.GetOutputPort("motor_rate").Eval(station_context), 0.2 + 0.1 * np.arange(6)
    )
    assert crank_rates(plant, context, handles) == pytest.approx(0.2 + 0.1 * np.arange(6))
    handles.plays[0].set_angle(context, handles.plays[0].get_angle(context) + 100 * q)
    assert angle.Eval(station_context)[0] == pytest.approx(before[0] + 100 * q, abs=q)


def test_the_station_starts_with_each_crank_on_its_loaded_flank():
    """Assembled at home, the cranks keep the IK's angles and rest on the flank that carries
    the holding torque (positive torque: the play at -b/2); held 0.2 s, they stay there."""
    station, simulator, _ = held_station(_scenario(B))
    plant, handles = station.plant, station.handles
    context = plant.GetMyContextFromRoot(simulator.get_context())
    plays = np.array([joint.get_angle(context) for joint in handles.plays])
    torques = holding_torques(station.plan.plant_geometry, X_HOME)
    np.testing.assert_array_equal(plays, -np.sign(torques) * B / 2)
    simulator.AdvanceTo(0.2)
    after = np.array([joint.get_angle(context) for joint in handles.plays])
    np.testing.assert_allclose(after, plays, atol=1e-6)


def test_the_scenario_field_round_trips_and_reaches_the_plant(tmp_path):
    scenario = _scenario(B)
    assert scenario.hardware.motors.backlash_rad == B
    dump_scenario(scenario, tmp_path / "b.yaml")
    again = load_scenario(tmp_path / "b.yaml")
    assert again.hardware.motors.backlash_rad == B
    plan = make_plan(again, with_reference=False)
    assert plan.servo.backlash_rad == B
    assert "backlash_rad: 0.0" in dump_scenario(_scenario())


@pytest.mark.parametrize("value", [-1e-3, MAX_BACKLASH_RAD * 1.01, float("nan")])
def test_a_bad_backlash_is_refused_naming_the_field(value):
    with pytest.raises(InvalidConfigError, match=r"hardware\.motors\.backlash_rad"):
        _scenario(value)
    with pytest.raises(InvalidConfigError, match=r"servo\.backlash_rad"):
        ServoModel(backlash_rad=value)


def test_the_loop_closure_and_the_replay_read_the_crank_through_the_play():
    """With the plays knocked off 0 (the rotors turned back by as much), LoopClosure from q
    alone equals Drake's kinematics; the state converted for the plant without play
    (states_without_play) puts every crank, rod and the platform where the play plant has
    them."""
    from stewart_drake.plant.closed_chain import (
        LoopClosure,
        loop_closure_errors,
        states_without_play,
    )
    from stewart_drake.plant.plant import make_plant

    plant, handles, _, context = _play_plant(B)
    rng = np.random.default_rng(0)
    for motor, play in zip(handles.motors, handles.plays):
        offset = rng.uniform(-B / 2, B / 2)
        play.set_angle(context, offset)
        motor.set_angle(context, motor.get_angle(context) - offset + 1e-4)  # a loop opened
        play.set_angular_rate(context, rng.uniform(-1, 1))
    q = plant.GetPositions(context)
    np.testing.assert_allclose(
        LoopClosure(handles)(q), loop_closure_errors(plant, context, handles), atol=1e-12
    )
    state = plant.get_state_output_port().Eval(context)
    bare, bare_context, bare_handles, _, _ = make_plant(handles.geometry)
    bare.SetPositionsAndVelocities(bare_context, states_without_play(plant, handles, state)[0])
    for name in ["platform", *(f"crank_{i}" for i in range(6)), *(f"rod_{i}" for i in range(6))]:
        X = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(name))
        X0 = bare.EvalBodyPoseInWorld(bare_context, bare.GetBodyByName(name))
        assert X.IsNearlyEqualTo(X0, 1e-12), name
        V = plant.EvalBodySpatialVelocityInWorld(context, plant.GetBodyByName(name))
        V0 = bare.EvalBodySpatialVelocityInWorld(bare_context, bare.GetBodyByName(name))
        np.testing.assert_allclose(V.get_coeffs(), V0.get_coeffs(), atol=1e-12, err_msg=name)


def test_the_emulated_servos_read_their_output_shafts():
    """The bus emulator's servos (StationServos) report the cranks' angles and rates, the
    rotors' plus the plays'."""
    from stewart_drake.live.plant_backend import StationServos, dynamixel_scenario

    servos = StationServos(dynamixel_scenario(scenario=_scenario(B)))
    station, context = servos.station, servos._plant_context
    handles = station.handles
    rotors = np.array([joint.get_angle(context) for joint in handles.motors])
    plays = np.array([joint.get_angle(context) for joint in handles.plays])
    assert plays.size == 6 and np.all(plays != 0)
    np.testing.assert_array_equal(servos.positions_rad(), rotors + plays)
    np.testing.assert_array_equal(
        servos.velocities_rad_s(), crank_rates(station.plant, context, handles)
    )


def test_with_contact_the_same_parts_may_collide_as_without_play():
    """The base and the cranks are no longer neighbours in the tree (a rotor between them), so
    Drake no longer filters their collisions by itself: the play's plant filters them, and its
    SceneGraph has the same candidate pairs as the plant without play."""

    def candidates(servo):
        builder = DiagramBuilder()
        geometry = StewartGeometry(motor_reflected_inertia=ServoModel().reflected_inertia)
        plant, scene_graph, _ = add_stewart_plant(builder, geometry, servo=servo, contact=True)
        diagram = builder.Build()
        context = scene_graph.GetMyContextFromRoot(diagram.CreateDefaultContext())
        inspector = scene_graph.get_query_output_port().Eval(context).inspector()

        def name(gid):
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(gid)).name()
            return f"{body}/{inspector.GetName(gid)}"

        return {tuple(sorted((name(a), name(b)))) for a, b in inspector.GetCollisionCandidates()}

    with_play = candidates(ServoModel(backlash_rad=B))
    assert with_play and with_play == candidates(ServoModel())
