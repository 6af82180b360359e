"""The tuner choices: each checks its fields against the run's controller and period, and wires
what drives the LQI's omega into the Diagram, read back from the built Diagram."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError, MissingFileError
from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.control.pd import PdDriver
from stewart_drake.control.tuning import AnnTunerDriver, RatioTunerDriver, WeightSchedule
from stewart_drake.run.diagram import make_stewart_diagram
from stewart_drake.run.scenario import Scenario


@pytest.mark.parametrize("tuner", [AnnTunerDriver(), RatioTunerDriver(), WeightSchedule()])
def test_a_tuner_needs_a_controller_with_the_omega_input(tuner):
    with pytest.raises(InvalidConfigError, match="omega input"):
        tuner.validate(PdDriver(), 1e-3)
    tuner.validate(LqiDriver(), 1e-3)  # raises if not


def test_a_network_tuner_s_fields_are_checked_by_name(tmp_path):
    with pytest.raises(InvalidConfigError, match="tuner.period_s"):
        AnnTunerDriver(period_s=0.0105).validate(LqiDriver(), 1e-3)  # not a whole multiple
    with pytest.raises(InvalidConfigError, match=r"tuner.feature_window must be an integer"):
        RatioTunerDriver(feature_window=0).validate(LqiDriver(), 1e-3)
    with pytest.raises(MissingFileError, match="tuner.weights"):
        AnnTunerDriver(weights=str(tmp_path / "none.npz")).validate(LqiDriver(), 1e-3)


def test_a_weight_schedule_drives_omega_held_from_each_time():
    schedule = WeightSchedule(
        t=[0.0, 0.05, 0.1], omega_Q=[1.0, 10.0, 0.1], omega_R=[1.0, 0.1, 10.0]
    )
    sd = make_stewart_diagram(Scenario(duration_s=0.2, tuner=schedule))
    source = sd.diagram.GetSubsystemByName("weight_schedule")
    context = source.CreateDefaultContext()
    for t, expected in (
        (0.0, [1, 1]),
        (0.049, [1, 1]),
        (0.05, [10, 0.1]),
        (0.12, [0.1, 10]),
        (0.2, [0.1, 10]),
    ):
        context.SetTime(t)
        np.testing.assert_allclose(source.get_output_port().Eval(context), expected)
    assert sd.tuner is source and sd.features is None


@pytest.mark.parametrize(
    "tuner, name",
    [
        (AnnTunerDriver(period_s=0.02), "ann_tuner"),
        (RatioTunerDriver(period_s=0.04), "ratio_tuner"),
    ],
)
def test_a_network_tuner_adds_its_features_and_logs_them_at_its_period(tuner, name):
    from stewart_drake.run.simulate import run_experiment

    scenario = Scenario(duration_s=0.2, tuner=tuner)
    sd = make_stewart_diagram(scenario)
    assert sd.tuner.get_name() == name and sd.features.get_name() == "features"
    result = run_experiment(scenario)
    # rho is logged where the tuner reads it: every tuner period from t = 0.
    assert result.rho.shape == (round(0.2 / tuner.period_s) + 1, 12)
    assert np.isfinite(result.rho).all() and np.all(result.rho >= 0)
    # omega moves only at the tuner's instants, within the network's clamp [0.1, 10].
    assert np.all((result.omega >= 0.1 - 1e-12) & (result.omega <= 10 + 1e-12))
