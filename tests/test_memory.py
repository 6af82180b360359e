"""A run's memory grows with its length by a bounded amount per simulated second: the logs are
sized for the run, the full-rate signals compact, the plant state logged at its own slower
period and the reference evaluated a stretch at a time; and the estimate checked before a run
covers what it holds. Sizes, not timings."""

import numpy as np
import pytest

from stewart_drake.run import simulate as experiments
from stewart_drake.run.memory import run_memory_bytes
from stewart_drake.run.reference import StepTimes, StretchFeeder, zero_order_hold
from stewart_drake.run.result import finish_result, release_reference
from stewart_drake.run.run_logs import SignalLog
from stewart_drake.run.scenario import Scenario
from stewart_drake.run.simulate import build_simulator

DURATION_S = 0.5


@pytest.fixture(scope="module")
def short_run():
    """The default scenario (1 kHz control and logs) for 0.5 s: its Diagram, Simulator and
    result."""
    scenario = Scenario(duration_s=DURATION_S)
    sd, simulator = build_simulator(scenario)
    logs, wall = experiments.simulate(sd, simulator)
    return scenario, sd, simulator, finish_result(logs, wall)


def test_the_result_holds_a_bounded_number_of_bytes_per_simulated_second(short_run):
    scenario, sd, _, result = short_run
    samples = DURATION_S / scenario.log_period_s + 1
    assert result.t.size == samples and result.t_state.size == DURATION_S / 0.01 + 1
    # Full-rate signals in float32 with float64 times; the 86-float plant state every 10 ms.
    assert result.x.dtype == result.x_d.dtype == result.T.dtype == np.float32
    per_sample = result.nbytes() / samples
    # 0.28 kB at the log period plus 0.07 kB of state: against 1.2 kB when the state (and the
    # pose and reference in float64) was kept every millisecond.
    assert 250 < per_sample < 400, per_sample
    nq_nv = result.state.shape[1]
    assert nq_nv > 60 and result.state.nbytes / samples < nq_nv * 8 / 9


def test_the_logs_are_allocated_for_the_run_and_nothing_grows(short_run):
    scenario, sd, _, result = short_run
    logs = {
        type(s).__name__ + s.get_name(): s
        for s in sd.diagram.GetSystems()
        if isinstance(s, SignalLog)
    }
    assert set(logs) == {"SignalLoglog_signals", "SignalLoglog_state"}
    signals, state = logs["SignalLoglog_signals"], logs["SignalLoglog_state"]
    # Allocated once, two rows beyond the samples logged: no doubling as Drake's logs do.
    assert signals.t.size == signals.num_samples + 1 == result.t.size + 1
    assert state.t.size == state.num_samples + 1
    assert signals.nbytes() / signals.t.size < 160  # t 8 B, 12 + 6 + 7 + 6 + 6 float32
    # The reference is not held as a table: only the feed-forward's (48 B a control period).
    assert set(sd.reference.feeder.sources) == {"x_d", "T_ff"}
    assert sd.reference.T_ff_table.shape == (DURATION_S / 1e-3 + 2, 6)


def test_releasing_the_reference_frees_its_tables():
    # What release_reference drops must not be kept alive by a view elsewhere (a view of the
    # feed-forward table's first row once kept the whole table: 72 MB on a 25-minute trace).
    import gc
    import weakref

    sd, simulator = build_simulator(Scenario(duration_s=0.05))
    logs, wall = experiments.simulate(sd, simulator)
    ref = sd.reference
    tables = {
        "T_ff_table": weakref.ref(ref.T_ff_table),
        "breaks": weakref.ref(ref.feeder.breaks),
    }
    assert all(w() is not None for w in tables.values())
    release_reference(sd)
    gc.collect()
    assert [name for name, w in tables.items() if w() is not None] == []
    result = finish_result(logs, wall)  # the result does not need them
    assert result.x_d.shape == (result.t.size, 18) and np.all(np.isfinite(result.x_d))


def test_a_signal_log_drained_every_second_grows_when_a_run_outlasts_it():
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    builder = DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource([1.0, 2.0]))
    signals = {"y": (source.get_output_port(), np.float32)}
    log = SignalLog.add(builder, "log", signals, 0.1, 0.15)  # room for 3 samples
    assert log.t.size == 3
    simulator = Simulator(builder.Build())
    log.bind(simulator.get_context())
    simulator.AdvanceTo(2.55)
    # Drained at 1 s and 2 s (before the sink's samples of that instant: the log is added
    # first): t = 0 .. 1.9 moved, the arrays grown.
    assert log.num_samples == 20
    view = log.logger("y").FindLog(simulator.get_context())
    np.testing.assert_allclose(view.sample_times(), 0.1 * np.arange(26), atol=1e-12)
    assert view.data().shape == (2, 26) and np.all(view.data() == [[1.0], [2.0]])
    # What the sink held is gone from it: memory bounded by the drain period.
    context = log.sink.GetMyContextFromRoot(simulator.get_context())
    assert log.sink.GetLog(context).num_samples() == 0


def test_a_signal_log_initialized_again_keeps_nothing_of_the_run_before():
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    builder = DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource([1.0]))
    log = SignalLog.add(builder, "log", {"y": (source.get_output_port(), np.float32)}, 0.1, 1.0)
    simulator = Simulator(builder.Build())
    log.bind(simulator.get_context())
    simulator.AdvanceTo(0.55)  # six samples in the sink, none drained yet
    simulator.get_mutable_context().SetTime(0.0)
    simulator.Initialize()
    simulator.AdvanceTo(0.35)
    view = log.logger("y").FindLog(simulator.get_context())
    np.testing.assert_allclose(view.sample_times(), 0.1 * np.arange(4), atol=1e-12)


def test_sources_fed_a_stretch_at_a_time_are_the_zero_order_hold_of_the_table():
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    rng = np.random.default_rng(3)
    breaks, table = np.arange(23) * 1e-3, rng.standard_normal((23, 4))
    made = []

    def rows(a, b):
        made.append((a, b))
        return table[a:b]

    builder = DiagramBuilder()
    feeder = builder.AddSystem(StretchFeeder(StepTimes(23, 1e-3), {"y": rows}, stretch=5))
    source = builder.AddSystem(feeder.sources["y"])
    whole = zero_order_hold(breaks, table)
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    context = source.GetMyContextFromRoot(simulator.get_context())
    # Every row in turn (at each break, inside its interval and just before the next), then
    # past the end (the last interval's row, as the whole table's hold clamps).
    walk = (np.array([0.0, 0.5e-3, 1e-3 - 1e-9])[None, :] + breaks[:-1, None]).ravel()
    for t in (*walk, 0.022, 0.03):
        simulator.AdvanceTo(t)
        np.testing.assert_array_equal(source.get_output_port().Eval(context), whole.value(t)[:, 0])
    # Stretches of 5 rows plus the pads, fed as the run reached them.
    assert [a for a, _ in made] == [0, 0, 0, 2, 7, 12] and max(b - a for a, b in made) <= 21


def test_the_estimate_before_a_run_covers_what_a_run_holds(short_run):
    """The pre-run estimate grows per simulated second by more than a run holds per second
    (its result, which shares the logs' arrays, and the feed-forward table), with room for the
    report's intermediates; and for a 25-minute trace at 1 kHz it is at least the 1.06 GB its
    reproduction was measured to peak at."""
    scenario, sd, _, result = short_run
    slope = run_memory_bytes(Scenario(duration_s=2.0)) - run_memory_bytes(Scenario(duration_s=1.0))
    held = (result.nbytes() + sd.reference.T_ff_table.nbytes) / DURATION_S
    assert 1.5 * held < slope < 4 * held, (slope, held)
    assert 1.1e9 <= run_memory_bytes(Scenario(duration_s=1500.0)) < 2e9


def _drake_version() -> str:
    from importlib.metadata import version

    return version("drake")


@pytest.fixture(scope="module", params=[[], ["contact=true"]], ids=["no_contact", "contact"])
def dropped_run(request):
    """{name: freed} of what a short run of the robot as built (paper_hardware: delay, current
    loop, encoders, guard; with and without contact, whose guard differs) built, run the way a
    study worker runs it, after every strong reference is dropped and the garbage collected."""
    import gc
    import weakref

    from stewart_drake.run.scenario_io import load_scenario

    scenario = load_scenario("paper_hardware", ["duration_s=0.05", *request.param])
    sd, simulator = build_simulator(scenario)
    logs, wall = experiments.simulate(sd, simulator)
    release_reference(sd)
    result = finish_result(logs, wall)
    refs = {
        "diagram": weakref.ref(sd.diagram),
        "station": weakref.ref(sd.station),
        "plant": weakref.ref(sd.plant),
        "guard": weakref.ref(sd.guard),
        "root context": weakref.ref(simulator.get_context()),
        "simulator": weakref.ref(simulator),
    }
    del sd, simulator, logs, result
    gc.collect()
    return {name: ref() is None for name, ref in refs.items()}


def test_a_run_frees_what_it_built_where_drake_frees_python_systems(dropped_run):
    from stewart_drake.execution.runners import drake_frees_diagrams

    if not drake_frees_diagrams():
        pytest.skip(
            f"drake {_drake_version()} keeps every Diagram with a Python LeafSystem "
            "(drake#22515; drake 1.58 frees them)"
        )
    assert dropped_run == dict.fromkeys(dropped_run, True)


def test_the_runners_probe_says_whether_a_run_is_freed(dropped_run):
    """The probe that lets local workers run without recycling (on every Drake)."""
    from stewart_drake.execution.runners import drake_frees_diagrams

    assert dropped_run["diagram"] == drake_frees_diagrams()


def test_the_plant_handles_hold_indices_and_look_the_elements_up():
    """A pydrake body, joint or port kept in a Python object keeps its plant, and the Diagram
    around it, alive: the handles keep indices and the plant only."""
    import dataclasses

    from pydrake.multibody.tree import BallRpyJoint, RevoluteJoint, RigidBody

    from stewart_drake.plant.plant import make_plant

    plant, _, handles, _, _ = make_plant(rod_model="bodies")
    kept = [
        v
        for f in dataclasses.fields(handles)
        for v in np.ravel(np.asarray(getattr(handles, f.name), dtype=object))
    ]
    handles_of_plant = [
        type(v).__name__
        for v in kept
        if type(v).__module__.startswith("pydrake")
        and v is not plant
        and not type(v).__name__.endswith("Index")
    ]
    assert handles_of_plant == []
    assert handles.platform.name() == "platform"
    assert isinstance(handles.platform, RigidBody)
    assert [b.name() for b in handles.cranks] == [f"crank_{i}" for i in range(6)]
    assert [b.name() for b in handles.rods] == [f"rod_{i}" for i in range(6)]
    assert [type(j) for j in handles.motors] == [RevoluteJoint] * 6
    assert [j.name() for j in handles.rod_balls] == [f"rod_ball_{i}" for i in range(6)]
    assert all(type(j) is BallRpyJoint for j in handles.rod_balls)
    assert handles.actuation_port.size() == handles.n_actuators
    assert handles.desired_state_port is None


def test_step_times_made_a_stretch_at_a_time_are_the_sampled_times_to_the_bit():
    # The reference's times are not held: made again from (n, h, offset, shift) they must be
    # the numbers the sampling used, or a row would be read at another time.
    n, h, offset, lead = 1_500_003, 1e-3, 5e-4, 2.5e-4
    t_sample = np.arange(n) * h + offset
    for shift, whole in ((0.0, t_sample), (lead, t_sample + lead), (-offset, t_sample - offset)):
        times = StepTimes(n, h, offset, shift)
        np.testing.assert_array_equal(times.values(), whole)
        for a, b in ((0, 7), (1_499_990, n), (777_777, 783_000), (n - 1, n + 5)):
            np.testing.assert_array_equal(times[a:b], whole[a:b])
