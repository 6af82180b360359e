"""A run's results as files: the .npz read back, and the same logs as a table with named columns
and units (.csv for spreadsheets, .mat for MATLAB), equal to the arrays they came from."""

import numpy as np
import pytest
from scipy.io import loadmat

from stewart_drake.cli.main import main
from stewart_drake.run.result import load_result, result_columns


@pytest.mark.filterwarnings("error::tqdm.TqdmWarning")
@pytest.mark.parametrize("t_end", [0.30000049, 37.4567891, 10.0])
def test_the_progress_bar_ends_at_the_run_s_end_without_a_warning(t_end, capsys):
    """The bar's total is the run's end itself and its count the simulator's time: a total
    rounded below the end (0.30000049 s shown as 0.3) or chunks summed past it once made tqdm
    warn that it clamps ("clamping frac to range [0, 1]", seen on a bus rehearsal)."""
    import types

    from stewart_drake.run.simulate import advance

    class Simulator:  # what advance uses of Drake's
        t = 0.0

        def get_context(self):
            return types.SimpleNamespace(get_time=lambda: self.t)

        def AdvanceTo(self, t):
            self.t = t

    simulator = Simulator()
    advance(simulator, t_end, progress=True)
    assert simulator.t == pytest.approx(t_end, abs=1e-12)
    assert f"{t_end:.2f}/{t_end:.2f} sim s" in capsys.readouterr().err


def test_run_writes_its_logs_as_a_named_table_equal_to_the_arrays(tmp_path, capsys):
    assert main(["run", "--duration", "0.3", "--out", str(tmp_path), "--no-progress"]) == 0
    assert "the logs as a table:" in capsys.readouterr().out
    result = load_result(tmp_path / "run_paper.npz")
    names, units, table = result_columns(result)
    header = (tmp_path / "run_paper.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["t [s]", "phi [rad]", "theta [rad]", "psi [rad]"]
    assert "X_dot [m/s]" in header and "Z_ddot_d [m/s^2]" in header and "T1 [N m]" in header
    assert header[-3:] == ["closure [m]", "omega_Q [1]", "omega_R [1]"]  # the LQI reports them
    csv = np.loadtxt(tmp_path / "run_paper.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(csv, table)  # 17 significant digits: the doubles themselves
    np.testing.assert_array_equal(csv[:, 1:13], result.x)
    np.testing.assert_array_equal(csv[:, names.index("T0") : names.index("T5") + 1], result.T)
    mat = loadmat(tmp_path / "run_paper.mat")
    np.testing.assert_array_equal(mat["t"].ravel(), result.t)
    np.testing.assert_array_equal(mat["Z_d"].ravel(), result.x_d[:, 5])
    assert [c.item() for c in mat["columns"].ravel()] == names
    assert [u.item() for u in mat["units"].ravel()] == units


def test_a_controller_without_weights_has_no_omega_columns():
    from stewart_drake.run.result import RunResult

    n = 3
    result = RunResult(
        t=np.arange(n) * 1e-3,
        x=np.zeros((n, 12)),
        x_d=np.zeros((n, 18)),
        T=np.ones((n, 6)),
        closure=np.zeros(n),
        status=np.zeros((n, 0)),
    )
    names, units, table = result_columns(result)
    assert table.shape == (n, 1 + 12 + 18 + 6 + 1) and "omega_Q" not in names
    assert len(names) == len(units) == table.shape[1]
    with pytest.raises(ValueError):
        names.index("omega_R")


def test_runs_of_other_scenarios_or_overrides_get_files_of_their_own():
    from stewart_drake.paper.command import run_stem
    from stewart_drake.run.scenario_io import load_scenario

    hardware, ideal = load_scenario("paper_hardware"), load_scenario("paper_ideal")
    assert run_stem(hardware, "paper_hardware") == "run_paper"  # the README's run
    assert run_stem(ideal, "paper_ideal") == "run_paper_ideal_paper"
    assert run_stem(hardware, "/tmp/mine.yaml") == "run_mine_paper"
    a = run_stem(hardware, "paper_hardware", ["controller.omega_Q=10"])
    b = run_stem(hardware, "paper_hardware", ["controller.omega_Q=0.1"])
    assert a.startswith("run_paper_set") and a != b
