"""Every typed error survives pickling (a refusal inside a worker comes back as itself)."""

import inspect
import pickle

import pytest

from stewart_drake.base import errors

POSE = [0.1, -0.2, 0.3, 0.01, -0.02, 0.31]
#: One instance per class of errors.py; a new class without an example fails the test below.
EXAMPLES = {
    errors.StewartError: errors.StewartError("something to change"),
    errors.InvalidGeometryError: errors.InvalidGeometryError("rod_length must be > 0"),
    errors.InvalidConfigError: errors.InvalidConfigError("omega_Q must be in [0.001, 1000]"),
    errors.CorruptFileError: errors.CorruptFileError(
        "w.npz", "ANN tuner weights file", "the entry 'W2' is missing", "retrain"
    ),
    errors.UnreachablePoseError: errors.UnreachablePoseError(3, 1.04, t=1.25, pose=POSE),
    errors.RiccatiSolveError: errors.RiccatiSolveError("no stabilizing solution"),
    errors.NotStabilizableError: errors.NotStabilizableError(
        {"stabilizable": False, "detectable": True, "rank_AB": 16, "rank_AC": 18, "n": 18},
        pose=POSE,
    ),
    errors.SimulationDivergedError: errors.SimulationDivergedError(
        "loop-closure error 2e-3 m", 0.644, "results/diverged/d.npz"
    ),
    errors.ForwardKinematicsError: errors.ForwardKinematicsError("Newton did not converge"),
    errors.RenderToolMissingError: errors.RenderToolMissingError("install Graphviz"),
    errors.JointLimitError: errors.JointLimitError(1, "crank_joint", -4.8e-4, t=0.644, pose=POSE),
    errors.SingularPoseError: errors.SingularPoseError("sigma_min_inv", 0.008, 0.01, t=2.0),
    errors.InterferenceError: errors.InterferenceError(
        "rod_2/tube", "base/plate", -0.004, 0.003, t=1.5, pose=POSE
    ),
    errors.MotorLimitError: errors.MotorLimitError(4, "torque", 1.21, 0.632, t=0.12, pose=POSE),
    errors.ResultsMismatchError: errors.ResultsMismatchError("results/collect holds seed 1"),
    errors.IncompleteResultsError: errors.IncompleteResultsError("2 of 9 runs lost"),
    errors.FolderInUseError: errors.FolderInUseError(
        "results/evaluation", "`evaluate` study, pid 4242 on host, since 2026-01-01 12:00:00"
    ),
    errors.MissingFileError: errors.MissingFileError("no weights at w.npz"),
    errors.MissingExtraError: errors.MissingExtraError(
        "train needs torch: pip install stewart-drake[train]"
    ),
    errors.BusError: errors.BusError("bus /dev/ttyUSB0: sync read: no status packet"),
    errors.MissingServoError: errors.MissingServoError(4, "/dev/ttyUSB0"),
    errors.ServoConfigMismatchError: errors.ServoConfigMismatchError(2, "Current Limit", 700, 1193),
    errors.StartPoseError: errors.StartPoseError("the robot rests at a pose outside the set"),
    errors.LoopStalledError: errors.LoopStalledError("no period completed for 312 ms"),
    errors.DeadlineMissError: errors.DeadlineMissError(11, 10, 0.002, 0.0061, 3.214),
    errors.LiveSourceError: errors.LiveSourceError("BREATH: no sample for 0.5 s after 1203"),
}


def test_every_error_class_has_an_example():
    classes = {
        c
        for _, c in inspect.getmembers(errors, inspect.isclass)
        if issubclass(c, errors.StewartError) and c.__module__ == errors.__name__
    }
    assert classes == set(EXAMPLES)


@pytest.mark.parametrize("error", EXAMPLES.values(), ids=lambda e: type(e).__name__)
def test_error_round_trips_through_pickle(error):
    error.add_note("raised in worker 1234")
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error)
    assert str(back) == str(error) and back.args == error.args
    assert vars(back) == vars(error)  # leg, ratio, t, pose, path, notes ...
    assert back.__notes__ == ["raised in worker 1234"]


def test_the_attributes_are_the_ones_given():
    e = pickle.loads(pickle.dumps(EXAMPLES[errors.JointLimitError]))
    assert (e.leg, e.limit, e.margin, e.t, e.pose) == (1, "crank_joint", -4.8e-4, 0.644, POSE)
    assert "leaves its crank_joint limit by 0.0275 deg at t = 0.644 s" in str(e)
    d = pickle.loads(pickle.dumps(EXAMPLES[errors.SimulationDivergedError]))
    assert (d.message, d.t, d.path) == (
        "loop-closure error 2e-3 m",
        0.644,
        "results/diverged/d.npz",
    )
