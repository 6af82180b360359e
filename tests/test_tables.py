"""base.tables: the one writer of the generated documents' Markdown tables."""

import pathlib
import re

import pytest

from stewart_drake.base.tables import markdown_lines, markdown_row, markdown_table

REPO = pathlib.Path(__file__).resolve().parent.parent


def test_the_table_is_written_exactly():
    text = markdown_table(["motion", "RMS [um]", "n"], [["breathing", f"{1.2345:.2f}", 3]])
    assert text == "| motion | RMS [um] | n |\n|---|---|---|\n| breathing | 1.23 | 3 |"
    assert markdown_lines(["a"], []) == ["| a |", "|---|"]


def test_blank_empty_and_short_rows_keep_the_documents_forms():
    # None: a blank cell '| |' (the corner above row labels, the cells after a failure);
    # '': an empty cell written '|  |' as any other text; a short row stays short.
    assert markdown_row([None, "reference", "chosen"]) == "| | reference | chosen |"
    assert markdown_row(["0.5 um", ""]) == "| 0.5 um |  |"
    lines = markdown_lines(["robot", "RMS", "peak"], [["ideal", "failed: diverged"]])
    assert lines[2] == "| ideal | failed: diverged |"
    assert markdown_row(["run", "failed: x", None, None]) == "| run | failed: x | | |"


def test_alignment_row_and_its_refusals():
    assert markdown_lines(["a", "b", "c"], [], align=[None, "right", "center"])[1] == (
        "|---|---:|:---:|"
    )
    with pytest.raises(ValueError, match="2 alignments for 3 columns"):
        markdown_table(["a", "b", "c"], [], align=["left", "left"])
    with pytest.raises(ValueError, match="unknown alignment 'middle'"):
        markdown_table(["a"], [], align=["middle"])


def test_no_module_writes_an_alignment_row_by_hand():
    """Every table of the package, its benchmarks and tools goes through base.tables; the layout
    table's tool reads the tree without importing the package (so it runs without Drake)."""
    rule = re.compile(r"""["']\|(?: ?:?-{3,}|["']\s*\+\s*["']-{3,})""")
    exempt = {"stewart_drake/base/tables.py", "tools/layout_table.py"}
    found = [
        str(p.relative_to(REPO))
        for folder in ("stewart_drake", "benchmarks", "tools")
        for p in sorted((REPO / folder).rglob("*.py"))
        if str(p.relative_to(REPO)) not in exempt and rule.search(p.read_text())
    ]
    assert found == []
    assert rule.search((REPO / "tools" / "layout_table.py").read_text())  # the pattern finds one
