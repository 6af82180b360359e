"""The trace study: its cases, one case run short, and tables whose verdicts follow the numbers."""

import pytest

from stewart_drake.references.organ.library import LIBRARY
from stewart_drake.studies import trace_study


def _row(label, none, learned, robot=trace_study.ROBOTS[0][0], again=None, peak=None, gamma=None):
    def fig(t_um, r_urad, peak_um=None, gamma_5um=0.9):
        return {
            "rms_translation_m": t_um * 1e-6,
            "rms_rotation_rad": r_urad * 1e-6,
            "peak_translation_m": (3 * t_um if peak_um is None else peak_um) * 1e-6,
            "peak_rotation_rad": 3 * r_urad * 1e-6,
            "gamma": [1.0, gamma_5um],
            "window_translation_m": [t_um * 1e-6] * 4,
            "window_rotation_rad": [r_urad * 1e-6] * 4,
            "lag_all_s": 0.0,
            "startup_translation_m": 2 * t_um * 1e-6,
            "startup_rotation_rad": 2 * r_urad * 1e-6,
            "startup_peak_translation_m": 5 * t_um * 1e-6,
            "resolution_m": 5.9e-6,
            "resolution_rad": 33.8e-6,
        }

    peaks, gammas = peak or (None, None, None), gamma or (0.9, 0.9, 0.9)
    return {
        "case": label,
        "robot": robot,
        "none": fig(*none, peaks[0], gammas[0]),
        "none_again": fig(*(again or none), peaks[1], gammas[1]),
        "learned": fig(*learned, peaks[2], gammas[2]),
        "learner": {"updates": 20, "skipped": 3, "rollbacks": 0, "stopped": 0},
        "wall_s": 10.0,
        "sim_s": 360.0,
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
    assert (
        "| a | 40.00 / 55.0; 40.00 / 55.0 | 4.00 / 19.0 | 120.0 / 12.0 | 90.0 / 90.0 |" in as_built
    )
    assert "| 80.00 / 8.00 um (peak 200.0 / 20.0) | 5.90 / 33.8 | 20 updates, 3 skipped" in as_built
    assert (
        "- Translation <= 5 um with learning: 1 of 2 motions (missed: b); 50 % against at "
        "least 80 %: NOT met." in as_built
    )
    assert "- Rotation <= 20 urad with learning: 1 of 2 motions (missed: b)." in as_built
    assert "NOT met: b (rotation RMS)." in as_built
    assert "| 6.00 / 31.0 (worse: rotation RMS) |" in as_built
    assert "| c | failed: the guard stopped the run" in as_built
    assert "counts_per_rev=524288" in finer.splitlines()[0]  # the robot's overrides shown
    assert "| a | 9.00 / 8.0; 9.00 / 8.0 | 3.00 / 7.0 |" in finer
    assert "100 % against at least 80 %: met." in finer and "met on every motion." in finer
    # within the spread of the two runs without learning: not worse
    results["b | x"] = _row("b", (10, 30), (4.5, 31.0), again=(10.2, 31.5))
    text = trace_study.tables(results).split(f"#### {fine}")[0]
    assert "2 of 2 motions; 100 % against at least 80 %: met." in text
    assert "Never worse than without learning" in text and "met on every motion." in text
    # a peak beyond both runs, a gamma below both
    results["b | x"] = _row("b", (10, 30), (4.5, 29.0), peak=(30, 32, 33), gamma=(0.5, 0.48, 0.47))
    text = trace_study.tables(results).split(f"#### {fine}")[0]
    assert "NOT met: b (peak translation, gamma 5 um / 10 ms)." in text
    results["b | x"] = _row("b", (10, 30), (4.5, 29.0), peak=(30, 34, 33), gamma=(0.5, 0.46, 0.47))
    assert "met on every motion." in trace_study.tables(results).split(f"#### {fine}")[0]
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
    n = len(trace_study.LIBRARY_CASES)
    assert [c.label for c in cases][:n] == [c.label for c in trace_study.LIBRARY_CASES]
    assert cases[-1].held_from.startswith("library:")
    # every motion of the library and the transfer, on every robot
    assert len(cases) == (len(trace_study.LIBRARY_CASES) + 1) * len(trace_study.ROBOTS)
    # every organ motion of the library (its registration motion is a tracker's, not an organ's)
    assert len(trace_study.LIBRARY_CASES) == len([m for m in LIBRARY if m != "registration"])
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
    assert out["sim_s"] == pytest.approx(12.0)
    assert out["learner"]["updates"] == 0  # held: nothing learned on this motion
    for mode in ("none", "none_again", "learned"):
        assert 0 < out[mode]["rms_translation_m"] < 1e-4
        assert len(out[mode]["window_translation_m"]) == 1  # one whole window of 2.5 s in 3 s
        assert 0 < out[mode]["gamma"][0] <= 1
