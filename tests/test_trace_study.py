"""The trace study: its cases, one case run short, and tables whose verdicts follow the numbers."""

import pytest

from stewart_drake.organ_motion import trace_study


def _row(label, none, learned, robot=trace_study.ROBOTS[0][0]):
    def fig(t_um, r_urad):
        return {
            "rms_translation_m": t_um * 1e-6,
            "rms_rotation_rad": r_urad * 1e-6,
            "peak_translation_m": 3 * t_um * 1e-6,
            "peak_rotation_rad": 3 * r_urad * 1e-6,
            "gamma": [1.0, 0.9],
            "window_translation_m": [t_um * 1e-6] * 4,
            "window_rotation_rad": [r_urad * 1e-6] * 4,
            "lag_all_s": 0.0,
        }

    return {
        "case": label,
        "robot": robot,
        "none": fig(*none),
        "learned": fig(*learned),
        "learner": {"updates": 20, "rollbacks": 0, "stopped": 0},
        "wall_s": 10.0,
        "sim_s": 240.0,
    }


def test_the_verdicts_are_computed_from_the_numbers(tmp_path):
    fine = trace_study.ROBOTS[1][0]
    results = {
        "a | x": _row("a", (40, 55), (4.0, 19.0)),
        "b | x": _row("b", (10, 30), (6.0, 31.0)),  # misses both goals, worse in rotation
        f"c | {trace_study.ROBOTS[0][0]}": "the guard stopped the run",
        "a | y": _row("a", (9, 8), (3.0, 7.0), robot=fine),
    }
    text = trace_study.tables(results)
    as_built, finer = text.split(f"#### {fine}")
    assert "| a | 40.00 / 55.0 | 4.00 / 19.0 | 10.00x |" in as_built
    assert "- Translation <= 5 um with learning: 1 of 2 motions (missed: b)." in as_built
    assert "- Rotation <= 20 urad with learning: 1 of 2 motions (missed: b)." in as_built
    assert "- Lower than without learning (translation and rotation): not on b." in as_built
    # 31 urad against 30: within 1.2 x 30 + one count (48 urad at 2^17 counts at the tip)
    assert "one encoder count at the crank tip, 5.3 um / 48 urad): met on every" in as_built
    assert "| c | failed: the guard stopped the run" in as_built
    assert "counts_per_rev=524288" in finer.splitlines()[0]  # the robot's overrides shown
    assert "| a | 9.00 / 8.0 | 3.00 / 7.0 | 3.00x |" in finer
    assert "1 of 1 motions." in finer and "on every motion." in finer
    results["b | x"] = _row("b", (10, 30), (4.5, 18.0))
    text = trace_study.tables(results).split(f"#### {fine}")[0]
    assert (
        "2 of 2 motions." in text
        and "Lower than without learning (translation and rotation): on every motion." in text
    )
    results["b | x"] = _row("b", (10, 30), (4.5, 90.0))
    assert "missed on b." in trace_study.tables(results).split(f"#### {fine}")[0]
    # written between its markers, the rest of the page kept
    doc = tmp_path / "page.md"
    doc.write_text("# page\n\nkept\n")
    trace_study.write_tables(doc, results)
    trace_study.write_tables(doc, results)
    page = doc.read_text()
    assert page.startswith("# page\n\nkept\n") and page.count(trace_study.TABLE_MARKERS[0]) == 1
    assert (tmp_path / "organ_motion_traces.json").exists()
    assert (tmp_path / "organ_motion_traces.png").stat().st_size > 10_000


def test_the_cases_take_the_patients_traces_found_and_the_transfer(tmp_path):
    cases = trace_study.trace_cases(None)
    assert [c.label for c in cases][:2] == [c.label for c in trace_study.LIBRARY_CASES]
    assert cases[-1].held_from.startswith("library:")
    assert len(cases) == 3 * len(trace_study.ROBOTS)  # every motion on every robot
    assert len({c.job_id for c in cases}) == len(cases)
    assert cases[-1].overrides == trace_study.ROBOTS[-1][1]
    folder = tmp_path / "Documentation" / "Liver"
    folder.mkdir(parents=True)
    for name in ("Liver_Trace 1.txt", "Liver_Trace 2.txt", "unrelated.txt"):
        (folder / name).write_text("0 0 0 0 0 0 0\n")
    cases = trace_study.trace_cases(tmp_path, robots=trace_study.ROBOTS[:1])
    labels = [c.label for c in cases]
    assert "liver 1 (IntERAct)" in labels and labels[-1] == "liver 2, model learned on liver 1"
    assert cases[-1].held_from.endswith("Liver_Trace 1.txt")
    assert cases[-1].path.endswith("Liver_Trace 2.txt")


def test_a_short_transfer_case_runs_both_ways_and_holds_its_model(monkeypatch):
    # 3 s runs with 2.5 s windows: the structure of the 120 s runs in a fortieth of the time
    monkeypatch.setattr(trace_study, "DURATION_S", 3.0)
    monkeypatch.setattr(trace_study, "MEASURED_FROM_S", 1.0)
    monkeypatch.setattr(trace_study, "WINDOW_S", 2.5)
    case = trace_study.trace_cases(None)[-1]  # on the finer robot
    out = trace_study.run_case(case)
    assert out["robot"] == trace_study.ROBOTS[-1][0]
    assert out["sim_s"] == pytest.approx(9.0)
    assert out["learner"]["updates"] == 0  # held: nothing learned on this motion
    for mode in ("none", "learned"):
        assert 0 < out[mode]["rms_translation_m"] < 1e-4
        assert len(out[mode]["window_translation_m"]) == 1  # one whole window of 2.5 s in 3 s
        assert 0 < out[mode]["gamma"][0] <= 1
