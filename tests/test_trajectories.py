"""References from files and user objects: a bad CSV is refused naming the line, an evaluate of
one time at a time is wrapped."""

import numpy as np
import pytest

from stewart_drake.errors import InvalidConfigError, MissingFileError
from stewart_drake.simulation.scenario import (
    Scenario,
)
from stewart_drake.simulation.trajectories import (
    ScalarEvaluate,
    as_trajectory,
    paper_manoeuvre,
)
from stewart_drake.studies.experiments import run_experiment


def test_bad_csv_files_name_the_line(tmp_path):
    f = tmp_path / "r.csv"
    f.write_text("t,x\n0,1\n")
    with pytest.raises(InvalidConfigError, match=r"header t,phi,theta,psi,X,Y,Z"):
        as_trajectory(f)
    f.write_text("t,phi,theta,psi,X,Y,Z\n0,0,0,0,0,0,0.3\n0.1,0,0,0,0,0,nan\n")
    with pytest.raises(InvalidConfigError, match=r"line 3: expected 7 finite numbers"):
        as_trajectory(f)
    f.write_text("t,phi,theta,psi,X,Y,Z\n0,0,0,0,0,0,0.3\n0.1,0,0,0,0,0,0.3\n")
    with pytest.raises(InvalidConfigError, match=r"at least 3 samples"):
        as_trajectory(f)
    with pytest.raises(MissingFileError):
        as_trajectory(tmp_path / "none.csv")


def test_an_evaluate_of_one_time_is_wrapped():
    class OneAtATime:
        name = "scalar"

        def evaluate(self, t):
            if np.ndim(t):
                raise TypeError("one time at a time")
            return tuple(np.asarray(v)[0] for v in paper_manoeuvre().evaluate(np.array([t])))

    wrapped = as_trajectory(OneAtATime())
    assert isinstance(wrapped, ScalarEvaluate) and wrapped.name == "scalar"
    t = np.array([0.1, 0.2, 0.3])
    for got, want in zip(wrapped.evaluate(t), paper_manoeuvre().evaluate(t)):
        np.testing.assert_allclose(got, want, rtol=1e-15)
    result = run_experiment(Scenario(duration_s=0.2), reference=OneAtATime())
    assert result.config_summary["trajectory"] == "scalar" and result.metrics["finite"]
    with pytest.raises(InvalidConfigError, match="an object with evaluate"):
        as_trajectory(3.0)
