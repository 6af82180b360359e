"""The tuner study's verdict: each controller's cost against the best fixed ratio of each task.

:func:`verdict` compares, at one lambda, every controller of :func:`verdict_arms` with the best
fixed ratio chosen in hindsight on each held-out task (the paired relative difference of J, its
mean and spread by family, and whether it meets :data:`~.study_runs.GOAL`);
:func:`closed_loop_choice` picks, on the training tasks, the candidate (a fixed ratio, an output
shift of our tuner) of the lowest mean normalized J.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .study_runs import GOAL, RATIOS, StudyArm, task_key


def task_J(record: dict, lam: float) -> float:
    """J of one run at lambda."""
    return float(record["e2"] + lam * record["u2"])


def normalized_J(record: dict, best_J: float, lam: float) -> float:
    """J of a run over the task's best fixed J (inf when the run lost the platform)."""
    return task_J(record, lam) / best_J


def closed_loop_choice(candidates: dict, fixed_records: dict, lam: float) -> tuple:
    """The candidate with the lowest mean J / J_best fixed over the training tasks.

    Training on the closed-loop cost: each candidate ran in closed loop on every training task.

    Args:
        candidates: {key: {task: record}} (a fixed ratio, an output shift).
        fixed_records: {task: {ratio: record}} of the same tasks (for J_best fixed).
    Returns:
        (key, {key: mean normalized J}).
    """
    best = {
        task: min(task_J(rec, lam) for rec in runs.values()) for task, runs in fixed_records.items()
    }
    means = {
        key: float(np.mean([normalized_J(runs[task], best[task], lam) for task in best]))
        for key, runs in candidates.items()
    }
    return min(means, key=means.__getitem__), means


def verdict_arms(lam: float) -> tuple:
    """The arms of the verdict at ``lam``, in the report's order."""
    return (
        StudyArm("hindsight", lam=lam),
        StudyArm("ours", lam=lam),
        StudyArm("ours closed-loop", lam=lam),
        StudyArm("paper tuner"),
        StudyArm("speed schedule"),
        StudyArm("fixed chosen", lam=lam),
        StudyArm("fixed gain", ratio=1.0),
    )


def verdict(records: dict, tasks: list, lam: float) -> dict:
    """Paired comparison at one lambda over the held-out tasks.

    Args:
        records: {(family, seed): {StudyArm: record}} with the 13 fixed ratios' arms.
        tasks: the held-out (family, seed).
    Returns:
        {"best_fixed": {task key: (ratio, J)}, "controllers": {label: {"arm": the arm's fields,
        "per_task": {task key: rel}, "mean", "std", "by_family": {family: (mean, std, n)},
        "beats"}}} with rel = (J - J_best fixed) / J_best fixed, negative when the controller
        does better (task keys: :func:`task_key`).
    """
    best = {}
    for task in tasks:
        runs = records[task]
        J_fixed = {
            r: task_J(runs[StudyArm("fixed", ratio=r)], lam)
            for r in RATIOS
            if StudyArm("fixed", ratio=r) in runs
        }
        r_best = min(J_fixed, key=J_fixed.__getitem__)
        best[task] = (r_best, J_fixed[r_best])
    out = {}
    for arm in verdict_arms(lam):
        per_task = {
            task: task_J(records[task][arm], lam) / best[task][1] - 1.0
            for task in tasks
            if arm in records[task]
        }
        if per_task:
            out[arm.label] = {"arm": dataclasses.asdict(arm), **_relative_figures(per_task)}
    return {"best_fixed": {task_key(t): v for t, v in best.items()}, "controllers": out}


def _relative_figures(per_task: dict) -> dict:
    """Mean and spread of the relative differences {task: rel}, overall and by family, and
    whether they meet the :data:`GOAL`: at least that much below, beyond the spread."""

    def mean_std(v):
        """(mean, sample std); inf for both when a run lost the platform."""
        if not np.all(np.isfinite(v)):
            return float("inf"), float("inf")
        return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0

    rel = np.array(list(per_task.values()))
    by_family = {}
    for family in sorted({f for f, _ in per_task}):
        v = np.array([x for (f, _), x in per_task.items() if f == family])
        by_family[family] = (*mean_std(v), len(v))
    mean, spread = mean_std(rel)
    if len(rel) < 2:
        spread = float("inf")
    return {
        "per_task": {task_key(t): v for t, v in per_task.items()},
        "mean": mean,
        "std": spread,
        "by_family": by_family,
        "beats": bool(mean <= -GOAL and -mean > spread),
    }
