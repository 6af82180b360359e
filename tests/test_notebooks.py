"""The notebooks are stored without outputs and run top to bottom (shortened by
STEWART_DRAKE_QUICK=1), importing this checkout's stewart_drake and showing plots."""

import os
import sys
from pathlib import Path

import nbformat
import pytest
from conftest import HANG_S, HAS_TORCH

REPO = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((REPO / "notebooks").glob("*.ipynb"))


def test_the_five_notebooks_exist():
    assert [p.name for p in NOTEBOOKS] == [
        "01_kinematics_workspace.ipynb",
        "02_paper_experiment.ipynb",
        "03_training_tuner.ipynb",
        "04_evaluation.ipynb",
        "05_organ_motion.ipynb",
    ]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_stored_with_outputs_cleared(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    for k, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            assert cell.outputs == [] and cell.execution_count is None, (
                f"{path.name} cell {k} stores outputs: clear them "
                f"(jupyter nbconvert --clear-output --inplace {path.relative_to(REPO)})"
            )
    assert nb.metadata.kernelspec.name == "python3"


def test_the_training_notebook_asks_for_torch_before_any_work(monkeypatch):
    """Without torch, notebook 03 stops in its first code cell with one line that says what to
    install (the CPU build), not after two minutes of collection; with torch it says nothing."""
    nb = nbformat.read(REPO / "notebooks" / "03_training_tuner.ipynb", as_version=4)
    first = next(cell for cell in nb.cells if cell.cell_type == "code")
    assert "import stewart_drake" not in first.source and "from stewart_drake" not in first.source
    if HAS_TORCH:
        exec(compile(first.source, "cell", "exec"), {})  # passes
    monkeypatch.setitem(sys.modules, "torch", None)  # as if not installed
    with pytest.raises(ModuleNotFoundError) as info:
        exec(compile(first.source, "cell", "exec"), {})
    message = str(info.value)
    assert "\n" not in message and "torch 2.3 or newer" in message and "CPU build" in message
    assert "README" in message


#: Notebooks whose run is the slow tier's: they run the studies of test_tuner_pipeline,
#: test_training and test_evaluation (collect, train, the evaluation grid) end to end, 20-30 s
#: each even shortened; every name they import or call is checked by test_docs in every tier.
SLOW_NOTEBOOKS = {"03_training_tuner", "04_evaluation"}


@pytest.mark.system
@pytest.mark.parametrize(
    "path",
    [pytest.param(p, marks=pytest.mark.slow) if p.stem in SLOW_NOTEBOOKS else p for p in NOTEBOOKS],
    ids=lambda p: p.stem,
)
def test_notebook_runs_and_shows_plots(path, monkeypatch):
    from nbclient import NotebookClient

    if not HAS_TORCH and "stewart_drake.tuner.training" in path.read_text():
        pytest.skip(f"{path.name} trains the tuner: needs torch (the [train] extra)")

    monkeypatch.setenv("STEWART_DRAKE_QUICK", "1")
    monkeypatch.delenv("MPLBACKEND", raising=False)  # CI's Agg would hide inline plots
    monkeypatch.setenv(
        "PYTHONPATH",
        os.pathsep.join(
            [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
        ),
    )
    nb = nbformat.read(path, as_version=4)
    nb.cells.append(
        nbformat.v4.new_code_cell(
            "import stewart_drake; print('STEWART_DRAKE_FILE', stewart_drake.__file__)"
        )
    )
    # Each cell within 300 s (2-17 s a notebook on a quiet machine with STEWART_DRAKE_QUICK=1;
    # unshortened, notebook 03 alone collects for two minutes): a hang fails by timing out.
    NotebookClient(
        nb, timeout=HANG_S, kernel_name="python3", resources={"metadata": {"path": str(REPO)}}
    ).execute()
    outputs = [o for cell in nb.cells if cell.cell_type == "code" for o in cell.outputs]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 1, f"{path.name} showed no plot"
    (where,) = [o["text"] for o in outputs if "STEWART_DRAKE_FILE" in o.get("text", "")]
    assert Path(where.split()[-1]).resolve().is_relative_to(REPO), where
