"""The tuner study: does tuning omega_Q / omega_R online beat the best fixed ratio?

It tests the paper's claim (its ANN on density features tracks better at less torque than fixed
weights) on the robot as built, with a cost declared before any run, against the best fixed
ratio chosen in hindsight for each task, on tasks the tuners never saw. Why so, the
negative result and how each choice was made: docs/tuners.md, "The paper's claim, tested".

**The cost** (:func:`~.metrics.sample_costs`), for each lambda of :data:`~.study_runs.LAMBDAS`::

    J = mean over the run's samples of  sum_i (e_i / s_e)^2  +  lambda sum_j (u_j / s_T)^2

with e the true pose error (s_e = 1 mrad | 1 mm, the LQI's scales) and u the *feedback* torque,
the applied torque minus the static holding torque of the reference pose
(:func:`~.metrics.feedback_torque`), s_T = 0.3 N m.

**Tasks** (:mod:`~stewart_drake.tuner.tasks`): training on seeds
:data:`~.study_runs.TRAIN_SEEDS` of :data:`~.study_runs.TRAIN_FAMILIES`; tests on seeds
:data:`~.study_runs.TEST_SEEDS` of the same families, of the ``surgical`` family, and on the
paper manoeuvre.

**Controllers**, all the LQI on the hardware: the fixed ratios :data:`~.study_runs.RATIOS`; the
LQI without re-scheduling on B(x) at ratio 1; a schedule on the reference speed
(:func:`~.study_runs.speed_schedule`); the paper's tuner; ours
(:class:`~stewart_drake.control.tuner.ratio.RatioTuner`, one per lambda,
:func:`~.ratio_training.train_ratio_tuner`); and the hindsight schedule
(:func:`~.study_runs.hindsight_schedule`).

**Verdict** (:func:`~.study_verdict.verdict`): per lambda and test task, the paired relative
difference (J_controller - J_best fixed) / J_best fixed, its mean and standard deviation over
the seeds of each family; our tuner "beats" the best fixed ratio at a lambda when its mean over
all test tasks is at least :data:`~.study_runs.GOAL` below and the difference exceeds the
seed-to-seed spread.

Every run is a :class:`~.study_runs.StudyJob` of the study runner (:mod:`.runners`), stored as
it arrives (:mod:`.store`: an interrupted study resumes); :func:`run_tuner_study` runs the
study's three stages (:class:`TunerStudy`). The report is made apart (:mod:`.tuner_report`).
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..control.tuner.network import load_tuner, save_tuner
from ..control.tuner.ratio import RatioTunerModel
from ..control.tuning import AnnTunerDriver, RatioTunerDriver, TunerChoice, WeightSchedule
from ..run.scenario_io import load_scenario
from .ratio_training import shifted, train_ratio_tuner
from .study_runs import (
    LAMBDAS,
    R_HOLD,
    R_MOVE,
    RATIOS,
    SHIFTS,
    SPEED_SCALE,
    TASK_DURATION_S,
    TUNER_PERIOD_S,
    WINDOW_S,
    StudyArm,
    StudyJob,
    hindsight_schedule,
    speed_schedule,
    study_job,
    task_key,
    test_tasks,
    train_tasks,
)
from .study_verdict import closed_loop_choice, task_J, verdict


def _json(value):
    return json.loads(
        json.dumps(value, default=lambda o: o.tolist() if isinstance(o, np.ndarray) else float(o))
    )


def summary_path(out_dir) -> Path:
    return Path(out_dir) / "tuner_study.json"


# -- the study -------------------------------------------------------------------------------------


def provenance(settings: dict, train: list) -> dict:
    """What a shipped tuner was trained on, for its metadata: the base scenario (name and the
    SHA-256 of its YAML), the training tasks, the runs per task, the cost and the versions."""
    import hashlib

    from .. import __version__
    from ..run.scenario import dump_scenario

    scenario = dump_scenario(load_scenario(settings["base"]))
    return {
        "made_by": "the tuner study of `stewart-drake evaluate` (stewart_drake.tuner."
        "tuner_study.run_tuner_study)",
        "base_scenario": settings["base"],
        "base_scenario_sha256": hashlib.sha256(scenario.encode()).hexdigest(),
        "training_tasks": [f"{f}_s{s}" for f, s in train],
        "task_duration_s": settings["duration_s"],
        "runs": f"{len(settings['ratios'])} fixed ratios omega_Q / omega_R per training "
        f"task (1e-3 .. 1e3), then the output shift chosen in closed loop on the same "
        f"tasks among {list(SHIFTS)}",
        "cost": "J = mean sum (e / 1 mrad|mm)^2 + lambda sum (u_fb / 0.3 N m)^2",
        "quick": settings["quick"],
        "stewart_drake": __version__,
        "drake": _version_of("drake"),
    }


def _version_of(package: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return "unknown"


def load_run(path: Path, job_id: str) -> dict:
    """One stored run of the study, through the checked loaders: a lost run's ``.json``
    (``{"lost": why}``, returned with infinite costs) or a run's ``.npz`` (its arrays; one that
    names its job must name ``job_id``).

    Raises:
        CorruptFileError: not JSON or not an ``.npz`` archive, an entry missing or of the wrong
            type, or the run of another job (names the file; delete it and run again).
    """
    from ..base.errors import CorruptFileError
    from ..base.fileio import read_json
    from ..base.npz import CheckedNpz

    remedy = "delete it and run the same command again to redo that run"
    if path.suffix == ".json":
        record = read_json(path, "tuner study run", remedy)
        if not isinstance(record, dict) or not isinstance(record.get("lost"), str):
            raise CorruptFileError(path, "tuner study run", 'it must be {"lost": why}', remedy)
        return {"lost": record["lost"], "e2": np.inf, "u2": np.inf}
    data = CheckedNpz(path, "tuner study run", remedy)
    if "job_id" in data and data.text("job_id") != job_id:
        raise data.corrupt(f"it holds the run {data.text('job_id')!r}, not {job_id!r}")
    for name in ("e2", "u2", "ratio_mean", "wall_s"):
        data.number(name)
    for name in ("e2_w", "u2_w", "inputs", "input_window"):
        data.array(name)
    return {k: v for k, v in data.arrays.items() if k != "job_id"}


def run_tuner_study(
    out_dir,
    runner,
    base: str = "paper_hardware",
    quick: bool = False,
    progress: bool = True,
    paper_weights: str = "",
    test: bool = True,
) -> dict:
    """Run the whole study (module docstring) into ``out_dir``; resumable.

    Our tuner as chosen in closed loop, one per lambda, is written to
    ``weights/chosen/ratio_tuner_lambda<lambda>.npz`` with the data it came from in its metadata
    (:func:`provenance`): the files ``stewart_drake/data/`` ships.

    Args:
        out_dir: folder of the runs (``runs/``), our tuners' weights (``weights/``) and
            ``tuner_study.json``.
        runner: a runner of :mod:`.runners`.  base: the scenario every run starts from.
        quick: one seed per family and 1 s tasks (tests, notebooks): a smoke test, not figures.
        paper_weights: the paper tuner's ``.npz`` (default the shipped one trained on the
            paper's labels, ``stewart_drake/data/ann_tuner_paper.npz``).
        test: run the held-out tasks and the verdict; False runs the training tasks only, to
            train our tuners (the same weights: the training runs are the same).
    Returns:
        the summary (also written to ``tuner_study.json``): settings, per-lambda verdicts,
        the hindsight headroom, every run's J, our tuners' training losses, wall times.
    Raises:
        IncompleteResultsError: runs lost twice (the message says to rerun); Interrupted.
    """
    study = TunerStudy(out_dir, runner, base, quick, progress, paper_weights, test)
    study.run_fixed_and_baselines()
    study.run_our_tuners()
    study.run_closed_loop_choices()
    return study.finish()


class TunerStudy:
    """The study's state between its three stages: the runs' store, the settings, the jobs run
    so far, the records read back, our tuners' training and the closed-loop choices.

    Stage A (:meth:`run_fixed_and_baselines`): the fixed ratios on every task, the baselines
    and the paper's tuner on the held-out tasks. Stage B (:meth:`run_our_tuners`): our tuners
    trained on the training tasks' fixed runs, their output shifts on the training tasks, the
    hindsight schedules and our tuners on the held-out tasks. Stage C
    (:meth:`run_closed_loop_choices`): the shift and the single fixed ratio chosen in closed loop
    on the training tasks, the chosen tuners on the held-out tasks. :meth:`finish` writes the
    summary.
    """

    def __init__(
        self,
        out_dir,
        runner,
        base: str,
        quick: bool,
        progress: bool,
        paper_weights: str,
        test: bool,
    ):
        from ..control.tuner.ann import PAPER_LABEL_TUNER_PATH
        from ..execution.store import ResultStore, file_digest

        self.out, self.runner, self.base, self.quick = Path(out_dir), runner, base, quick
        self.progress = progress
        self.duration = 1.0 if quick else TASK_DURATION_S
        self.train, self.test = train_tasks(quick), (test_tasks(quick) if test else [])
        self.paper_weights = str(paper_weights or PAPER_LABEL_TUNER_PATH)  # the paper's labels
        self.lqi = load_scenario(base).lqi()
        self.settings = {
            "base": base,
            "quick": quick,
            "duration_s": self.duration,
            "lambdas": LAMBDAS,
            "ratios": RATIOS,
            "train": self.train,
            "test": self.test,
            "window_s": WINDOW_S,
            "speed_schedule": [R_HOLD, R_MOVE, SPEED_SCALE],
            "paper_weights": file_digest(self.paper_weights),
        }
        self.store = ResultStore(self.out, "tuner_study", self.settings, pattern="runs/*/*.npz")
        self.jobs: dict = {}
        self.loaded: dict = {}
        self.trained: dict = {}
        self.chosen: dict = {}
        self.wall0 = time.perf_counter()

    # -- jobs ----------------------------------------------------------------------------------
    def job(self, arm: StudyArm, task: tuple, tuner: TunerChoice | None = None) -> StudyJob:
        """The run of ``arm`` on ``task``: the base's LQI at the arm's ratio (1 for the tuned
        ones), without re-scheduling B(x) for the fixed gain."""
        ratio = arm.ratio if arm.ratio is not None else 1.0
        controller = dataclasses.replace(
            self.lqi, omega_Q=ratio, omega_R=1.0, schedule_pose=arm.kind != "fixed gain"
        )
        return StudyJob(
            arm,
            task[0],
            task[1],
            self.duration,
            self.base,
            controller,
            tuner,
            str(self.out / "diverged"),
        )

    def schedule(self, arm: StudyArm, task: tuple, t_ratios: tuple) -> StudyJob:
        """The run of a weight schedule (t, ratios) of ``arm`` on ``task``."""
        t, ratios = t_ratios
        return self.job(
            arm, task, WeightSchedule(t=list(t), omega_Q=list(ratios), omega_R=[1.0] * len(t))
        )

    def run(self, jobs: list, desc: str) -> None:
        """Run the jobs not on disk yet, storing each as it arrives."""
        from ..execution.store import run_jobs

        by_id = {job.job_id: job for job in jobs}
        run_jobs(
            self.store,
            self.runner,
            study_job,
            by_id,
            lambda i, o: self.save(by_id[i], o),
            progress=self.progress,
            desc=desc,
            what="runs",
        )
        self.jobs.update(by_id)

    def save(self, job: StudyJob, outcome) -> None:
        """Store a run's arrays (or that it lost the platform) under its job id."""
        from ..execution.runners import JobFailure

        if isinstance(outcome, JobFailure):
            record = {"lost": outcome.message.splitlines()[0][:300]}
            self.store.put_json(job.job_id, f"runs/{job.job_id}.json", record, lost=True)
            return
        arrays: dict[str, Any] = {k: np.asarray(v) for k, v in outcome.items()}
        arrays["job_id"] = np.array(job.job_id)  # the run says which it is (load checks)
        self.store.put(
            job.job_id,
            f"runs/{job.job_id}.npz",
            lambda f: np.savez(f, **arrays),
            label=job.arm.label,
            J={f"{lam:g}": task_J(outcome, lam) for lam in LAMBDAS},
        )

    def load(self, job_id: str) -> dict:
        """A stored run's record, read from disk once (the stages and the summary reuse it)."""
        if job_id not in self.loaded:
            file = self.store.manifest["jobs"][job_id]["file"]
            self.loaded[job_id] = load_run(self.out / file, job_id)
        return self.loaded[job_id]

    def record(self, arm: StudyArm, task: tuple) -> dict:
        """The record of ``arm``'s run on ``task``."""
        return self.load(f"{task_key(task)}/{arm.slug}")

    def fixed(self, tasks: list) -> dict:
        """{task: {ratio: record}} of the fixed ratios on ``tasks``."""
        return {
            task: {r: self.record(StudyArm("fixed", ratio=r), task) for r in RATIOS}
            for task in tasks
        }

    # -- the stages ----------------------------------------------------------------------------
    def run_fixed_and_baselines(self) -> None:
        """A: the fixed ratios everywhere; the baselines and the paper's tuner on the test
        tasks."""
        jobs = [
            self.job(StudyArm("fixed", ratio=r), task)
            for task in self.train + self.test
            for r in RATIOS
        ]
        for task in self.test:
            jobs += [
                self.job(StudyArm("fixed gain", ratio=1.0), task),
                self.schedule(
                    StudyArm("speed schedule"),
                    task,
                    speed_schedule(*task, self.duration, self.base),
                ),
                self.job(
                    StudyArm("paper tuner"),
                    task,
                    AnnTunerDriver(weights=self.paper_weights, period_s=TUNER_PERIOD_S),
                ),
            ]
        self.run(jobs, "tuner study: fixed ratios and baselines")

    def run_our_tuners(self) -> None:
        """B: our tuners (trained on the training tasks' fixed runs, labels from the cost), the
        hindsight schedules on the test tasks, and our tuners with their output shifted by each
        of :data:`SHIFTS` on the training tasks (for the closed-loop choice of C)."""
        fixed_train, fixed_test = self.fixed(self.train), self.fixed(self.test)
        jobs = []
        for lam in LAMBDAS:
            path = self.out / "weights" / f"ratio_tuner_lambda{lam:g}.npz"
            model = train_ratio_tuner(fixed_train, lam)
            save_tuner(model, path)
            self.trained[f"{lam:g}"] = model.metadata
            for shift in self.shifts():
                shift_path = self._shift_path(lam, shift)
                save_tuner(shifted(model, shift), shift_path)
                jobs += [
                    self.job(
                        StudyArm("ours", lam=lam, shift=shift),
                        task,
                        RatioTunerDriver(weights=str(shift_path), period_s=TUNER_PERIOD_S),
                    )
                    for task in self.train
                ]
            for task in self.test:
                jobs += [
                    self.schedule(
                        StudyArm("hindsight", lam=lam),
                        task,
                        hindsight_schedule(fixed_test[task], lam),
                    ),
                    self.job(
                        StudyArm("ours", lam=lam),
                        task,
                        RatioTunerDriver(weights=str(path), period_s=TUNER_PERIOD_S),
                    ),
                ]
        self.run(jobs, "tuner study: hindsight and our tuners")

    def run_closed_loop_choices(self) -> None:
        """C: the closed-loop choices on the training tasks: our tuner's output shift (run on
        the test tasks) and the single fixed ratio (its test runs exist already)."""
        fixed_train = self.fixed(self.train)
        jobs = []
        for lam in LAMBDAS:
            r_chosen, r_means = closed_loop_choice(
                {r: {task: fixed_train[task][r] for task in self.train} for r in RATIOS},
                fixed_train,
                lam,
            )
            shift, shift_means = closed_loop_choice(
                {
                    sh: {
                        task: self.record(StudyArm("ours", lam=lam, shift=sh), task)
                        for task in self.train
                    }
                    for sh in self.shifts()
                },
                fixed_train,
                lam,
            )
            self.chosen[f"{lam:g}"] = {
                "fixed_ratio": r_chosen,
                "fixed_means": r_means,
                "shift": shift,
                "shift_means": shift_means,
            }
            path = self._shift_path(lam, shift)
            model = load_tuner(RatioTunerModel, path)
            save_tuner(
                dataclasses.replace(
                    model,
                    metadata={
                        **model.metadata,
                        "closed_loop_means": shift_means,
                        "data": provenance(self.settings, self.train),
                    },
                ),
                self.out / "weights" / "chosen" / f"ratio_tuner_lambda{lam:g}.npz",
            )
            jobs += [
                self.job(
                    StudyArm("ours closed-loop", lam=lam),
                    task,
                    RatioTunerDriver(weights=str(path), period_s=TUNER_PERIOD_S),
                )
                for task in self.test
            ]
        self.run(jobs, "tuner study: our tuners as chosen in closed loop")

    def shifts(self) -> tuple:
        """The output shifts tried (every other one when quick)."""
        return SHIFTS if not self.quick else SHIFTS[::2]

    def _shift_path(self, lam: float, shift: float) -> Path:
        return self.out / "weights" / f"ratio_tuner_lambda{lam:g}_shift{shift:+g}.npz"

    # -- the summary ---------------------------------------------------------------------------
    def finish(self) -> dict:
        """The verdicts on the held-out tasks and every run's figures, written to
        ``tuner_study.json`` (the store is closed as complete). Returns the summary."""
        from ..base.fileio import atomic_write

        by_task: dict = {task: {} for task in self.test}
        for job in self.jobs.values():
            if job.task in by_task:
                by_task[job.task][job.arm] = self.record(job.arm, job.task)
        fixed_test = self.fixed(self.test)
        for lam in LAMBDAS:
            r = self.chosen[f"{lam:g}"]["fixed_ratio"]
            for task in self.test:
                by_task[task][StudyArm("fixed chosen", lam=lam)] = fixed_test[task][r]
        points = {
            task_key(task): {
                arm.label: {
                    "arm": dataclasses.asdict(arm),
                    "e2": float(rec["e2"]),
                    "u2": float(rec["u2"]),
                    "ratio_mean": float(rec.get("ratio_mean", np.nan)),
                }
                for arm, rec in runs.items()
                if "lost" not in rec
            }
            for task, runs in by_task.items()
        }
        lost = sorted(
            f"{task_key(task)}: {arm.label}"
            for task, runs in by_task.items()
            for arm, rec in runs.items()
            if "lost" in rec
        )
        summary = _json(
            {
                "settings": self.settings,
                "verdicts": {f"{lam:g}": verdict(by_task, self.test, lam) for lam in LAMBDAS},
                "tasks": {task_key(t): {"family": t[0], "seed": t[1]} for t in self.test},
                "points": points,
                "lost": lost,
                "trained": self.trained,
                "chosen": self.chosen,
                "wall_s": time.perf_counter() - self.wall0,
                "run_s": sum(float(self.load(i).get("wall_s", 0.0)) for i in self.jobs),
                "n_runs": len(self.jobs),
            }
        )
        text = json.dumps(summary, indent=1).encode()
        atomic_write(summary_path(self.out), lambda f: f.write(text))
        self.store.finish(True, summary="tuner_study.json")
        return summary
