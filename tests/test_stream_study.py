"""The stream study's verdicts: the acceptance on the end-to-end ratios (b) judged from the
numbers, against goals written out here, and refused for every figure that misses one."""

import numpy as np
import pytest

from stewart_drake.studies import stream_study
from stewart_drake.studies.stream_study import StreamCase, judge, peak_ratio, verdicts

# A set that meets every goal, with margins written out: at 0.2 s the mean RMS ratio
# (0.3 + 0.4 + 0.5) / 3 = 0.4 <= 0.5, the largest 0.5 <= 0.8, the largest peak ratio 1.05 <=
# 1.1; at 0.5 s the mean (0.6 + 0.6 + 0.75) / 3 = 0.65 <= 0.7; the largest of all 0.75 <= 1.
GOOD_B = {0.2: [0.3, 0.4, 0.5], 0.5: [0.6, 0.6, 0.75]}
GOOD_PEAK = {0.2: [0.9, 1.0, 1.05], 0.5: [1.3, 1.0, 1.0]}


def _by_name(checks):
    return {name: (figure, goal, met) for name, figure, goal, met in checks}


def test_a_set_within_every_goal_meets_them_all_with_its_own_figures():
    checks = _by_name(judge(GOOD_B, GOOD_PEAK))
    assert checks == {
        "0.2 s, mean RMS ratio": (pytest.approx(0.4), 0.5, True),
        "0.2 s, largest RMS ratio": (pytest.approx(0.5), 0.8, True),
        "0.2 s, largest peak ratio": (pytest.approx(1.05), 1.1, True),
        "0.5 s, mean RMS ratio": (pytest.approx(0.65), 0.7, True),
        "any latency, largest RMS ratio": (pytest.approx(0.75), 1.0, True),
    }


@pytest.mark.parametrize(
    "latency, where, value, missed",
    [
        # the mean at 0.2 s: (0.3 + 0.4 + 0.83) / 3 = 0.51 > 0.5 (and 0.83 > 0.8)
        (0.2, 2, 0.83, {"0.2 s, mean RMS ratio", "0.2 s, largest RMS ratio"}),
        # one motion above 0.8, the mean (0.3 + 0.4 + 0.81) / 3 = 0.503 > 0.5 as well
        (0.2, 2, 0.81, {"0.2 s, mean RMS ratio", "0.2 s, largest RMS ratio"}),
        # a better motion: (0.1 + 0.4 + 0.5) / 3 = 0.33, every goal still met
        (0.2, 0, 0.1, set()),
        # the mean at 0.5 s: (0.6 + 0.6 + 0.95) / 3 = 0.717 > 0.7
        (0.5, 2, 0.95, {"0.5 s, mean RMS ratio"}),
        # a motion worse than none at 0.5 s (1.01 > 1), the mean (0.6 + 0.6 + 1.01) / 3 > 0.7
        (0.5, 2, 1.01, {"0.5 s, mean RMS ratio", "any latency, largest RMS ratio"}),
    ],
)
def test_each_rms_goal_is_missed_by_a_figure_beyond_it(latency, where, value, missed):
    b = {k: list(v) for k, v in GOOD_B.items()}
    b[latency][where] = value
    checks = judge(b, GOOD_PEAK)
    assert {name for name, _, _, met in checks if not met} == missed


def test_a_peak_more_than_a_tenth_above_nones_misses_at_0_2_s_only():
    peak = {0.2: [0.9, 1.0, 1.11], 0.5: GOOD_PEAK[0.5]}
    assert {n for n, _, _, met in judge(GOOD_B, peak) if not met} == {"0.2 s, largest peak ratio"}
    # 0.5 s has no peak goal: a peak twice none's there is not judged
    peak = {0.2: GOOD_PEAK[0.2], 0.5: [2.0, 1.0, 1.0]}
    assert all(met for *_, met in judge(GOOD_B, peak))


def test_figures_that_are_not_finite_are_left_out_and_none_finite_is_missed():
    b = {0.2: [0.3, float("nan"), 0.5], 0.5: GOOD_B[0.5]}
    checks = _by_name(judge(b, GOOD_PEAK))
    assert checks["0.2 s, mean RMS ratio"][0] == pytest.approx(0.4)  # (0.3 + 0.5) / 2
    nan = float("nan")
    checks = _by_name(judge({0.2: [nan, nan], 0.5: [0.5, 0.5]}, {0.2: [nan], 0.5: [1.0]}))
    for name in ("0.2 s, mean RMS ratio", "0.2 s, largest RMS ratio", "0.2 s, largest peak ratio"):
        assert checks[name][2] is False and np.isnan(checks[name][0])


def _figures(b, peak_with, peak_none=1e-3, a=0.3, used=1.0):
    return {
        "horizon": {"ratio": a},
        "ratio_translation": b,
        "with": {"peak_translation_m": peak_with},
        "without": {"peak_translation_m": peak_none},
        "used": used,
    }


def test_the_peak_ratio_is_the_largest_error_with_over_without():
    assert peak_ratio(_figures(0.5, 1.2e-3, 1e-3)) == pytest.approx(1.2)
    assert np.isnan(peak_ratio(_figures(0.5, 1e-3, 0.0)))


def test_the_verdict_lines_say_each_set_and_what_it_missed(monkeypatch):
    monkeypatch.setattr(stream_study, "LATENCIES", (0.2, 0.5))
    rows = []
    for i in range(3):
        lib = StreamCase(f"lib {i}", motion="breathing", tuned_on=True)
        rows.append((lib, {0.2: _figures(0.4, 1e-3), 0.5: _figures(0.6, 1e-3)}))
        trace = StreamCase(f"trace {i}", path="x.txt")
        # IntERAct: one trace with a peak 1.2 times none's at 0.2 s
        rows.append(
            (trace, {0.2: _figures(0.4, 1.2e-3 if i == 1 else 1e-3), 0.5: _figures(0.6, 1e-3)})
        )
    lines = verdicts(rows)
    assert len(lines) == 2
    assert lines[0].startswith("IntERAct's traces (3)")
    assert "0.2 s, largest peak ratio 1.20 (goal <= 1.1): MISSED" in lines[0]
    assert "not all met" in lines[0]
    assert lines[1].startswith("the library's motions (3)")
    assert "MISSED" not in lines[1] and "all met" in lines[1]


def _full(b, peak_with):
    side = {"rms_translation_m": 1e-3, "nrmse_translation": 0.1, "within_tolerance": 0.5}
    f = _figures(b, peak_with)
    f["with"].update(side)
    f["without"].update(side)
    f["horizon"].update(
        none_translation_m=1e-3, rms_translation_m=5e-4, model_translation_m=5e-4,
        nrmse_none=0.2, nrmse=0.1,
    )  # fmt: skip
    f.update(rate_hz=5.0, ratio_rotation=0.5)
    return f


def test_the_tables_give_each_motions_source_and_three_ratios(monkeypatch):
    from stewart_drake.references.prediction import PredictorSettings

    monkeypatch.setattr(stream_study, "LATENCIES", (0.2, 0.5))
    rows = [(StreamCase("trace 0", path="x.txt"), {0.2: _full(0.4, 1.2e-3), 0.5: _full(0.6, 1e-3)})]
    lines = stream_study.tables(rows, PredictorSettings(history_s=2.0))
    # (a) 0.3, (b) 0.4, peak 1.2e-3 / 1e-3
    assert "| trace 0 | IntERAct | 5 | 0.30 / 0.40 / 1.20 | 0.30 / 0.60 / 1.00 |" in lines
    assert any("history 2 s, memory 30 s" in line for line in lines)
    assert not any("tuning" in line.lower() for line in lines)
