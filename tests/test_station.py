"""The open station. The station's ports mean what they say, a controller written here plugs into
the Diagram by the contract, any reference works."""

from pathlib import Path

import numpy as np
import pytest
from conftest import HANG_S
from pydrake.systems.framework import LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.control.contract import (
    CONTROLLER_REGISTRY,
    ControllerContext,
    check_controller,
    register_controller,
)
from stewart_drake.references.samples import CubicSplineTrajectory
from stewart_drake.references.trajectories import as_trajectory, paper_manoeuvre
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry
from stewart_drake.run.diagram import held_station, make_stewart_diagram
from stewart_drake.run.scenario import (
    CsvReference,
    PdDriver,
    Robot,
    Scenario,
    UserController,
)
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.run.simulate import run_experiment
from stewart_drake.station.station import p_ETool

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"


# -- the station ----------------------------------------------------------------------------------


def _station_sim(scenario, x=X_HOME, T=None, wrench=None):
    return held_station(scenario, x, T, np.zeros(6) if wrench is None else wrench)


def test_station_ports_measure_the_robot():
    x = X_HOME + np.array([0.05, -0.03, 0.1, 0.01, -0.02, 0.02])
    station, simulator, ctx = _station_sim(Scenario(), x)
    simulator.AdvanceTo(0.05)
    pose = station.GetOutputPort("platform_state").Eval(ctx)
    theta = station.GetOutputPort("motor_angle").Eval(ctx)
    np.testing.assert_allclose(pose[:6], x, atol=1e-6)  # held by the holding torques
    np.testing.assert_allclose(theta, kinematics.ik(StewartGeometry(), pose[:6]), atol=1e-6)
    np.testing.assert_allclose(
        station.GetOutputPort("motor_torque_applied").Eval(ctx),
        statics.holding_torques(StewartGeometry(), x),
        rtol=1e-12,
    )
    assert station.GetOutputPort("plant_state").size() == station.plant.num_multibody_states()


def test_tool_wrench_pushes_the_platform_and_the_limit_clips_the_torque():
    scenario = Scenario(torque_limit_Nm=0.2)  # below the 0.285 N m to hold home
    station, simulator, ctx = _station_sim(scenario)
    simulator.AdvanceTo(0.05)
    np.testing.assert_allclose(station.GetOutputPort("motor_torque_applied").Eval(ctx), 0.2)
    assert station.GetOutputPort("platform_state").Eval(ctx)[5] < X_HOME[5] - 1e-3  # sags

    held = _station_sim(Scenario())
    pushed = _station_sim(Scenario(), wrench=np.array([0, 0, 0, 0, 0, 5.0]))  # 5 N up on the tool
    twisted = _station_sim(Scenario(), wrench=np.array([0, 0, 0.2, 0, 0, 0]))  # 0.2 N m about z
    for _, simulator, _ in (held, pushed, twisted):
        simulator.AdvanceTo(0.05)
    z = [s.GetOutputPort("platform_state").Eval(c) for s, _, c in (held, pushed, twisted)]
    assert abs(z[0][5] - X_HOME[5]) < 1e-6
    # The whole chain is lighter than 5 N / 9.81: the push lifts it by millimetres in 50 ms.
    assert z[1][5] - X_HOME[5] > 1e-3
    assert z[2][2] > 1e-3 and abs(z[2][5] - X_HOME[5]) < 1e-3  # a twist turns it about z (yaw)
    assert p_ETool[2] == pytest.approx(0.08)


def test_tool_load_torques_hold_the_platform_in_drake_under_the_wrench():
    """Our statics (virtual work through the wrench map) and Drake's dynamics agree: the torques
    for gravity + a tool wrench hold the pushed platform still; the gravity ones alone do not."""
    g = StewartGeometry()
    x = X_HOME + np.array([0.05, -0.03, 0.1, 0.01, -0.02, 0.02])
    wrench = np.array([0.05, -0.1, 0.2, 5.0, -3.0, 2.0])  # N m, N at the tool tip
    T = statics.tool_load_torques(g, x, wrench)
    drift = []
    for torques in (T, statics.holding_torques(g, x)):
        station, simulator, ctx = _station_sim(Scenario(), x, T=torques, wrench=wrench)
        simulator.AdvanceTo(0.05)
        drift.append(np.abs(station.GetOutputPort("platform_state").Eval(ctx)[:6] - x).max())
    assert drift[0] < 1e-6 < 1e-3 < drift[1]


def test_the_plant_falls_with_the_geometry_s_gravity():
    """Holding torques for the Moon's gravity hold a Moon robot (they would drop an Earth one)."""
    moon = Robot.from_value(StewartGeometry(gravity=1.62))
    _, simulator, ctx = _station_sim(Scenario(robot=moon))
    station_earth, sim_earth, ctx_earth = _station_sim(
        Scenario(), T=statics.holding_torques(StewartGeometry(gravity=1.62), X_HOME)
    )
    simulator.AdvanceTo(0.2)
    sim_earth.AdvanceTo(0.2)
    moon_station = simulator.get_system().GetSubsystemByName("station")
    assert abs(moon_station.GetOutputPort("platform_state").Eval(ctx)[5] - X_HOME[5]) < 1e-6
    assert station_earth.GetOutputPort("platform_state").Eval(ctx_earth)[5] < X_HOME[5] - 0.05


# -- a user's controller ----------------------------------------------------------------------


class TaskSpacePd(LeafSystem):
    """A controller written here, not in the package: task-space PD on the measured pose with the
    reference's feed-forward, T = T_ff + J^-T M_x (K_p (x_d - x) + K_d (v_d - v)), with M_x and J
    re-evaluated at the reference every step. Follows the contract: x, x_d, T_ff in; T out."""

    def __init__(self, context: ControllerContext, bandwidth_hz: float = 15.0):
        super().__init__()
        self.geometry = context.geometry
        w = 2 * np.pi * bandwidth_hz
        self.k_p, self.k_d = w * w, 2 * w
        self._x = self.DeclareVectorInputPort("x", 12)
        self._x_d = self.DeclareVectorInputPort("x_d", 18)
        self._T_ff = self.DeclareVectorInputPort("T_ff", 6)
        state = self.DeclareDiscreteState(statics.holding_torques(self.geometry, context.x_initial))
        self.DeclareStateOutputPort("T", state)
        self.DeclarePeriodicDiscreteUpdateEvent(context.period_s, context.offset_s, self._Update)

    def _Update(self, ctx, discrete_state):
        x, ref = self._x.Eval(ctx), self._x_d.Eval(ctx)
        J = kinematics.jacobian(self.geometry, ref[:6])
        M = statics.task_inertia(self.geometry, ref[:6])
        wrench = M @ (self.k_p * (ref[:6] - x[:6]) + self.k_d * (ref[6:12] - x[6:12]))
        discrete_state.set_value(0, self._T_ff.Eval(ctx) + np.linalg.solve(J.T, wrench))


def test_a_controller_written_in_the_test_runs_the_paper_manoeuvre():
    # 1 s is enough to tell (0.20 mrad, 19 um and the soft PD 12 times worse, measured); a
    # Python controller steps slowly.
    result = run_experiment(Scenario(duration_s=1.0), controller=TaskSpacePd)
    m = result.metrics
    assert m["finite"] and m["max_closure_m"] < 1e-5
    assert m["rms_error"][0] < 1e-3 and m["rms_error"][5] < 1e-4  # phi < 1 mrad, Z < 0.1 mm
    assert m["status"] == {} and result.omega is None and "gain_solves" not in m
    # A softer PD tracks worse: the parameter reaches the controller.
    register_controller("task_space_pd", TaskSpacePd)
    soft = run_experiment(
        Scenario(duration_s=1.0, controller=UserController("task_space_pd", {"bandwidth_hz": 5.0}))
    )
    assert soft.metrics["rms_error"][0] > 2 * m["rms_error"][0]
    CONTROLLER_REGISTRY.pop("task_space_pd")


def test_the_plug_in_your_controller_example_runs_as_pasted(capsys):
    """docs/station.md's example, executed as a user pastes it: it runs the paper manoeuvre,
    prints the errors, and registers its factory for scenarios."""
    import re

    text = (Path(__file__).resolve().parent.parent / "docs" / "station.md").read_text()
    (block,) = [b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "MyController" in b]
    try:
        pasted = {"__name__": "__main__"}
        exec(compile(block, "docs/station.md", "exec"), pasted)
        assert capsys.readouterr().out.strip()  # the errors, printed
        rms = np.asarray(pasted["result"].metrics["rms_error"])
        assert rms.shape == (6,) and rms[0] < 1e-3 and rms[5] < 1e-4  # tracks: < 1 mrad, 0.1 mm
        soft = run_experiment(
            Scenario(duration_s=0.5, controller=UserController("mine", {"bandwidth_hz": 10.0}))
        )
        assert soft.metrics["finite"]
    finally:
        CONTROLLER_REGISTRY.pop("mine", None)


def test_a_controller_that_breaks_the_contract_is_refused_by_port():
    class NoTorque(LeafSystem):
        def __init__(self, context):
            super().__init__()
            self.DeclareVectorInputPort("x_d", 18)

    class WrongSize(TaskSpacePd):
        def __init__(self, context):
            super().__init__(context)
            self.DeclareVectorInputPort("motor_angle", 5)

    with pytest.raises(InvalidConfigError, match=r"no output port 'T'"):
        make_stewart_diagram(Scenario(duration_s=0.1), controller=NoTorque)
    with pytest.raises(InvalidConfigError, match=r"'motor_angle' has size 5, the contract says 6"):
        make_stewart_diagram(Scenario(duration_s=0.1), controller=WrongSize)
    with pytest.raises(InvalidConfigError, match=r"'nope' is not a registered controller"):
        make_stewart_diagram(Scenario(duration_s=0.1, controller=UserController("nope")))
    with pytest.raises(InvalidConfigError, match=r"'no.such:mod' is an import path"):
        make_stewart_diagram(Scenario(duration_s=0.1, controller=UserController("no.such:mod")))
    with pytest.raises(InvalidConfigError, match=r"must return a pydrake LeafSystem"):
        check_controller(object())


def test_package_controllers_follow_the_contract():
    sd = make_stewart_diagram(Scenario(duration_s=0.1, controller=PdDriver()))
    inputs = {
        sd.controller.get_input_port(i).get_name() for i in range(sd.controller.num_input_ports())
    }
    assert inputs == {"x", "x_d", "T_ff"}  # no omega: the PD has no weights
    assert (
        make_stewart_diagram(Scenario(duration_s=0.1)).controller.status_names[2] == "gain_solves"
    )


# -- references -----------------------------------------------------------------------------------


def test_csv_and_drake_references_track_like_the_analytic_one(tmp_path):
    t = np.arange(0.0, 1.0001, 0.01)
    x = paper_manoeuvre().evaluate(t)[0]
    csv = tmp_path / "paper.csv"
    np.savetxt(
        csv, np.column_stack([t, x]), delimiter=",", header="t,phi,theta,psi,X,Y,Z", comments=""
    )
    from_csv = as_trajectory(str(csv))
    assert isinstance(from_csv, CubicSplineTrajectory) and from_csv.end_time == pytest.approx(1.0)
    probe = np.linspace(0.05, 0.95, 50)
    exact = paper_manoeuvre().evaluate(probe)
    for k, tol in enumerate((1e-6, 1e-4, 1e-2)):  # pose, rate, acceleration of a spline
        np.testing.assert_allclose(from_csv.evaluate(probe)[k], exact[k], atol=tol)
    spline = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, x.T, False)
    # Half the table's second: the three runs differ, if at all, from the first steps on.
    a = run_experiment(Scenario(duration_s=0.5, reference=CsvReference(str(csv))))
    b = run_experiment(Scenario(duration_s=0.5), reference=spline)
    c = run_experiment(Scenario(duration_s=0.5))
    np.testing.assert_allclose(a.x, b.x, atol=1e-12)  # the same spline both ways
    np.testing.assert_allclose(a.x[:, :6], c.x[:, :6], atol=5e-6)  # ... close to the analytic
    with pytest.raises(InvalidConfigError, match=r"ends at t = 1 s"):
        run_experiment(Scenario(duration_s=2.0, reference=CsvReference(str(csv))))


# -- the command ----------------------------------------------------------------------------------


def test_cli_runs_a_scenario_file_with_overrides(tmp_path, capsys):
    scenario = tmp_path / "mine.yaml"
    assert main(["scenario", "paper_ideal", "--set", "duration_s=0.3", "--out", str(scenario)]) == 0
    assert (
        main(
            [
                "run",
                "--scenario",
                str(scenario),
                "--set",
                "controller.omega_Q=10",
                "--out",
                str(tmp_path / "out"),
                "--no-progress",
            ]
        )
        == 0
    )
    assert "gain re-schedules: 31" in capsys.readouterr().out
    # The scenario's name and a hash of the overrides name the files (run_stem).
    (npz,) = (tmp_path / "out").glob("run_mine_paper_set*.npz")
    data = np.load(npz)
    assert "omega_Q: 10.0" in str(data["config"]) and data["t"][-1] == pytest.approx(0.3)
    assert main(["run", "--set", "controller.gain=1", "--no-progress"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "'gain' is not a field of LqiDriver" in err[0]


def test_cli_reference_from_a_csv_file(tmp_path, capsys):
    t = np.arange(0.0, 0.5001, 0.01)
    np.savetxt(
        tmp_path / "ref.csv",
        np.column_stack([t, paper_manoeuvre().evaluate(t)[0]]),
        delimiter=",",
        header="t,phi,theta,psi,X,Y,Z",
        comments="",
    )
    assert (
        main(
            [
                "run",
                "--trajectory-file",
                str(tmp_path / "ref.csv"),
                "--duration",
                "0.5",
                "--out",
                str(tmp_path),
                "--no-progress",
            ]
        )
        == 0
    )
    assert (tmp_path / "run_ref.npz").exists()


def test_sdf_and_diagrams_write_to_the_current_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["sdf"]) == 0 and (tmp_path / "sdf" / "rotary_stewart.sdf").stat().st_size > 1000
    assert main(["diagrams", "--dot-only"]) == 0
    assert (tmp_path / "diagrams" / "control_loop.dot").exists()


@pytest.mark.system
def test_run_with_the_tuner_needs_no_torch(tmp_path):
    """torch is the [train] extra: with it unimportable, `run --tuner ann` works and `train` says
    in one line which extra to install."""
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['torch'] = None\n"
        "from stewart_drake.cli.main import main\n"
        "import stewart_drake.evaluation.evaluation, stewart_drake.tuner.collection\n"
        f"assert main(['run', '--tuner', 'ann', '--duration', '0.1', '--no-progress', "
        f"'--out', {str(tmp_path)!r}]) == 0\n"
        # the data are checked first: pretend the folder holds a collection
        "stewart_drake.tuner.collection.load_records = lambda path: [{}, {}]\n"
        f"sys.exit(main(['train', '--data', {str(tmp_path)!r}]))\n"
    )
    argv = [sys.executable, "-c", code]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=HANG_S)
    assert proc.returncode == 2, proc.stderr
    # `run` says it is compiling when numba's cache holds no compiled step (a fresh clone)
    lines = [x for x in proc.stderr.strip().splitlines() if "compiling the LQI's" not in x]
    assert lines == [
        "stewart-drake train: `stewart-drake train` needs torch: install PyTorch's CPU build, "
        "then pip install 'stewart-drake[train]' (README: Install)"
    ]
    assert (tmp_path / "run_paper_ann.npz").exists()


def test_the_paper_tuner_runs_with_the_paper_s_gain_switching():
    from stewart_drake.control.tuning import AnnTunerDriver
    from stewart_drake.run.scenario import use_paper_tuner

    scenario = load_scenario("paper_hardware")
    assert scenario.controller.gain_transfer == "integral"  # ours, the default
    use_paper_tuner(scenario, AnnTunerDriver(period_s=0.04))
    assert scenario.controller.gain_transfer == "none"
    assert isinstance(scenario.tuner, AnnTunerDriver) and scenario.tuner.period_s == 0.04
    scenario.validate()  # raises if not
