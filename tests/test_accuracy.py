"""The step-size study: SAP's errors shrink in proportion to the step, as docs/accuracy.md says."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from stewart_drake.analysis import accuracy
from stewart_drake.robot.geometry import X_HOME


def test_observed_order_is_the_log_log_slope():
    h = np.array([1e-3, 5e-4, 2e-4, 1e-4])
    assert accuracy.observed_order(h, 3.0 * h**1.5) == pytest.approx(1.5, abs=1e-12)
    assert np.isnan(accuracy.observed_order(h, [1e-3, 1e-4, 0.0, 1e-16]))  # round-off left out


def test_pose_errors_measure_distance_and_rotation_angle():
    x = np.array([0.1, -0.2, 0.3, 0.01, 0.02, 0.3])
    moved = x + [0, 0, 1e-9, 3e-3, 4e-3, 0]  # 1 nrad of yaw, 5 mm
    position, rotation = accuracy.pose_errors(moved, x)
    assert position == pytest.approx(5e-3, rel=1e-12)
    assert rotation == pytest.approx(1e-9, rel=1e-6)  # no arccos round-off at 1e-9


def test_sap_fall_errors_are_first_order_and_lose_one_percent_at_1_ms(geometry):
    """Measured (0.1 ms reference): 4.3e-4 and 1.9e-4 m at 1 and 0.5 ms after 0.1 s (ratio 2.2);
    energy -1.1 % and -0.55 %; closure 1.8e-5 and 4.5e-6 m (second order)."""
    fall = accuracy.SCENARIOS[0]
    ref = accuracy.simulate("drake_sap", fall, 1e-4, geometry)
    coarse = accuracy.simulate("drake_sap", fall, 1e-3, geometry)
    half = accuracy.simulate("drake_sap", fall, 5e-4, geometry)
    e_coarse = accuracy.pose_errors(coarse.x, ref.x)[0]
    e_half = accuracy.pose_errors(half.x, ref.x)[0]
    assert np.all((e_coarse / e_half > 1.8) & (e_coarse / e_half < 2.6))
    assert 3e-4 < e_coarse[1] < 6e-4  # 0.43 mm of a 49 mm fall
    assert X_HOME[5] - ref.x[1, 5] > 0.045
    assert -0.013 < coarse.energy_change < -0.009
    assert coarse.energy_change / half.energy_change == pytest.approx(2.0, rel=0.05)
    assert coarse.max_closure_m / half.max_closure_m == pytest.approx(4.0, rel=0.15)


@pytest.mark.slow
def test_benchmark_writes_the_report(tmp_path):
    """benchmarks/accuracy.py --quick end to end (about 10 s): report, plot and JSON."""
    path = Path(__file__).resolve().parent.parent / "benchmarks" / "accuracy.py"
    spec = importlib.util.spec_from_file_location("accuracy_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--quick", "--docs", str(tmp_path), "--json", str(tmp_path / "a.json")])
    text = (tmp_path / "accuracy.md").read_text()
    assert "## The default step" in text and "QUICK mode" in text
    assert (tmp_path / "accuracy.png").stat().st_size > 10_000
