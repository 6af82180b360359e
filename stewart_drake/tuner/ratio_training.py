"""Our tuner's training (the tuner study): a network trained on the declared cost itself.

:func:`train_ratio_tuner` fits a :class:`~stewart_drake.control.tuner.ratio.RatioTunerModel` on the
training tasks' fixed-ratio runs for one lambda; :func:`shifted` offsets its output, the one
weight the study then chooses in closed loop (:func:`~.study_verdict.closed_loop_choice`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..base.errors import InvalidConfigError
from ..control.tuner.ratio import (
    N_RATIO_INPUTS,
    RATIO_LOG10_MAX,
    RATIO_LOG10_MIN,
    RatioTunerModel,
)
from .study_runs import RATIOS, window_costs


def train_ratio_tuner(
    fixed_records: dict, lam: float, hidden: int = 16, epochs: int = 300, seed: int = 0
) -> RatioTunerModel:
    """Train our tuner on the training tasks' fixed-ratio runs for one lambda.

    Every tuner instant of every fixed run is a sample: its inputs (density features of that
    run, the reference's motion) and the cost curve of its window over the 13 ratios. The loss
    is the window's J at the predicted log10 ratio, linearly interpolated on the grid: the
    declared cost itself, so a near-tie costs little and a bad choice much (labels from the cost,
    not from its argmin alone).

    Args:
        fixed_records: {(family, seed): {ratio: record}} of :func:`~.study_runs.study_job` records.
    Returns:
        the trained :class:`~stewart_drake.control.tuner.ratio.RatioTunerModel`.
    Raises:
        InvalidConfigError: no training records.
    """
    import torch

    Xs, Cs = [], []
    for runs in fixed_records.values():
        J = window_costs(runs, lam)  # (13, n_w)
        # A ratio that lost the platform costs ten times the worst one that did not.
        J = np.where(np.isfinite(J), J, 10 * np.nanmax(np.where(np.isfinite(J), J, np.nan), axis=0))
        for r in RATIOS:
            rec = runs[r]
            if "lost" in rec:
                continue
            Xs.append(np.asarray(rec["inputs"]))
            Cs.append(J[:, np.asarray(rec["input_window"])].T)  # (K, 13)
    if not Xs:
        raise InvalidConfigError("no training runs for the ratio tuner")
    X, C = np.concatenate(Xs), np.concatenate(Cs)
    x_mean, x_std = X.mean(axis=0), X.std(axis=0)
    x_std = np.where(x_std > 1e-12, x_std, 1.0)
    Z = torch.tensor((X - x_mean) / x_std)
    cost = torch.tensor(C / C.mean())  # one scale for every lambda
    grid = torch.tensor(np.log10(RATIOS))
    torch.manual_seed(seed)
    net = torch.nn.Sequential(
        torch.nn.Linear(N_RATIO_INPUTS, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, 1)
    ).double()
    optimizer = torch.optim.Adam(net.parameters(), lr=0.01)
    for _ in range(epochs):
        optimizer.zero_grad()
        y = net(Z)[:, 0].clamp(RATIO_LOG10_MIN, RATIO_LOG10_MAX)
        # linear interpolation of each sample's cost curve at y
        pos = (y - grid[0]) / (grid[1] - grid[0])
        k = pos.detach().floor().clamp(0, len(RATIOS) - 2).long()
        w = (pos - k).clamp(0.0, 1.0)
        rows = torch.arange(len(y))
        loss = ((1 - w) * cost[rows, k] + w * cost[rows, k + 1]).mean()
        loss.backward()
        optimizer.step()
    lin1, lin2 = net[0], net[2]
    with torch.no_grad():
        return RatioTunerModel(
            lin1.weight.numpy().copy(),
            lin1.bias.numpy().copy(),
            lin2.weight.numpy().copy(),
            lin2.bias.numpy().copy(),
            x_mean,
            x_std,
            {
                "lambda": lam,
                "hidden": hidden,
                "epochs": epochs,
                "seed": seed,
                "samples": int(len(X)),
                "final_loss": float(loss),
            },
        )


def shifted(model: RatioTunerModel, shift: float) -> RatioTunerModel:
    """``model`` with its output (log10 ratio) offset by ``shift``: the output bias b2 + shift."""
    return dataclasses.replace(
        model, b2=model.b2 + shift, metadata={**model.metadata, "shift": float(shift)}
    )
