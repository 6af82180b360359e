"""A servo on its bench (stewart_drake/actuator): its logs read and checked (a battery of wrong
files refused, each naming what is wrong), its model's file, the identification recovering a
servo whose parameters the test chose (within 10 %, from logs its own bench made), and the
``servo`` command as a user runs it."""

import json
import math

import numpy as np
import pytest

from stewart_drake.actuator.bench import BenchModel, errors, replay
from stewart_drake.actuator.bench_log import BenchLog, read_bench_log, write_bench_log
from stewart_drake.actuator.identify import Identified, identify
from stewart_drake.actuator.model_file import read_model, write_model
from stewart_drake.base.errors import CorruptFileError, InvalidConfigError
from stewart_drake.cli import main as cli

SERVO = "XL330-M288-T"
#: The servo the test hides in its logs: the XL330's datasheet constant (0.52 N m / 1.47 A), a
#: winding of 2.8 ohm, a rotor of 2e-3 kg m^2 at the shaft, a zero 10 mrad off, and friction.
HIDDEN = BenchModel(
    SERVO, "m1", 0.35, 2.8, 0.002, 0.01, {"coulomb_Nm": 0.01, "viscous_Nm_s_per_rad": 0.006}
)
COUNT = 2 * math.pi / 4096


def _bench_log(kp: float, shape: str, model: BenchModel = HIDDEN, seconds: float = 4.0):
    """What the bench records of ``model`` (0.49 kg at 0.1 m, 7.4 V) following ``shape`` at gain
    ``kp``: the angles its encoder reads, in whole counts."""
    t = np.arange(0.0, seconds, 0.005)
    goal = {
        "sin": 1.2 * np.sin(math.pi * t),
        "chirp": 0.9 * np.sin(2 * math.pi * (0.3 + 0.3 * t) * t),
        "step": np.where(t > 0.3, 1.0, 0.0),
    }[shape]
    on = np.ones(t.size, bool)
    blank = BenchLog("", 0.49, 0.1, 0.0, kp, 7.4, "xl330", shape, t, goal, np.zeros(t.size), on)
    q = np.round(replay(model, blank) / COUNT) * COUNT
    return BenchLog("", 0.49, 0.1, 0.0, kp, 7.4, "xl330", f"{shape} kp {kp:g}", t, goal, q, on)


@pytest.fixture(scope="module")
def bench_logs():
    return [_bench_log(kp, s) for kp in (100, 400) for s in ("sin", "chirp", "step")]


def test_identification_recovers_the_hidden_servo_within_ten_percent(bench_logs):
    """Six logs of the hidden servo (two gains, three motions): the search finds each of its
    parameters within 10 % (the zero within 1 mrad), and its replay within a count of the
    logs; a servo twice as stiff (k doubled) would be 30 times further."""
    found = identify(bench_logs, SERVO, "m1", seed=1, generations=50)
    m = found.model
    for name in ("k_Nm_per_A", "resistance_ohm", "armature_kg_m2"):
        assert getattr(m, name) == pytest.approx(getattr(HIDDEN, name), rel=0.1), name
    assert abs(m.q_offset_rad - HIDDEN.q_offset_rad) < 1e-3
    for name, value in HIDDEN.friction.items():
        assert m.friction[name] == pytest.approx(value, rel=0.1), name
    assert found.mae_rad < COUNT
    wrong = BenchModel(SERVO, "m1", 0.7, 2.8, 0.002, 0.01, dict(HIDDEN.friction))
    far = np.mean([errors(replay(wrong, log), log)["mae_rad"] for log in bench_logs])
    assert far > 30 * found.mae_rad


def test_a_replay_of_the_true_servo_is_within_a_count_and_of_another_is_not(bench_logs):
    log = bench_logs[0]
    e = errors(replay(HIDDEN, log), log)
    assert e["mae_rad"] <= 0.5 * COUNT and e["peak_rad"] <= 0.5 * COUNT + 1e-12
    heavy = BenchModel(SERVO, "m1", 0.35, 2.8, 0.02, 0.01, dict(HIDDEN.friction))
    assert errors(replay(heavy, log), log)["mae_rad"] > 10 * COUNT
    # the figures by hand: the mean, the root mean square and the largest of |simulated - log|
    shifted = log.q + np.where(np.arange(log.q.size) % 2 == 0, 0.003, -0.001)
    by_hand = errors(shifted, log)
    assert by_hand["mae_rad"] == pytest.approx(0.002, rel=1e-3)
    assert by_hand["rms_rad"] == pytest.approx(math.sqrt((0.003**2 + 0.001**2) / 2), rel=1e-3)
    assert by_hand["peak_rad"] == pytest.approx(0.003)


# -- the log's file ---------------------------------------------------------------------------


def _raw(**changes):
    entries = [
        {"timestamp": 0.005 * i, "goal_position": 0.01 * i, "position": 0.0, "torque_enable": True}
        for i in range(30)
    ]
    data = {"mass": 0.49, "length": 0.1, "kp": 200, "vin": 7.4, "entries": entries}
    data.update(changes)
    return data


def test_a_log_reads_back_as_written(tmp_path, bench_logs):
    path = write_bench_log(tmp_path / "log.json", bench_logs[1])
    log = read_bench_log(path)
    np.testing.assert_array_equal(log.q, bench_logs[1].q)
    np.testing.assert_array_equal(log.goal, bench_logs[1].goal)
    assert (log.kp, log.mass_kg, log.name) == (100, 0.49, "log.json")
    assert log.supply_V == pytest.approx(7.4, rel=1e-12)
    assert log.inertia_kg_m2 == pytest.approx(0.49 * 0.01)
    assert log.gravity_Nm == pytest.approx(0.49 * 9.80665 * 0.1)


def test_the_supply_is_the_measured_one_where_the_log_has_it(tmp_path):
    data = _raw()
    for entry in data["entries"]:
        entry["input_volts"] = 7.2
    (tmp_path / "v.json").write_text(json.dumps(data))
    assert read_bench_log(tmp_path / "v.json").supply_V == pytest.approx(7.2)
    (tmp_path / "n.json").write_text(json.dumps(_raw()))
    assert read_bench_log(tmp_path / "n.json").supply_V == 7.4


BAD_LOGS = {
    "not an object": ([1, 2], "not an object"),
    "no mass": ({k: v for k, v in _raw().items() if k != "mass"}, "it has no 'mass'"),
    "no length": (_raw(length=0), "length is 0.0, not a finite number above 0"),
    "a string kp": (_raw(kp="400"), "kp is '400', not a number"),
    "a NaN supply": (_raw(vin=float("nan")), "vin is nan"),
    "a negative arm": (_raw(arm_mass=-1), "arm_mass is -1.0"),
    "too short": (_raw(entries=_raw()["entries"][:5]), "5 samples, fewer than the 20"),
    "entries not a list": (_raw(entries={"a": 1}), "entries holds dict"),
}


@pytest.mark.parametrize("name", BAD_LOGS)
def test_a_wrong_log_is_refused_naming_what_is_wrong(tmp_path, name):
    data, words = BAD_LOGS[name]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data).replace("NaN", "NaN"))
    with pytest.raises(CorruptFileError) as err:
        read_bench_log(path)
    assert words in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize(
    "entry, words",
    [
        ({"timestamp": 0.0, "position": 0.0, "torque_enable": True}, "has no 'goal_position'"),
        ({"timestamp": 0.0, "goal_position": None, "position": 0.0}, "goal_position is None"),
        ({"timestamp": 0.0, "goal_position": 0, "position": 0, "torque_enable": "yes"}, "yes"),
    ],
)
def test_a_wrong_sample_is_named_by_its_index(tmp_path, entry, words):
    data = _raw()
    data["entries"][7] = entry
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(CorruptFileError, match="entry 7") as err:
        read_bench_log(tmp_path / "bad.json")
    assert words in str(err.value)


def test_timestamps_that_do_not_increase_are_refused_where_they_stop(tmp_path):
    data = _raw()
    data["entries"][12]["timestamp"] = data["entries"][11]["timestamp"]
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(CorruptFileError, match="do not increase at entry 12"):
        read_bench_log(tmp_path / "bad.json")


def test_a_folder_random_bytes_and_an_empty_file_are_refused(tmp_path):
    with pytest.raises(CorruptFileError, match="folder"):
        read_bench_log(tmp_path)
    (tmp_path / "r.json").write_bytes(bytes(range(256)))
    with pytest.raises(CorruptFileError, match="not JSON|not UTF-8"):
        read_bench_log(tmp_path / "r.json")
    (tmp_path / "e.json").write_text("")
    with pytest.raises(CorruptFileError, match="empty"):
        read_bench_log(tmp_path / "e.json")


# -- the model's file -------------------------------------------------------------------------


def test_a_model_reads_back_as_written_with_the_logs_it_came_from(tmp_path, bench_logs):
    from stewart_drake.actuator.identify import Identified

    found = Identified(HIDDEN, 0.001, 10, ("a.json", "b.json"))
    model, logs = read_model(write_model(tmp_path / "m.json", found, seed=3))
    assert model == HIDDEN and logs == ("a.json", "b.json")
    data = json.loads((tmp_path / "m.json").read_text())
    assert data["seed"] == 3 and data["mae_rad"] == 0.001


@pytest.mark.parametrize(
    "change, words",
    [
        ({"format": "other"}, "format is not"),
        ({"version": 2}, "version 2"),
        ({"k_Nm_per_A": "0.3"}, "k_Nm_per_A is '0.3'"),
        ({"resistance_ohm": -1.0}, "resistance_ohm must be > 0"),
        ({"servo": "XM999"}, "the bench knows"),
        ({"model_class": "m9"}, "model class 'm9'"),
        ({"friction": {"load": 0.1}}, "m1 has no friction term load"),
        ({"friction": {"coulomb_Nm": -0.1}}, "coulomb_Nm must be >= 0"),
        ({"friction": [1]}, "not an object of terms"),
        ({"identified_on": "a.json"}, "not a list of names"),
    ],
)
def test_a_wrong_model_file_is_refused_naming_what_is_wrong(tmp_path, change, words):
    from stewart_drake.actuator.identify import Identified

    path = write_model(tmp_path / "m.json", Identified(HIDDEN, 0.001, 1, ("a",)), 0)
    data = json.loads(path.read_text())
    data.update(change)
    path.write_text(json.dumps(data))
    with pytest.raises(CorruptFileError) as err:
        read_model(path)
    assert words in str(err.value)


def test_an_unknown_servo_or_class_is_refused_before_the_search(bench_logs):
    with pytest.raises(InvalidConfigError, match="the bench knows XL330-M288-T, XM430-W350-T"):
        identify(bench_logs, "XL430-W250-T")  # a bus servo without Current Control Mode
    with pytest.raises(InvalidConfigError, match="choose one of m1"):
        identify(bench_logs, SERVO, "m7")
    with pytest.raises(InvalidConfigError, match="at least one bench log"):
        identify([], SERVO)


def test_a_search_has_settled_when_its_best_error_stops_falling():
    """Settled: the best error fell by under 1 % of itself over the last tenth of the search
    (at least 10 generations); a search that short cannot tell."""
    from stewart_drake.actuator.identify import has_settled, settling_window

    assert (settling_window(50), settling_window(150), settling_window(400)) == (10, 15, 40)
    flat = [2.0] * 30 + [1.0] * 20
    assert has_settled(flat)
    assert not has_settled([1.0] * 40 + [0.98] * 10)  # 2 % over the last 10 of 50
    assert has_settled([1.0] * 39 + [0.98] * 11)  # the same fall 11 back: outside them
    assert has_settled([1.0] * 40 + [0.991] * 10)  # 0.9 %
    assert not has_settled([1.0] * 40 + [0.989] * 10)  # 1.1 %
    # 400 generations: judged over the last 40, so a fall 30 back counts, one 50 back not
    assert not has_settled([1.0] * 370 + [0.9] * 30)
    assert has_settled([1.0] * 350 + [0.9] * 50)
    assert not has_settled([1.0] * 10) and not has_settled([])
    # or a fall under a tenth of an encoder count (1e-3 rad here), whatever its share
    small = [1e-3] * 40 + [0.9e-3] * 10  # 10 %, 1e-4 rad
    assert not has_settled(small) and not has_settled(small, count_rad=0.99e-3)
    assert has_settled(small, count_rad=1.01e-3)
    # what the command says of each
    from stewart_drake.actuator.command import _search_line

    settled = Identified(HIDDEN, 1e-3, 1, ("a",), settled=True, generations=400)
    assert _search_line(settled).startswith("the search had settled: over its last 40 of 400")
    going = Identified(HIDDEN, 1e-3, 1, ("a",), settled=False, generations=150)
    line = _search_line(going)
    assert "over its last 15 of 150 generations its best error still fell by over 1%" in line
    assert line.endswith("run it again with more --generations")


# -- the command ------------------------------------------------------------------------------


def test_identify_then_replay_as_a_user_runs_them(tmp_path, capsys, bench_logs):
    paths = [write_bench_log(tmp_path / f"{i}.json", log) for i, log in enumerate(bench_logs)]
    out = tmp_path / "model.json"
    argv = ["servo", "identify", *map(str, paths[:4]), "--servo", SERVO, "--model-class", "m1"]
    assert cli.main([*argv, "--generations", "25", "--no-progress", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "(identified on it)" in said and f"wrote {out}" in said
    model, seen = read_model(out)
    assert seen == tuple(p.name for p in paths[:4])
    png = tmp_path / "replay.png"
    argv = ["servo", "replay", *map(str, paths), "--model", str(out), "--plot", str(png)]
    assert cli.main(argv) == 0
    said = capsys.readouterr().out
    assert "mean over the 4 logs it was identified on" in said
    assert "mean over the 2 logs held out of its identification" in said
    assert png.stat().st_size > 10_000


def test_the_command_refuses_in_one_line(tmp_path, capsys, bench_logs):
    path = write_bench_log(tmp_path / "0.json", bench_logs[0])
    argv = ["servo", "identify", str(path), "--servo", "XM999", "--out", str(tmp_path / "m")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the bench knows XL330-M288-T" in err[0]
    assert cli.main(["servo", "replay", str(path), "--model", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a valid servo model file" in err[0]


# -- commissioning over the bus ---------------------------------------------------------------


def _emulated_excitation(seed: int, shares=(1.0,), seconds: float = 4.0):
    """Bench logs of an XM430-W350-T as it is (drawn from ``seed``), 1 kg at 0.15 m, excited
    over the emulated bus on its own clock (10 ms a write): (logs, the hidden servo, the
    backend)."""
    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    from stewart_drake.actuator.commissioning import (
        Pendulum,
        excitation_current,
        excite,
        safe_amplitude_A,
    )
    from stewart_drake.station.bus.driver import DynamixelBus
    from stewart_drake.station.bus.emulator import BusEmulator
    from stewart_drake.station.bus.emulator_config import EmulatorConfig
    from stewart_drake.station.bus.servo_models import BenchServos
    from stewart_drake.station.bus.servos import servo_spec

    spec = servo_spec("XM430-W350-T")
    hidden = EmulatorConfig(seed=seed).draw(spec, 1)
    bench = Pendulum(1.0, 0.15)
    logs = []
    for share in shares:
        backend = BenchServos(hidden, bench.mass_kg, bench.length_m, q_offset_rad=[0.01])
        with BusEmulator([1], spec.name, backend=backend, command_step_s=0.01) as emu:
            bus = DynamixelBus(
                emu.port, 1_000_000, [1], spec.name, reply_timeout_s=HANG_BUS_S,
                watchdog_s=2.54,  # a loaded machine's pause between two writes is not a trip
            )  # fmt: skip
            t = np.arange(0.0, seconds, 0.01)
            amplitude = share * safe_amplitude_A(bench, spec.torque_constant_Nm_per_A)
            logs.append(
                excite(bus, bench, excitation_current(t, amplitude, seconds), 0.01, commanded=True)
            )
            assert emu.read_item(1, (64, 1)) == 0  # the torque off at the end
    return logs, hidden, backend


#: The emulated bus's reply timeout: a guard against a hang, not a measure of speed.
HANG_BUS_S = 5.0


def _hidden_model(hidden, backend) -> BenchModel:
    """The emulated servo's figures as a bench model of the directional class (m5)."""
    from stewart_drake.station.bus.servo_physics import FRICTION, MODEL_CLASSES

    f = hidden.friction[0]
    return BenchModel(
        "XM430-W350-T", "m5", float(hidden.k_Nm_per_A[0]), float(hidden.resistance_ohm[0]),
        backend.armature, 0.01, {n: float(f[FRICTION[n]]) for n in MODEL_CLASSES["m5"]},
        hidden.current_time_constant_s,
    )  # fmt: skip


def test_an_emulated_servo_excited_over_the_bus_replays_as_its_hidden_model():
    """The bench log an excitation over the emulated bus writes (each Goal Current held from
    its write, the arm's angle read in counts), replayed by the bench's own physics with the
    servo's hidden figures: within a count on average, the arm having swung over half a radian
    (its peak, 3.1 counts, where the arm sticks and slips: the bench's 1 ms step against the
    emulator's 0.5 ms moves when it slips; at the same step 2.3); the same replay with the motor
    constant 2 % off is 5.9 counts on average, 5 % off 15."""
    logs, hidden, backend = _emulated_excitation(seed=3)
    log = logs[0]
    assert log.mode == "current" and log.motor == "XM430-W350-T" and np.ptp(log.q) > 0.5
    assert np.max(np.abs(log.goal)) <= 0.8 * 1.0 * 9.80665 * 0.15 / (4.1 / 2.3 * 4 / 3) + 1e-9
    model = _hidden_model(hidden, backend)
    count = 2 * math.pi / 4096
    e = errors(replay(model, log), log)
    assert e["mae_rad"] <= count and e["peak_rad"] <= 4 * count
    off = BenchModel(**{**model.__dict__, "k_Nm_per_A": 1.02 * model.k_Nm_per_A})
    assert errors(replay(off, log), log)["mae_rad"] > 4 * count


def test_an_excitation_log_reads_back_and_a_log_of_another_servo_is_refused(tmp_path, capsys):
    logs, hidden, backend = _emulated_excitation(seed=1, seconds=1.0)
    path = write_bench_log(tmp_path / "xm430.json", logs[0])
    again = read_bench_log(path)
    assert again.mode == "current"
    np.testing.assert_array_equal(again.goal, logs[0].goal)
    argv = ["servo", "replay", str(path), "--model", "XL330-M288-T"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "stewart-drake servo: xm430.json logs a XM430-W350-T, not a XL330-M288-T: give the logs "
        "of that servo"
    ]


def test_excite_as_a_user_runs_it_on_the_emulator(tmp_path, capsys):
    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    out = tmp_path / "log.json"
    argv = ["servo", "excite", "--emulate", "2", "--mass", "1", "--length", "0.15"]
    assert cli.main([*argv, "--seconds", "2", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert f"wrote {out}" in said and "the emulated servo (seed 2) hid: k " in said
    assert read_bench_log(out).mode == "current"
    # identified, a bus servo's model says what its crank in the crank servo takes: k (1 - K_l)
    # over the e-Manual's stall ratio 4.1 N m / 2.3 A, the static friction budget (the sliding
    # and the Stribeck excess), K_l, as the model file holds them
    found = tmp_path / "m5.json"
    argv = ["servo", "identify", str(out), "--servo", "XM430-W350-T", "--model-class", "m5"]
    assert cli.main([*argv, "--generations", "2", "--no-progress", "--out", str(found)]) == 0
    said = capsys.readouterr().out
    model, _ = read_model(found)
    f, k = model.friction, model.k_Nm_per_A
    # two generations cannot tell: the command says so, and what to do
    assert (
        "the search had not settled: its 2 generations are too few to tell (it takes "
        "over 10)" in said
    )
    assert "run it again with more --generations" in said
    assert json.loads(found.read_text())["search_settled"] is False
    line = next(x for x in said.splitlines() if "for its crank in the crank servo" in x)
    assert line.endswith(
        f"torque_constant_scale {k * (1 - f['load_motor']) / (4.1 / 2.3):.4g}, friction_Nm "
        f"{f['coulomb_Nm'] + f['stribeck_Nm']:.4g}, friction_load_share "
        f"{f['load_motor']:.4g}"
    )
    assert cli.main(["servo", "excite", "--mass", "1", "--length", "0.1", "--out", str(out)]) == 2
    assert "give the servo's --port, or --emulate [SEED]" in capsys.readouterr().err
    argv = ["servo", "excite", "--emulate", "--mass", "1", "--length", "0.1", "--amplitude", "2"]
    assert cli.main([*argv, "--out", str(out)]) == 2
    assert "--amplitude 2: at most 1" in capsys.readouterr().err


def test_one_servo_of_a_drawn_set_is_that_servo_as_drawn_among_six():
    from stewart_drake.station.bus.emulator_config import EmulatorConfig
    from stewart_drake.station.bus.servos import servo_spec

    six = EmulatorConfig(seed=5).draw(servo_spec("XM430-W350-T"))
    for i in (0, 5):
        one = six.one(i)
        for name in ("kt_scale", "k_Nm_per_A", "resistance_ohm", "inl_counts", "inl_phase"):
            np.testing.assert_array_equal(getattr(one, name), getattr(six, name)[i : i + 1])
        np.testing.assert_array_equal(one.friction, six.friction[i : i + 1])
        assert (one.rotor_inertia_scale, one.seed) == (six.rotor_inertia_scale, 5)
    assert six.one(1).k_Nm_per_A[0] != six.one(2).k_Nm_per_A[0]
    for i in (-1, 6):
        with pytest.raises(InvalidConfigError, match="a set of 6: choose 1 to 6"):
            six.one(i)


def test_excite_takes_a_crank_of_the_robots_own_draw(tmp_path, capsys):
    """``--crank I`` excites the servo that ``robot --emulate`` puts at crank I for the same
    seed (the robot's draw taken as the emulator's process takes it, from the scenario), and
    is refused in one line outside 1-6 or without ``--emulate``."""
    pytest.importorskip("dynamixel_sdk", reason="the robot extra: pip install -e '.[robot]'")
    from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario
    from stewart_drake.station.bus.servos import servo_spec

    def robot(*sets):
        scenario = load_scenario(ROBOT_SCENARIO, ["emulator.seed=2", *sets])
        bus = scenario.bus
        return scenario.emulator.draw(servo_spec(bus.model, torque_control=False), len(bus.ids))

    out = tmp_path / "crank3.json"
    argv = ["servo", "excite", "--emulate", "2", "--mass", "1", "--length", "0.15"]
    assert cli.main([*argv, "--crank", "3", "--seconds", "1", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    drawn = robot()
    k = drawn.k_Nm_per_A[2]
    assert f"(seed 2, the robot's crank 3) hid: k {k:.4g} N m/A" in said
    # a departure set as robot takes it reaches the servo excited: its motor constant 1.3 x the
    # model's where the draw had it kt_scale x
    strong = robot("emulator.kt_scale=1.3").k_Nm_per_A[2]
    assert strong / k == pytest.approx(1.3 / drawn.kt_scale[2], rel=1e-9)
    sets = ["--set", "emulator.kt_scale=1.3", "--crank", "3", "--seconds", "1"]
    assert cli.main([*argv, *sets, "--out", str(out)]) == 0
    assert f"crank 3) hid: k {strong:.4g} N m/A" in capsys.readouterr().out
    # the robot's servos must be the ones named
    other = ["--crank", "1", "--scenario", "phantom_bus", "--out", str(out)]
    assert cli.main([*argv, *other]) == 2
    assert "phantom_bus has PM42-010-S260-R servos, not XM430-W350-T" in capsys.readouterr().err
    for crank in ("0", "7"):
        with pytest.raises(SystemExit) as stopped:
            cli.main([*argv, "--crank", crank, "--out", str(out)])
        err = capsys.readouterr().err
        assert stopped.value.code == 2 and f"--crank: invalid choice: {crank}" in err, err
    # a robot's setting without a robot's crank would be silently ignored: refused
    assert cli.main([*argv, "--set", "emulator.kt_scale=1.3", "--out", str(out)]) == 2
    assert "--set emulator.kt_scale=1.3: only with --crank" in capsys.readouterr().err
    no_emulator = ["servo", "excite", "--port", "/dev/null", "--mass", "1", "--length", "0.15"]
    assert cli.main([*no_emulator, "--crank", "2", "--out", str(out)]) == 2
    assert "only with --emulate" in capsys.readouterr().err


@pytest.mark.slow
def test_commissioning_over_the_bus_recovers_the_emulated_servos_hidden_figures():
    """Three 8 s excitations of a servo as it is (seed 3) over the emulated bus, identified as
    the directional class: its motor constant, rotor, the bench's zero, its winding, and its
    friction at rest (the static budget and its share of the motor's torque) within 10 % of
    what it hid. The current loop's lag (0.9 ms) is not among them: a 10 ms excitation holds
    each current for ten of its time constants, and the search finds anything below about 3 ms
    alike (docs/servo_bench.md)."""
    from stewart_drake.station.bus.servo_physics import FRICTION

    logs, hidden, backend = _emulated_excitation(seed=3, shares=(1.0, 0.8, 0.6), seconds=8.0)
    m = identify(logs, "XM430-W350-T", "m5", seed=0, generations=100).model
    truth = _hidden_model(hidden, backend)
    for name in ("k_Nm_per_A", "armature_kg_m2", "resistance_ohm"):
        assert getattr(m, name) == pytest.approx(getattr(truth, name), rel=0.1), name
    assert m.q_offset_rad == pytest.approx(0.01, abs=1e-3)
    f = hidden.friction[0]
    at_rest = f[FRICTION["coulomb_Nm"]] + f[FRICTION["stribeck_Nm"]]
    found = m.friction["coulomb_Nm"] + m.friction["stribeck_Nm"]
    assert found == pytest.approx(at_rest, rel=0.1)
    share = f[FRICTION["load_motor"]] + f[FRICTION["load_motor_stribeck"]]
    assert m.friction["load_motor"] + m.friction["load_motor_stribeck"] == pytest.approx(
        share, rel=0.1
    )


def test_what_the_crank_servo_takes_of_an_identified_servo():
    """An XM430-W350-T identified as M5 (k 2.5 N m/A at the shaft, the gears losing 0.29 of the
    motor's torque): its torque per ampere while it drives, 2.5 x 0.71 = 1.775 N m/A, over the
    e-Manual's stall ratio 4.1 N m / 2.3 A; its Coulomb friction the static budget, the sliding
    0.04 and the Stribeck excess 0.02; its load share 0.29. An M3 model's single load share is
    taken the same way; a servo the bus does not drive (the XL330) has none."""
    from stewart_drake.actuator.bench import crank_servo_settings

    friction = {"coulomb_Nm": 0.04, "stribeck_Nm": 0.02, "load_motor": 0.29}
    m5 = BenchModel("XM430-W350-T", "m5", 2.5, 5.2, 0.01, 0.0, friction)
    got = crank_servo_settings(m5)
    assert got["torque_constant_scale"] == pytest.approx(2.5 * 0.71 / (4.1 / 2.3), rel=1e-12)
    assert got["friction_Nm"] == pytest.approx(0.06, rel=1e-12)
    assert got["friction_load_share"] == 0.29
    m3 = BenchModel("XM430-W350-T", "m3", 2.5, 5.2, 0.01, 0.0, {"coulomb_Nm": 0.04, "load": 0.2})
    got = crank_servo_settings(m3)
    assert got["torque_constant_scale"] == pytest.approx(2.5 * 0.8 / (4.1 / 2.3), rel=1e-12)
    assert (got["friction_Nm"], got["friction_load_share"]) == (0.04, 0.2)
    assert crank_servo_settings(HIDDEN) is None
