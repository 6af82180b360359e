"""The feasibility tables: the committed clearance table is what the code computes."""


def test_committed_clearance_table_is_current():
    from pathlib import Path

    from stewart_drake.studies.feasibility import CLEARANCE_TABLE_MARKERS, clearance_table

    doc = (Path(__file__).resolve().parents[1] / "docs" / "reference_geometry.md").read_text()
    start, end = (doc.index(m) for m in CLEARANCE_TABLE_MARKERS)
    committed = doc[start : end + len(CLEARANCE_TABLE_MARKERS[1])]
    assert committed == clearance_table(), (
        "docs/reference_geometry.md's clearance table is stale: paste "
        "stewart_drake.studies.feasibility.clearance_table() between its markers"
    )
