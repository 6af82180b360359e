"""Data set and training of the ANN tuner from closed-loop runs (paper section III.D).

A **run record** is a dict describing one closed-loop run at fixed weights:

    omega_Q   float > 0       the run's state weight (eq. 27)
    omega_R   float > 0       the run's torque weight (eq. 27)
    t         (N,)            sample times, s, increasing
    rho       (N, 12)         density features [rho_e, rho_T] at t (:mod:`.features`)
    cost_e    (N,)            e^T Q_1 e at t: the state part of eq. 26's summand at omega_Q = 1
                              (normalized units, Q_1 = ``LqiScales.Q_unit()``)
    cost_u    (N,)            u^T R_1 u at t: the torque part at omega_R = 1

so that the cost of a window W at weights (omega_Q, omega_R) is, by eq. 26,
J_W(omega_Q, omega_R) = sum_{k in W} omega_Q cost_e[k] + omega_R cost_u[k] (:func:`window_cost`).

Label modes (:func:`build_dataset`):

* ``"paper"``: every sample is labelled with its own run's (omega_Q, omega_R), as the paper does.
* ``"best_cost"``: the runs share the reference trajectory and the time base; the time axis is
  cut into windows of ``window_s``, and in each window *every* run's samples are labelled with
  the (omega_Q, omega_R) of the run with the lowest window cost J_W(w_Q, w_R) at one fixed
  common weighting, (w_Q, w_R) = ``common_weights`` (default (1, 1)); ties go to the first run
  in the list. Why a common weighting: docs/paper_notes.md, "Section III.D: the estimator's
  outputs and labels".

Targets are y = log10 [omega_Q, omega_R]; the network (:mod:`.tuner`) is trained on them by
back-propagation (mini-batch Adam, MSE), with a seeded 70/30 random split (paper section III.D).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InvalidConfigError
from ..control.features import N_FEATURES
from ..control.tuner.ann import ANN_LOG10_MAX, ANN_LOG10_MIN, TunerModel, build_mlp
from ..control.tuner.network import save_tuner

LABEL_MODES = ("paper", "best_cost")
RUN_KEYS = ("omega_Q", "omega_R", "t", "rho", "cost_e", "cost_u")
OUTPUT_NAMES = ("omega_Q", "omega_R")

__all__ = [
    "Dataset",
    "LABEL_MODES",
    "RUN_KEYS",
    "build_dataset",
    "r2_scores",
    "save_tuner",
    "train",
    "window_cost",
]


@dataclass
class Dataset:
    """Features and log10 weight labels for training the tuner.

    Attributes:
        rho: (N, 12) density features, dimensionless.
        y: (N, 2) targets log10 [omega_Q, omega_R], in [-1, 1].
        run_index: (N,) index of the run each sample comes from.
        mode: label mode, "paper" or "best_cost".
        info: JSON-serializable description (counts of each label pair, window, weighting).
    """

    rho: np.ndarray
    y: np.ndarray
    run_index: np.ndarray
    mode: str
    info: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.rho)


def _check_run(i: int, run: dict) -> dict:
    missing = [k for k in RUN_KEYS if k not in run]
    if missing:
        raise InvalidConfigError(f"run {i} lacks keys {missing}; a run record needs {RUN_KEYS}")
    out = {k: np.asarray(run[k], dtype=float) for k in RUN_KEYS}
    for name in ("omega_Q", "omega_R"):
        w = out[name]
        if w.shape != () or not (np.isfinite(w) and 10**ANN_LOG10_MIN <= w <= 10**ANN_LOG10_MAX):
            raise InvalidConfigError(
                f"run {i}: {name} must be a number in [0.1, 10] (the range "
                f"the tuner can output), got {run[name]!r}"
            )
    n = out["t"].shape
    shapes = {"t": n, "rho": n + (N_FEATURES,), "cost_e": n, "cost_u": n}
    for name, shape in shapes.items():
        if len(n) != 1 or out[name].shape != shape:
            raise InvalidConfigError(
                f"run {i}: {name} has shape {out[name].shape}, expected {shape} with N = len(t)"
            )
        if not np.all(np.isfinite(out[name])):
            raise InvalidConfigError(
                f"run {i}: {name} has non-finite values; the run diverged, "
                f"drop it or collect it again"
            )
    if np.any(out["cost_e"] < 0) or np.any(out["cost_u"] < 0):
        raise InvalidConfigError(f"run {i}: cost_e and cost_u are quadratic forms, must be >= 0")
    if n[0] < 1 or np.any(np.diff(out["t"]) <= 0):
        raise InvalidConfigError(f"run {i}: t must be non-empty and strictly increasing")
    return out


def window_cost(run: dict, omega_Q: float, omega_R: float, window_s: float) -> np.ndarray:
    """Cost J of eq. 26 summed over consecutive windows of a run.

    Args:
        run: run record (module docstring); uses t, cost_e, cost_u.
        omega_Q, omega_R: weights of eq. 27 applied to the unit-weight costs.
        window_s: window length, s; window j holds the samples with
            j <= (t - t[0]) / window_s < j + 1.
    Returns:
        (n_windows,) J_j = sum over window j of omega_Q cost_e + omega_R cost_u (normalized units).
    Raises:
        InvalidConfigError: a malformed run record or window_s <= 0.
    Source: paper eq. 26 restricted to a window.
    """
    if not (np.isfinite(window_s) and window_s > 0):
        raise InvalidConfigError(f"window_s must be > 0 s, got {window_s}")
    r = _check_run(0, run)
    bins = _window_bins(r["t"], window_s)
    return np.bincount(bins, weights=omega_Q * r["cost_e"] + omega_R * r["cost_u"])


def _window_bins(t: np.ndarray, window_s: float) -> np.ndarray:
    # The 1e-9 keeps a sample that lands on a boundary (up to round-off) in the later window.
    return np.floor((t - t[0]) / window_s + 1e-9).astype(int)


def build_dataset(
    runs, mode: str = "paper", window_s: float = 0.2, common_weights=(1.0, 1.0)
) -> Dataset:
    """Training set of (rho -> log10 [omega_Q, omega_R]) from closed-loop run records.

    Args:
        runs: list of run records (module docstring for the keys).
        mode: "paper" (each sample labelled with its run's weights) or "best_cost" (each window
            labelled, in every run, with the weights of the run of lowest common-weight cost).
        window_s: best_cost only: window length, s (0.2 s = 10 tuner periods of 20 ms).
        common_weights: best_cost only: the fixed (w_Q, w_R) that makes runs comparable.
    Returns:
        :class:`Dataset` with all samples of all runs, in run order.
    Raises:
        InvalidConfigError: unknown mode, no runs, malformed records, or (best_cost) runs whose
            time bases differ.
    """
    if mode not in LABEL_MODES:
        raise InvalidConfigError(f"mode must be one of {LABEL_MODES}, got {mode!r}")
    if len(runs) == 0:
        raise InvalidConfigError("no runs: collect them first with `stewart-drake collect`")
    checked = [_check_run(i, run) for i, run in enumerate(runs)]
    omegas = np.array([[r["omega_Q"], r["omega_R"]] for r in checked])
    rho = np.concatenate([r["rho"] for r in checked])
    run_index = np.concatenate([np.full(len(r["t"]), i) for i, r in enumerate(checked)])
    info = {
        "mode": mode,
        "n_runs": len(checked),
        "n_samples": int(len(rho)),
        "run_omegas": omegas.tolist(),
    }

    if mode == "paper":
        labels = omegas[run_index]
    else:
        t0 = checked[0]["t"]
        for i, r in enumerate(checked[1:], start=1):
            if r["t"].shape != t0.shape or not np.allclose(r["t"], t0, rtol=0, atol=1e-9):
                raise InvalidConfigError(
                    f"best_cost labels compare runs sample by sample: run {i} has a different "
                    f"time base from run 0 ({len(r['t'])} vs {len(t0)} samples); collect all "
                    f"runs on the same trajectory, duration and sampling period"
                )
        w_Q, w_R = (float(w) for w in common_weights)
        J = np.array([window_cost(run, w_Q, w_R, window_s) for run in runs])  # (runs, windows)
        best = np.argmin(J, axis=0)  # first on ties
        per_sample = omegas[best[_window_bins(t0, window_s)]]  # (N0, 2)
        labels = np.tile(per_sample, (len(checked), 1))
        info.update(
            window_s=float(window_s),
            common_weights=[w_Q, w_R],
            n_windows=int(J.shape[1]),
            windows_won=np.bincount(best, minlength=len(checked)).tolist(),
        )

    pairs, counts = np.unique(labels, axis=0, return_counts=True)
    info["label_counts"] = {f"{q:g},{r:g}": int(c) for (q, r), c in zip(pairs, counts)}
    return Dataset(rho=rho, y=np.log10(labels), run_index=run_index, mode=mode, info=info)


def r2_scores(y_true, y_pred) -> dict:
    """Coefficient of determination per output and overall.

    Args:
        y_true, y_pred: (N, 2) targets and predictions (log10 [omega_Q, omega_R]).
    Returns:
        {"omega_Q": R^2, "omega_R": R^2, "overall": R^2}; per output 1 - SS_res / SS_tot about
        that output's mean, overall 1 - sum SS_res / sum SS_tot. NaN where SS_tot = 0 (a
        constant target has no variance to explain).
    """
    y_true, y_pred = np.asarray(y_true, float), np.asarray(y_pred, float)
    ss_res = np.sum((y_true - y_pred) ** 2, axis=0)
    ss_tot = np.sum((y_true - y_true.mean(axis=0)) ** 2, axis=0)

    def r2(res, tot):
        return float(1.0 - res / tot) if tot > 0 else float("nan")

    out = {name: r2(ss_res[j], ss_tot[j]) for j, name in enumerate(OUTPUT_NAMES)}
    out["overall"] = r2(ss_res.sum(), ss_tot.sum())
    return out


def _split(n: int, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    perm = np.random.default_rng(seed).permutation(n)
    n_val = int(round(val_fraction * n))
    if n_val < 1 or n - n_val < 2:
        raise InvalidConfigError(
            f"{n} samples cannot be split {1 - val_fraction:.0%}/"
            f"{val_fraction:.0%} with samples on both sides; collect more"
        )
    return np.sort(perm[n_val:]), np.sort(perm[:n_val])


def train(
    dataset: Dataset,
    seed: int = 0,
    epochs: int = 100,
    lr: float = 0.03,
    batch_size: int = 512,
    hidden: int = 10,
    activation: str = "tanh",
    val_fraction: float = 0.3,
    num_threads: int | None = 1,
    metadata: dict | None = None,
):
    """Train the tuner network by back-propagation on a seeded random train/validation split.

    Mini-batch Adam with a cosine learning-rate decay on the MSE of the unclamped log10 outputs
    (the clamp to [-1, 1] would stop gradients); losses and R^2 in the report are of the
    deployed, clamped outputs. 15k samples train in about a second on one CPU thread.

    Args:
        dataset: from :func:`build_dataset`.
        seed: seeds the split and the weight initialization (same seed, same tuner).
        epochs: passes over the training split.
        lr: initial Adam learning rate (cosine decay to 0 over the run).
        batch_size: samples per Adam step.
        hidden, activation: network shape (paper: 10, and tanh here; see
            :func:`~.tuner.ann.build_mlp`).
        val_fraction: share held out for validation (paper: 0.3).
        num_threads: torch intra-op threads during training (restored afterwards); None keeps
            torch's setting. One by default: a 12-10-2 network gains nothing from more, and on
            a shared 2-core machine 2 threads ran 4x slower than 1 (measured).
        metadata: extra JSON-serializable facts stored with the weights (e.g. feature settings).
    Returns:
        (model, report): the :class:`~.tuner.ann.TunerModel` and a dict with n_train, n_val,
        initial and final train/val MSE (log10 units), R^2 per output and overall for train and
        val, loss_history (mean training MSE of each epoch), seconds, and the settings.
    Raises:
        InvalidConfigError: bad settings or too few samples to split.
    Source: paper section III.D (one hidden layer of 10, back-propagation, 70/30 split).
    """
    _check_settings(epochs, lr, batch_size, val_fraction)
    start = time.perf_counter()
    train_idx, val_idx = _split(len(dataset), val_fraction, seed)
    x_mean = dataset.rho[train_idx].mean(axis=0)
    x_std = dataset.rho[train_idx].std(axis=0)
    x_std = np.where(x_std > 1e-12, x_std, 1.0)  # a constant feature: centre, do not scale
    z = (dataset.rho - x_mean) / x_std
    mlp, initial, history, threads = _fit_network(
        z[train_idx],
        dataset.y[train_idx],
        (x_mean, x_std),
        seed,
        epochs,
        lr,
        batch_size,
        hidden,
        activation,
        num_threads,
    )

    report = {
        "mode": dataset.mode,
        "seed": seed,
        "epochs": epochs,
        "lr": lr,
        "batch_size": batch_size,
        "hidden": hidden,
        "activation": activation,
        "val_fraction": val_fraction,
        "threads": threads,
        "n_train": int(len(train_idx)),
        "n_val": int(len(val_idx)),
    }
    meta = {**dataset.info, **(metadata or {}), **report}
    model = TunerModel.from_torch(mlp, x_mean, x_std, meta)
    for split, idx in (("train", train_idx), ("val", val_idx)):
        report.update(_split_losses(split, initial, model, dataset.rho[idx], dataset.y[idx]))
    report["loss_history"] = history
    report["seconds"] = time.perf_counter() - start
    model.metadata.update({k: report[k] for k in ("train_loss", "val_loss", "train_r2", "val_r2")})
    return model, report


def _check_settings(epochs, lr, batch_size, val_fraction) -> None:
    """Refuse settings :func:`train` cannot use (InvalidConfigError, naming them)."""
    if not (
        isinstance(epochs, int)
        and epochs >= 1
        and isinstance(batch_size, int)
        and batch_size >= 1
        and np.isfinite(lr)
        and lr > 0
    ):
        raise InvalidConfigError(
            f"epochs and batch_size must be integers >= 1 and lr > 0, got "
            f"{epochs}, {batch_size}, {lr}"
        )
    if not 0 < val_fraction < 1:
        raise InvalidConfigError(f"val_fraction must be in (0, 1), got {val_fraction}")


def _fit_network(
    z, y, scaling: tuple, seed, epochs, lr, batch_size, hidden, activation, num_threads
) -> tuple:
    """The network of :func:`train` built from ``seed`` and fitted (:func:`_fit`) on the
    normalized features z (n, 12) and targets y (n, 2) of the training split, with torch's
    intra-op threads set to ``num_threads`` meanwhile (restored afterwards).

    Returns:
        (mlp, initial, history, threads): the fitted torch network, the
        :class:`~.ann.TunerModel` of its initial weights (normalized by ``scaling`` = (x_mean,
        x_std)), the mean training MSE of each epoch, the threads used.
    """
    import torch

    threads_before = torch.get_num_threads()
    threads = num_threads or threads_before
    torch.set_num_threads(threads)
    try:
        torch.manual_seed(seed)
        mlp = build_mlp(hidden, activation)
        initial = TunerModel.from_torch(mlp, *scaling)  # for the initial losses
        history = _fit(mlp, torch.from_numpy(z), torch.from_numpy(y), epochs, lr, batch_size, seed)
    finally:
        torch.set_num_threads(threads_before)
    return mlp, initial, history, threads


def _fit(mlp, z, y, epochs: int, lr: float, batch_size: int, seed: int) -> list:
    """Mini-batch Adam with a cosine learning-rate decay on the MSE of the unclamped outputs of
    ``mlp`` on (z, y) (torch tensors), batches shuffled by ``seed``; returns the mean training
    MSE of each epoch."""
    import torch

    optimizer = torch.optim.Adam(mlp.parameters(), lr=lr)
    n_batches = -(-len(z) // batch_size)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, epochs * n_batches)
    shuffle = torch.Generator().manual_seed(seed)
    history = []
    for _ in range(epochs):
        total = 0.0
        for batch in torch.randperm(len(z), generator=shuffle).split(batch_size):
            optimizer.zero_grad()
            loss = torch.nn.functional.mse_loss(mlp(z[batch]), y[batch])
            loss.backward()
            optimizer.step()
            schedule.step()
            total += loss.item() * len(batch)
        history.append(total / len(z))
    return history


def _split_losses(split: str, initial: TunerModel, model: TunerModel, rho, y) -> dict:
    """The initial and final MSE (log10 units, clamped outputs) and R^2 of one split."""
    pred = model.predict_log10(rho)
    return {
        f"{split}_loss_initial": float(np.mean((initial.predict_log10(rho) - y) ** 2)),
        f"{split}_loss": float(np.mean((pred - y) ** 2)),
        f"{split}_r2": r2_scores(y, pred),
    }
