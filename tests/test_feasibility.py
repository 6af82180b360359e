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


def test_the_check_says_what_its_limits_are_and_draws_each_measure_on_its_own_axis(
    tmp_path, monkeypatch
):
    """The torque limit a reference may use is given with what it is a share of (90 % of the
    motors' 0.702 N m peak), in the summary and on the plot beside the motors' own line; cond(J)
    and 1/sigma_max(J) each get a panel and a limit of their own (on one panel's twin axis a
    curve crossed the other's limit line); motors are named 0..5 with the paper's T1..T6."""
    import matplotlib.pyplot as plt
    import numpy as np

    from stewart_drake.simulation.scenario_io import load_scenario
    from stewart_drake.studies.feasibility import check, plot_margins

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
