"""README.md says first what the project is for, and prints what the code prints."""

import re
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
README = (REPO / "README.md").read_text()


def test_the_first_screen_says_what_the_project_is_for():
    """Before the install section a newcomer reads the two uses: motion phantoms for
    radiotherapy QA and surgical motion robots, then the paper it began from."""
    first_screen = README[: README.index("## Install")].lower()
    for words in ("radiotherapy", "motion phantom", "breathing", "surgical", "drake"):
        assert words in first_screen, f"README's first screen does not say {words!r}"
    assert first_screen.index("radiotherapy") < first_screen.index("intelligent optimal")


def _printout() -> list[str]:
    """The figure lines of README's `stewart-drake run` printout (real-time factor and the
    files written left out: they depend on the machine and the folder)."""
    block = re.search(r"```\n(RMS tracking error over .*?)```", README, re.S)
    assert block, "README shows no printout of `stewart-drake run`"
    return [
        line
        for line in block.group(1).splitlines()
        if not line.startswith(("real-time factor", "wrote "))
    ]


#: A figure of the printout (0.0259, 5.21e-07, 501).
_NUMBER = re.compile(r"\d+(?:\.\d+)?(?:e-?\d+)?")


def _numbers(lines: list[str]) -> list[float]:
    return [float(v) for line in lines for v in _NUMBER.findall(line)]


@pytest.mark.slow
def test_the_printout_is_what_the_paper_run_prints():
    """The 10 s paper run on the robot as built (about 10 s of CPU) prints README's lines, every
    figure within 10 % of README's. Not to the digits: a quantised, friction-limited loop moves
    them with the libraries under it (the same code gave phi 0.0259 and 0.0253 mrad RMS on two
    numpy 2.4 installs with Drake 1.51; Drake 1.58's SAP solver moves RMS figures up to 4 % and
    peaks up to 9 %); what a wrong run changes (a controller not told of the delay: three times
    the error, docs/hardware_figures.md) is far outside that."""
    from stewart_drake.run.metrics import format_metrics
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.run.simulate import run_experiment

    result = run_experiment(load_scenario("paper_hardware"))
    printed = [
        line
        for line in format_metrics(result.metrics).splitlines()
        if not line.startswith("real-time factor")
    ]
    shape = [" ".join(_NUMBER.sub("#", line).split()) for line in printed]
    assert shape == [" ".join(_NUMBER.sub("#", line).split()) for line in _printout()]
    np.testing.assert_allclose(_numbers(printed), _numbers(_printout()), rtol=0.1)


def test_the_printout_has_every_figure_line():
    """The block the slow test compares holds the six axes, the torques, the loop closure and
    the controller's counts."""
    lines = _printout()
    assert len(lines) == 12 and lines[0].startswith("RMS tracking error over t in [5, 10] s")
    assert sum(" mrad RMS" in line for line in lines) == 3
    assert sum(" mm RMS" in line for line in lines) == 3
    assert any(line.startswith("max loop-closure error") for line in lines)
