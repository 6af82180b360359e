"""ANN tuner: numpy inference equals torch, save/load round trip, and the LeafSystem's output stays
in [0.1, 10] and never NaN."""

import numpy as np
import pytest
from conftest import needs_torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from pydrake.systems.analysis import Simulator

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control.tuner import ann as tuner_module
from stewart_drake.control.tuner.ann import AnnTuner, TunerModel
from stewart_drake.control.tuner.network import load_tuner, save_tuner


def random_model(seed=0, activation="tanh", scale=1.0) -> TunerModel:
    """A network initialized as torch's nn.Linear is (uniform in +-1/sqrt(fan_in)), with random
    normalization; scale > 1 drives the clamp. numpy only: these tests run without torch."""
    rng = np.random.default_rng(seed)

    def linear(n_out, n_in):
        bound = 1 / np.sqrt(n_in)
        return rng.uniform(-bound, bound, (n_out, n_in)), rng.uniform(-bound, bound, n_out)

    (W1, b1), (W2, b2) = linear(10, 12), linear(2, 10)
    return TunerModel(
        W1,
        b1,
        scale * W2,
        b2,
        rng.uniform(0.5, 2, 12),
        rng.uniform(0.1, 1, 12),
        activation,
        {"note": "test", "val_r2": {"overall": 0.5}},
    )


@needs_torch
@pytest.mark.parametrize("activation", ["tanh", "sigmoid"])
def test_numpy_inference_equals_torch(activation):
    import torch

    model = random_model(1, activation, scale=5.0)
    rho = np.random.default_rng(2).uniform(0, 50, (500, 12))
    with torch.no_grad():
        y_torch = model.to_torch()(torch.from_numpy((rho - model.x_mean) / model.x_std))
        y_torch = y_torch.clamp(-1, 1).numpy()
    y_numpy = model.predict_log10(rho)
    np.testing.assert_allclose(y_numpy, y_torch, rtol=0, atol=1e-6)
    assert np.max(np.abs(y_numpy - y_torch)) < 1e-12  # float64 throughout
    assert 0 < np.mean(np.abs(y_numpy) == 1.0) < 1  # the clamp was exercised
    np.testing.assert_allclose(model.predict(rho), 10.0**y_numpy, rtol=1e-15)
    again = TunerModel.from_torch(model.to_torch(), model.x_mean, model.x_std, model.metadata)
    np.testing.assert_array_equal(again.predict_log10(rho), y_numpy)  # torch round trip


def test_save_load_round_trip(tmp_path):
    model = random_model(3)
    path = save_tuner(model, tmp_path / "sub" / "tuner.npz")
    assert path.name == "tuner.npz" and path.is_file()
    loaded = load_tuner(TunerModel, path)
    rho = np.random.default_rng(4).uniform(0, 50, (200, 12))
    np.testing.assert_array_equal(loaded.predict(rho), model.predict(rho))
    assert loaded.metadata == model.metadata and loaded.activation == model.activation
    with np.load(path, allow_pickle=False) as data:  # plain arrays, no pickle
        assert set(data.files) == {
            "W1",
            "b1",
            "W2",
            "b2",
            "x_mean",
            "x_std",
            "log10_min",
            "log10_max",
            "activation",
            "format_version",
            "metadata_json",
        }
        assert data["W1"].shape == (10, 12) and data["W2"].shape == (2, 10)


def test_missing_default_weights_name_the_command(tmp_path, monkeypatch):
    monkeypatch.setattr(tuner_module, "DEFAULT_TUNER_PATH", tmp_path / "ann_tuner.npz")
    with pytest.raises(FileNotFoundError, match="stewart-drake collect && stewart-drake train"):
        load_tuner(TunerModel)
    with pytest.raises(FileNotFoundError, match="stewart-drake collect && stewart-drake train"):
        AnnTuner()
    with pytest.raises(FileNotFoundError, match="no ANN tuner weights"):
        load_tuner(TunerModel, tmp_path / "elsewhere.npz")


def test_shipped_weights_load():
    if not tuner_module.DEFAULT_TUNER_PATH.is_file():
        pytest.skip("no shipped weights yet: `stewart-drake collect && stewart-drake train`")
    model = load_tuner(TunerModel)
    omega = model.predict(np.ones(12))
    assert omega.shape == (2,) and np.all((0.1 <= omega) & (omega <= 10))


def test_bad_weights_raise():
    model = random_model()
    with pytest.raises(InvalidConfigError, match="W1"):
        TunerModel(model.W1[:, :11], model.b1, model.W2, model.b2, model.x_mean, model.x_std)
    with pytest.raises(InvalidConfigError, match="x_std"):
        TunerModel(model.W1, model.b1, model.W2, model.b2, model.x_mean, 0 * model.x_std)
    with pytest.raises(InvalidConfigError, match="non-finite"):
        TunerModel(model.W1 * np.nan, model.b1, model.W2, model.b2, model.x_mean, model.x_std)


class _Stepper:
    """AnnTuner alone, its rho input fixed; step() runs exactly one periodic update."""

    def __init__(self, model, period_s=0.02):
        self.system = AnnTuner(model, period_s=period_s)
        self.simulator = Simulator(self.system)
        self.context = self.simulator.get_mutable_context()
        self.period_s = period_s
        self.k = 0

    def step(self, rho):
        self.system.get_rho_input_port().FixValue(self.context, rho)
        self.simulator.AdvanceTo(self.k * self.period_s + self.period_s / 2)  # update at k T
        self.k += 1
        omega = self.system.get_omega_output_port().Eval(self.context)
        count = self.system.get_nonfinite_count_output_port().Eval(self.context)[0]
        return omega.copy(), count


_STEEP = _Stepper(random_model(5, scale=20.0))  # steep network: hits both clamps
_extreme = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, 1e-300, -1e308, 1e308, 50.0]),
)


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, 12, elements=_extreme))
def test_tuner_output_in_range_for_extreme_finite_inputs(rho):
    omega, count = _STEEP.step(rho)
    assert np.all(np.isfinite(omega)) and np.all((0.1 <= omega) & (omega <= 10))
    np.testing.assert_array_equal(omega, _STEEP.system.model.predict(rho))
    assert count == 0


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, 12, elements=st.floats(allow_nan=True, allow_infinity=True)))
def test_tuner_keeps_last_output_on_non_finite_features(rho):
    stepper = _Stepper(random_model(6, scale=20.0))
    good = np.linspace(0, 3, 12)
    omega_good, _ = stepper.step(good)
    omega, count = stepper.step(rho)
    assert np.all(np.isfinite(omega)) and np.all((0.1 <= omega) & (omega <= 10))
    if np.all(np.isfinite(rho)):
        assert count == 0
    else:
        np.testing.assert_array_equal(omega, omega_good)
        assert count == 1


def test_tuner_initial_output_and_period():
    stepper = _Stepper(random_model(7), period_s=0.05)
    np.testing.assert_array_equal(
        stepper.system.get_omega_output_port().Eval(stepper.context), [1.0, 1.0]
    )
    omega, _ = stepper.step(np.ones(12))
    np.testing.assert_array_equal(omega, stepper.system.model.predict(np.ones(12)))
    with pytest.raises(InvalidConfigError):
        AnnTuner(random_model(), period_s=0.0)
