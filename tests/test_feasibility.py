"""The feasibility tables: the committed clearance table is what the code computes."""

import pytest


def _committed_clearance_table() -> str:
    from pathlib import Path

    from stewart_drake.analysis.feasibility import CLEARANCE_TABLE_MARKERS

    doc = (Path(__file__).resolve().parents[1] / "docs" / "reference_geometry.md").read_text()
    start, end = (doc.index(m) for m in CLEARANCE_TABLE_MARKERS)
    return doc[start : end + len(CLEARANCE_TABLE_MARKERS[1])]


@pytest.mark.slow
def test_committed_clearance_table_is_current():
    """The whole sweep of the paper manoeuvre (its 10 s at 1 mm of motion); the default tiers
    check each row at its own time (test_each_committed_clearance_row_holds_at_its_time)."""
    from stewart_drake.analysis.feasibility import clearance_table

    assert _committed_clearance_table() == clearance_table(), (
        "docs/reference_geometry.md's clearance table is stale: paste "
        "stewart_drake.analysis.feasibility.clearance_table() between its markers"
    )


def test_each_committed_clearance_row_holds_at_its_time():
    """Each row of the committed table as clearance_table() computes it, from the poses it
    measures (the same samples of the paper manoeuvre) within 5 ms of the row's time only: the
    smallest clearance of a pair of families lies there, so the rows come out as committed
    unless the parts, the geometry or the query changed (the slow tier sweeps the whole path:
    test_committed_clearance_table_is_current)."""
    import numpy as np

    from stewart_drake.plant.clearance import clearance_model, family, sample_indices
    from stewart_drake.references.trajectories import paper_manoeuvre
    from stewart_drake.robot.geometry import StewartGeometry

    rows = [
        [cell.strip() for cell in line.strip("|").split("|")]
        for line in _committed_clearance_table().splitlines()
        if line.startswith("| ") and not line.startswith("| parts")
    ]
    timed = [r for r in rows if "fixed by design" not in r[2]]
    fixed = [r for r in rows if "fixed by design" in r[2]]
    geometry = StewartGeometry()
    model = clearance_model(geometry)
    t = np.arange(0.0, 10.0 + 5e-4, 1e-3)
    x = paper_manoeuvre().evaluate(t)[0]
    keep = sample_indices(geometry, x, 1e-3)
    times = np.array(sorted({float(r[2]) for r in timed}))
    near = keep[np.abs(t[keep][:, None] - times[None, :]).min(axis=1) <= 0.005 + 1e-9]
    _, _, families = model.sweep(x[near], by_family=True, max_distance=0.3)
    computed = {
        f"{a} / {b}": [f"{1e3 * d:.1f}", f"{t[near][k]:.2f}", f"{c.part_a} / {c.part_b}"]
        for (a, b), (d, k, c) in families.items()
    }
    assert {r[0]: r[1:] for r in timed} == computed
    by_design = {}
    for c in model.fixed:
        key = " / ".join(sorted((family(c.part_a), family(c.part_b))))
        by_design.setdefault(key, [f"{1e3 * c.distance:.1f}", f"{c.part_a} / {c.part_b}"])
    assert {r[0]: [r[1], r[3]] for r in fixed} == by_design


def test_the_check_says_what_its_limits_are_and_draws_each_measure_on_its_own_axis(
    tmp_path, monkeypatch
):
    """The torque limit a reference may use is given with what it is a share of (90 % of the
    motors' 0.702 N m peak), in the summary and on the plot beside the motors' own line; cond(J)
    and 1/sigma_max(J) each get a panel and a limit of their own (on one panel's twin axis a
    curve crossed the other's limit line); motors are named 0..5 with the paper's T1..T6."""
    import matplotlib.pyplot as plt
    import numpy as np

    from stewart_drake.analysis.feasibility import check, plot_margins
    from stewart_drake.run.scenario_io import load_scenario

    report = check(load_scenario("paper_hardware"))
    assert abs(report.torque_limit / 0.9 - 0.702) < 5e-4 and report.effort_margin == 0.9
    assert "limit 0.632 N m, 90 % of the motors' 0.702 N m peak" in report.summary()
    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    plot_margins(report, tmp_path / "check.png")
    (fig,) = figures
    assert len(fig.axes) == 7  # reach, joints, cond, 1/sigma_max, clearance, torque, speed: no twin
    by_label = {ax.get_ylabel().split("\n")[0]: ax for ax in fig.axes}
    for label, threshold in (
        ("cond(J)", report.cond_threshold),
        ("1/sigma_max(J)", report.sigma_min_inv_threshold),
    ):
        ys = [float(np.ravel(line.get_ydata())[0]) for line in by_label[label].get_lines()]
        assert threshold in ys, (label, ys)  # its own limit line, on its own axis
    torque = by_label["|torque| needed"]
    assert [t.get_text() for t in torque.get_legend().get_texts()] == [
        f"motor {i} (T{i + 1})" for i in range(6)
    ]
    lines = [float(np.ravel(line.get_ydata())[0]) for line in torque.get_lines()[6:]]
    assert np.allclose(sorted(lines), [0.632, 0.702], atol=5e-4)
    assert "motors' peak 0.702 N m" in " ".join(t.get_text() for t in torque.texts)
