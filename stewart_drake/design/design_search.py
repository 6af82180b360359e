"""Design search: the best design an optimizer finds for a task, with a fixed motor.

A candidate design (:class:`~stewart_drake.design.variables.Design`) is judged against a task
sampled once (:func:`~.task_samples.task_samples`) by :func:`~.margins.evaluate`: its margins
(>= 0: met) and figures, an :class:`~.margins.Evaluation`.

:func:`search` minimizes one objective (:data:`~.margins.OBJECTIVES`) over the design's numbers
with a fixed motor, using scipy's ``differential_evolution``: a population method that needs no
gradient (the admissible set's edges are not smooth), is seeded and deterministic (``rng``, the
population evaluated a generation at a time), and lets us evaluate each generation with the
project's runners (local processes, Ray or Dask). pymoo's NSGA-II would give a Pareto front of
several objectives, but the task's acceptance is one objective under constraints per motor, the
motor is a choice among five, and scipy is already a dependency: :func:`cheapest_motor` runs one
search per catalogue motor, cheapest first, and the set of (motor price, least torque share)
pairs is the front between cost and reserve. Constraints are handled by Deb's feasibility rule
(any design that meets every margin beats any that does not; of two that do not, the smaller
total shortfall wins), as a penalty on the objective (:meth:`~.margins.Evaluation.penalized`).

A search persists through the project's :class:`~stewart_drake.execution.store.ResultStore`: each
generation's evaluations are one job, keyed by the generation's candidates; a search killed and
run again replays the finished generations from disk (the optimizer is deterministic, so it asks
for the same candidates) and continues. The same seed gives the same design.
"""

from __future__ import annotations

import dataclasses
import hashlib
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import CorruptFileError, InvalidConfigError, StewartError
from ..robot.motor_catalogue import MOTOR_CATALOGUE, REFERENCE_MOTOR, catalogue_motor
from .margins import EVALUATION_VERSION, OBJECTIVES, Evaluation, evaluate
from .task_samples import TaskSamples
from .variables import DESIGN_BOUNDS, Design, reference_design

#: The design's variables the search varies, in order; ``rod_length`` is drawn within the
#: lengths that close every leg at home (:meth:`Design.rod_length_range`), so every candidate
#: whose other variables allow a rod builds.
SEARCH_VARIABLES = tuple(name for name in DESIGN_BOUNDS if name != "rod_length") + ("rod_length",)


# --- the search ---------------------------------------------------------------------------


def design_from_vector(u, motor: str) -> Design:
    """The design of a point u in [0, 1]^8 of the search (:data:`SEARCH_VARIABLES`): each
    variable at its share of its bounds, the rod at its share of the closing range (clipped to
    its bounds)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    values = {}
    for ui, name in zip(u, SEARCH_VARIABLES[:-1], strict=False):
        lo, hi = DESIGN_BOUNDS[name][:2]
        values[name] = float(lo + ui * (hi - lo))
    rlo, rhi = DESIGN_BOUNDS["rod_length"][:2]
    design = Design(**values, rod_length=0.5 * (rlo + rhi), motor=motor)
    lo, hi = design.rod_length_range()
    lo, hi = max(lo, rlo), min(hi, rhi)
    if lo > hi:  # no rod closes: the nearest bound, the build margin says by how much
        design.rod_length = float(np.clip(0.5 * (lo + hi), rlo, rhi))
    else:
        design.rod_length = float(lo + u[-1] * (hi - lo))
    return design


def vector_of(design: Design) -> np.ndarray:
    """Inverse of :func:`design_from_vector` for a design that builds, (8,)."""
    u = [
        (getattr(design, name) - DESIGN_BOUNDS[name][0])
        / (DESIGN_BOUNDS[name][1] - DESIGN_BOUNDS[name][0])
        for name in SEARCH_VARIABLES[:-1]
    ]
    lo, hi = design.rod_length_range()
    rlo, rhi = DESIGN_BOUNDS["rod_length"][:2]
    lo, hi = max(lo, rlo), min(hi, rhi)
    u.append((design.rod_length - lo) / (hi - lo) if hi > lo else 0.5)
    return np.clip(np.array(u), 0.0, 1.0)


@dataclass(frozen=True)
class _Job:
    """Candidates for a worker: the task's file and the designs' points (a share of a
    generation: one job per worker, so a generation costs a few submissions)."""

    task_file: str
    motor: str
    points: tuple


_TASKS: dict = {}


def _evaluate_job(job: _Job) -> list:
    """Worker side: load the task once per process, evaluate the job's candidates."""
    task = _TASKS.get(job.task_file)
    if task is None:
        task = _TASKS[job.task_file] = TaskSamples.load(job.task_file)
    return [evaluate(design_from_vector(u, job.motor), task).to_json() for u in job.points]


#: Defaults of a search: population per variable, generations (scipy's ``popsize`` and
#: ``maxiter``; 8 x 8 = 64 candidates a generation).
DEFAULT_POPSIZE, DEFAULT_MAXITER = 8, 30


@dataclass
class SearchResult:
    """What :func:`search` found.

    Attributes:
        motor, objective, seed: what was searched.
        best: the :class:`~.margins.Evaluation` of the best design (feasible if any candidate
            was; a best that misses is evaluated again with every margin, ``lazy=False``).
        evaluations: candidates evaluated (the reference design among them), ``reused`` of them
            read back from an earlier, interrupted run.
        generations: per generation, [best penalized objective, feasible share].
        wall_s: this call's wall time, s.
        compute_s: the wall time the generations took when they were evaluated, s (this call's
            and, for those read back, the run's that evaluated them).
    """

    motor: str
    objective: str
    seed: int
    best: Evaluation
    evaluations: int
    reused: int
    generations: list
    wall_s: float
    compute_s: float = 0.0

    @property
    def feasible(self) -> bool:
        return self.best.feasible


class _Generations:
    """The map scipy's optimizer evaluates a generation with (its ``workers``): each generation
    is one job of the study's store, keyed by its candidates, run through the runner a candidate
    a process; a generation on disk is read back instead (kill and resume)."""

    def __init__(self, store, runner, task_file: Path, motor: str, objective: str, progress):
        self.store, self.runner, self.task_file = store, runner, str(task_file)
        self.motor, self.objective, self.progress = motor, objective, progress
        self.best: Evaluation | None = None
        self.evaluations = self.reused = 0
        self.compute_s = 0.0
        self.generations: list = []
        #: The typed error that ended a generation: scipy wraps a ValueError raised in its map
        #: (a CorruptFileError is one) in a RuntimeError of its own, which :func:`search` undoes.
        self.error: StewartError | None = None

    def __call__(self, func, population):
        try:
            return self._evaluate(population)
        except StewartError as err:
            self.error = err
            raise

    def _stored(self, job_id: str, size: int) -> list:
        """The ``size`` evaluations of a generation on disk, checked: a list of evaluations'
        JSON, one per candidate.

        Raises:
            CorruptFileError: the file is not JSON, or not evaluations (names it).
        """
        docs = self.store.load_json(job_id)
        try:
            evals = [Evaluation.from_json(d) for d in docs]
            for e in evals:  # each must give its objective, as a fresh evaluation does
                e.penalized(self.objective)
            if len(evals) != size:
                raise ValueError(f"{len(evals)} evaluations for {size} candidates")
        except (KeyError, TypeError, ValueError, AttributeError) as err:
            what = err if type(err) is ValueError else f"{type(err).__name__} {err}"
            path = self.store.folder / self.store.manifest["jobs"][job_id]["file"]
            raise CorruptFileError(
                path,
                "design generation",
                f"not the generation's evaluations ({what})",
                "delete it and run the same command again to redo that generation",
            ) from None
        return docs

    def _evaluate(self, population) -> list:
        rows = [np.asarray(u, dtype=float) for u in population]
        key = hashlib.sha256(b"".join(u.tobytes() for u in rows)).hexdigest()[:16]
        job_id = f"{self.motor}/{self.objective}/gen_{key}"
        if job_id in self.store.done():
            docs = self._stored(job_id, len(rows))
            self.reused += len(rows)
            self.compute_s += float(self.store.manifest["jobs"][job_id].get("wall_s", 0.0))
        else:
            shares = np.array_split(np.arange(len(rows)), max(1, self.runner.n_workers))
            jobs = {
                f"{i:02d}": _Job(self.task_file, self.motor, tuple(tuple(rows[k]) for k in share))
                for i, share in enumerate(shares)
                if len(share)
            }
            wall0 = time.perf_counter()
            outcomes = dict(self.runner.map(_evaluate_job, jobs))
            failed = [o for o in outcomes.values() if not isinstance(o, list)]
            if failed:  # evaluate() raises only on bad input, which search() checked
                raise StewartError(f"design candidates failed: {failed[0]}")
            docs = [doc for k in jobs for doc in outcomes[k]]
            wall = time.perf_counter() - wall0
            self.compute_s += wall
            self.store.put_json(
                job_id, f"{self.motor}_{self.objective}_gen_{key}.json", docs, wall_s=wall
            )
        evals = [Evaluation.from_json(d) for d in docs]
        values = [e.penalized(self.objective) for e in evals]
        self.evaluations += len(evals)
        for e, v in zip(evals, values, strict=True):
            if self.best is None or v < self.best.penalized(self.objective):
                self.best = e
        self.generations.append([float(min(values)), float(np.mean([e.feasible for e in evals]))])
        if self.progress is not None:
            self.progress.update()
            self.progress.set_postfix_str(self._status())
        return values

    def _status(self) -> str:
        if self.best is None:
            return ""
        if self.best.feasible:
            return f"best {self.objective} {self.best.objective(self.objective):.4g}"
        name, margin = self.best.binding
        return f"none feasible yet ({name} {margin:+.3g})"


def search(
    task: TaskSamples,
    motor: str = REFERENCE_MOTOR,
    objective: str = "peak_torque",
    out_dir="results/design",
    seed: int = 0,
    runner=None,
    popsize: int = DEFAULT_POPSIZE,
    maxiter: int = DEFAULT_MAXITER,
    progress: bool = True,
    say=None,
) -> SearchResult:
    """Minimize ``objective`` over the design's numbers with ``motor`` at every crank, subject to
    every margin of :data:`~.margins.MARGINS` (module docstring: the optimizer, the constraints,
    resuming).

    The first generation holds the reference robot's numbers (scipy's ``x0``), so a task the
    reference robot meets returns a design at least as good.

    Args:
        task: :func:`~.task_samples.task_samples` of the requirements.
        motor: a catalogue name. objective: one of :data:`~.margins.OBJECTIVES`.
        out_dir: the study's folder (created); a search of other settings there is refused.
        seed: the optimizer's seed: the same seed and settings give the same design.
        runner: any runner of :mod:`~stewart_drake.execution.runners` (default: this process).
        popsize, maxiter: scipy's; evaluations <= popsize x 8 x (maxiter + 1).
        progress: a bar over the generations.
        say: None, or ``say(line)`` told before the work after the bar (the best design's
            every margin, when none meets the task).
    Raises:
        InvalidConfigError: an unknown motor or objective, popsize < 2 or maxiter < 1.
        ResultsMismatchError, FolderInUseError: see :class:`~stewart_drake.execution.store.
            ResultStore`.
    """
    _check_options(motor, objective, popsize, maxiter)
    wall0 = time.perf_counter()
    generations = _generations(
        Path(out_dir), task, motor, objective, seed, runner, popsize, maxiter, progress
    )
    best = generations.best
    assert best is not None
    if not best.feasible:  # every margin of the best miss, for the report (one evaluation)
        if say is not None:
            say(f"{motor}: evaluating every margin of the best design, which misses the task")
        best = evaluate(best.design, task, lazy=False)
    return SearchResult(
        motor,
        objective,
        int(seed),
        best,
        generations.evaluations,
        generations.reused,
        generations.generations,
        time.perf_counter() - wall0,
        generations.compute_s,
    )


def _generations(out: Path, task, motor, objective, seed, runner, popsize, maxiter, progress):
    """The search's generations evolved in ``out`` (its store continued where it holds them),
    under a progress bar; the store closed however the search ends.

    Raises:
        the typed error a worker raised (scipy wraps it in a RuntimeError of its own);
        ResultsMismatchError, FolderInUseError: as :class:`~stewart_drake.execution.store.
        ResultStore`'s.
    """
    from tqdm import tqdm

    from ..execution.runners import SerialRunner
    from ..execution.store import ResultStore

    out.mkdir(parents=True, exist_ok=True)
    store = ResultStore(out, "design", _settings(task, seed, popsize, maxiter), "*_gen_*.json")
    generations: _Generations | None = None
    try:
        task_file = _task_file(out, task)
        with tqdm(
            total=maxiter + 1, desc=f"design {motor}", unit="gen", disable=not progress
        ) as bar:
            generations = _Generations(
                store, runner or SerialRunner(), task_file, motor, objective, bar
            )
            _evolve(generations, seed, popsize, maxiter)
        store.close()
    except RuntimeError:
        store.close()
        # scipy wraps a typed error raised in its map in a RuntimeError of its own
        if generations is not None and generations.error is not None:
            raise generations.error from None
        raise
    except BaseException:
        store.close()
        raise
    return generations


def _check_options(motor: str, objective: str, popsize: int, maxiter: int) -> None:
    """Refuse an unknown motor or objective, popsize < 2 or maxiter < 1 (InvalidConfigError)."""
    catalogue_motor(motor)
    if objective not in OBJECTIVES:
        raise InvalidConfigError(f"objective {objective!r} is not one of {', '.join(OBJECTIVES)}")
    if int(popsize) < 2 or int(maxiter) < 1:
        raise InvalidConfigError(f"popsize must be >= 2 and maxiter >= 1, got {popsize}, {maxiter}")


def _settings(task: TaskSamples, seed: int, popsize: int, maxiter: int) -> dict:
    """What decides a search's candidates, kept by its store (a search of other settings in
    the same folder is refused): the task, the rules, the bounds, the catalogue, the optimizer's
    settings."""
    return {
        "task": task.digest(),
        "evaluation": EVALUATION_VERSION,
        "variables": list(SEARCH_VARIABLES),
        "bounds": {k: list(v[:2]) for k, v in DESIGN_BOUNDS.items()},
        "catalogue": {k: dataclasses.asdict(v) for k, v in MOTOR_CATALOGUE.items()},
        "seed": int(seed),
        "popsize": int(popsize),
        "maxiter": int(maxiter),
    }


def _task_file(out: Path, task: TaskSamples) -> Path:
    """``out/task.npz``, the samples the workers load: written the first time, checked to hold
    ``task`` when a search resumes."""
    task_file = out / "task.npz"
    if not task_file.exists():
        task.save(task_file)
    elif TaskSamples.load(task_file).digest() != task.digest():  # pragma: no cover - guarded
        raise InvalidConfigError(f"{task_file} holds another task: choose another --out")
    return task_file


def _evolve(generations: _Generations, seed: int, popsize: int, maxiter: int) -> None:
    """scipy's differential evolution over [0, 1]^8 from the reference robot's numbers (with
    the search's motor), each generation evaluated by ``generations``."""
    from scipy.optimize import differential_evolution

    reference = reference_design()
    reference.motor = generations.motor
    differential_evolution(
        _unused_objective,
        [(0.0, 1.0)] * len(SEARCH_VARIABLES),
        popsize=popsize,
        maxiter=maxiter,
        polish=False,
        init="latinhypercube",
        x0=vector_of(reference),
        workers=generations,
        updating="deferred",
        tol=1e-6,
        **_seeded(seed),
    )


def _unused_objective(u) -> float:  # pragma: no cover - the generations' map evaluates instead
    raise AssertionError("design candidates are evaluated by _Generations")


def _seeded(seed: int) -> dict:
    """scipy's seed argument: one Generator stream for every scipy the project supports
    (``rng`` from 1.15, ``seed`` before)."""
    import inspect

    from scipy.optimize import differential_evolution

    generator = np.random.default_rng(int(seed))
    if "rng" in inspect.signature(differential_evolution).parameters:
        return {"rng": generator}
    return {"seed": generator}


def torque_refusal(motor: str) -> str:
    """Why ``robot`` could not drive catalogue motor ``motor`` by torque ("" if it can): a bus
    servo without Current Control Mode (the XL430-W250-T senses no current, so the controllers'
    torques cannot be sent to it; :func:`~stewart_drake.station.bus.servos.servo_spec`)."""
    from ..station.bus.servos import SERVO_SPECS

    spec = SERVO_SPECS.get(motor)
    if spec is not None and spec.current_unit_A is None:
        return (
            "no Current Control Mode (no current sensing), so the robot's controllers cannot "
            "send it a torque and `robot` refuses it"
        )
    return ""


def cheapest_motor(
    task: TaskSamples,
    out_dir="results/design",
    seed: int = 0,
    runner=None,
    popsize: int = DEFAULT_POPSIZE,
    maxiter: int = DEFAULT_MAXITER,
    progress: bool = True,
    say=None,
) -> list[SearchResult]:
    """Search the catalogue's motors from the cheapest up for a design that meets the task with
    the most reserve (objective ``torque_share``); stops at the first motor that meets it
    (``say``: as :func:`search`'s). A motor the robot could not drive by torque is skipped and
    said (:func:`torque_refusal`): a design is never recommended on a motor ``robot`` refuses.

    Returns:
        the searches run, cheapest motor first; the last is feasible unless no motor is (then
        each names its binding constraint).
    Raises:
        as :func:`search`.
    """
    results = []
    for motor in sorted(MOTOR_CATALOGUE, key=lambda m: MOTOR_CATALOGUE[m].price_usd):
        refused = torque_refusal(motor)
        if refused:
            line = f"design: {motor} skipped: {refused}"
            say(line) if say else print(line, file=sys.stderr, flush=True)
            continue
        result = search(
            task, motor, "torque_share", out_dir, seed, runner, popsize, maxiter, progress, say
        )
        results.append(result)
        if result.feasible:
            break
    return results
