"""The predictor chosen across sources, leaving each out: the choice and the verdicts on rows
written here (their figures known), the forms real inputs take applied as said, a motion that
moves only in the warm-up reported and not judged, and one real measurement of a candidate
beside no prediction. Fast unit tests."""

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.references.organ.library import make_motion
from stewart_drake.references.stream import Stream, stream_of
from stewart_drake.studies import stream_selection as sel
from stewart_drake.studies.stream_sources import (
    Source,
    StreamForm,
    hurting,
    random_walk,
    sources,
)
from stewart_drake.studies.stream_study import StreamCase


def _row(source, candidate, latency, rms, peak, case="m", judged=True):
    return {
        "source": source, "case": case, "latency_s": latency, "candidate": candidate,
        "rms_ratio": rms, "peak_ratio": peak, "used": 1.0, "fallbacks": 0, "rejected": 0,
        "judged": judged,
    }  # fmt: skip


def _rows(table):
    """{candidate: {source: (rms at 0.2, rms at 0.5, peak at 0.2)}} as rows."""
    out = []
    for c, per_source in table.items():
        for s, (a, b, p) in per_source.items():
            out += [_row(s, c, 0.2, a, p), _row(s, c, 0.5, b, 1.0)]
    return out


def test_the_choice_weighs_sources_alike_and_keeps_peaks_within_the_limit():
    """Three sources. "sharp" has the least mean but a peak of 1.2 on source C: it is chosen
    only when C is left out; "steady" otherwise (its mean the least of those whose peaks stay
    within 1.05). The score is the mean over sources of each source's mean, both latencies."""
    rows = _rows({
        "sharp": {"A": (0.2, 0.3, 1.0), "B": (0.2, 0.3, 1.0), "C": (0.2, 0.3, 1.2)},
        "steady": {"A": (0.3, 0.4, 1.0), "B": (0.3, 0.4, 1.0), "C": (0.3, 0.4, 1.0)},
        "slow": {"A": (0.5, 0.6, 1.0), "B": (0.5, 0.6, 1.0), "C": (0.5, 0.6, 1.0)},
    })  # fmt: skip
    assert sel.score(rows, "steady") == pytest.approx((0.35, 1.0))
    assert sel.score(rows, "sharp", exclude="C") == pytest.approx((0.25, 1.0))
    assert sel.choose(rows) == "steady"
    assert sel.choose(rows, exclude="C") == "sharp"
    assert sel.choose(rows, exclude="A") == "steady"
    loso = {s: c for s, c, _, _ in sel.leave_one_out(rows)}
    assert loso == {"A": "steady", "B": "steady", "C": "sharp"}


def test_when_no_candidate_keeps_its_peaks_the_least_peak_is_chosen():
    rows = _rows({
        "a": {"A": (0.2, 0.3, 1.3), "B": (0.2, 0.3, 1.0)},
        "b": {"A": (0.4, 0.5, 1.1), "B": (0.4, 0.5, 1.0)},
    })  # fmt: skip
    assert sel.choose(rows) == "b"


@pytest.mark.parametrize(
    "rms_02, peak, rms_05, missed",
    [
        ((0.40, 0.45), (1.0, 1.05), (0.6, 0.6), []),
        ((0.40, 0.51), (1.0, 1.0), (0.5, 0.5), ["0.2 s, mean RMS ratio"]),
        ((0.05, 0.81), (1.0, 1.0), (0.5, 0.5), ["0.2 s, largest RMS ratio"]),
        ((0.40, 0.40), (1.0, 1.06), (0.5, 0.5), ["0.2 s, largest peak ratio"]),
        ((0.40, 0.40), (1.0, 1.0), (0.6, 0.61), ["0.5 s, mean RMS ratio"]),
        ((np.nan, np.nan), (np.nan, np.nan), (0.5, 0.5), ["0.2 s, mean RMS ratio",
         "0.2 s, largest RMS ratio", "0.2 s, largest peak ratio"]),
    ],
)  # fmt: skip
def test_judge_holds_each_goal_at_its_edge(rms_02, peak, rms_05, missed):
    """Each goal met at its value and missed just above it; figures that are not finite show
    no goal met."""
    figures = {
        0.2: {"rms": np.array(rms_02), "peak": np.array(peak)},
        0.5: {"rms": np.array(rms_05), "peak": np.array([1.0, 1.0])},
    }
    checks = sel.judge(figures)
    assert [w for w, _, _, met in checks if not met] == missed
    assert len(checks) == 4


def test_a_motion_that_moves_only_in_the_warm_up_is_reported_not_judged():
    """The library's persistent excursion (done within 5 s) does not move once a predictor
    may be used (6.3 s at 25 Hz, 0.2 s late); breathing does. A row not judged counts in no
    score."""
    t = np.arange(0.0, 120.0, 0.01)
    for motion, moves in (("persistent_excursion", False), ("breathing", True)):
        m = make_motion(motion, {})
        stream = stream_of(m, 0.2, 25.0, 120.0)
        assert sel.moves_after_warm_up(np.asarray(m.evaluate(t)[0]), t, stream) == moves
    rows = [_row("A", "c", 0.2, 0.3, 1.0), _row("A", "c", 0.2, 1.0, 1.0, "x", judged=False)]
    rows += [_row("A", "c", 0.5, 0.3, 1.0)]
    assert sel.score(rows, "c") == pytest.approx((0.3, 1.0))


def _stream(n=20000):
    t = np.arange(n) * 0.04
    poses = np.zeros((n, 6))
    poses[:, 5] = 0.3 + 0.01 * np.sin(t)
    return Stream(t, poses, 0.2, "test")


def test_the_forms_do_what_they_say():
    """Noise of the std given on each translation only; outliers on about the share given,
    of the size given; a dropout repeats the sample before; positions written in steps."""
    s = _stream()
    noisy = StreamForm(noise_m=3e-4, seed=1).apply(s).poses - s.poses
    assert np.all(noisy[:, :3] == 0)
    assert np.std(noisy[:, 3:], axis=0) == pytest.approx([3e-4] * 3, rel=0.03)
    off = StreamForm(outlier_share=0.01, outlier_m=3e-3, seed=2).apply(s).poses - s.poses
    hit = np.any(off != 0, axis=1)
    assert 150 <= hit.sum() <= 250
    assert np.std(off[hit, 3:]) == pytest.approx(3e-3, rel=0.15)
    dropped = StreamForm(dropout_share=0.05, seed=3).apply(s).poses
    repeated = np.all(dropped[1:] == dropped[:-1], axis=1)
    assert 800 <= repeated.sum() <= 1200
    stepped = StreamForm(quantum_m=1e-4).apply(s).poses
    assert np.allclose(stepped[:, 3:] / 1e-4, np.round(stepped[:, 3:] / 1e-4), atol=1e-6)
    assert np.max(np.abs(stepped - s.poses)) == pytest.approx(0.5e-4, rel=0.05)
    assert StreamForm(rate_hz=10.0, quantum_m=1e-4).words() == "10 Hz, 0.1 mm steps"


@pytest.mark.parametrize(
    "change",
    [
        {"noise_m": -1.0}, {"outlier_share": 0.6}, {"dropout_share": -0.1}, {"seed": None},
        {"seed": -1}, {"seed": 1.5}, {"seed": True},
    ],
)  # fmt: skip
def test_bad_forms_are_refused(change):
    with pytest.raises(InvalidConfigError):
        StreamForm(**change)


def test_the_sources_and_the_motions_where_prediction_cannot_pay():
    """Without the traces: the library and the seven other sources, each with motions; the
    random walk's increments have the stated step and are independent."""
    names = [s.name for s in sources(None)]
    assert names[0] == "library" and "IntERAct" not in names and len(names) == 8
    assert [s.name for s in hurting()] == ["random walk", "10 % outliers of 10 mm"]
    walk = random_walk(4)
    t = np.arange(0.0, 100.0, 0.01)
    d = np.diff(np.asarray(walk.evaluate(t)[0])[:, 3:], axis=0)
    assert np.std(d) == pytest.approx(1e-4, rel=0.05)
    assert abs(np.corrcoef(d[1:, 0], d[:-1, 0])[0, 1]) < 0.05


def test_one_measurement_beside_no_prediction():
    """Breathing at 25 Hz (120 s, 0.2 and 0.5 s late) by the shipped linear regression:
    ratio (b) 0.25-0.35 at both (0.290 and 0.311 measured), judged, used on 85-97 % of the
    arrivals (92 %); no prediction against itself is 1.0 exactly."""
    source = Source("test", (StreamCase("breathing", "breathing"),), StreamForm(rate_hz=25.0))
    candidates = (sel.Candidate("linear", "linear"), sel.Candidate("none", "none"))
    rows = sel.measure([source], candidates)
    by = {(r["candidate"], r["latency_s"]): r for r in rows}
    for lat in (0.2, 0.5):
        assert 0.25 < by["linear", lat]["rms_ratio"] < 0.35
        assert 0.85 < by["linear", lat]["used"] < 0.97 and by["linear", lat]["judged"]
        assert by["none", lat]["rms_ratio"] == 1.0 and by["none", lat]["used"] == 0.0
        assert 0.2 < by["linear", lat]["peak_ratio"] <= 1.0 and by["none", lat]["peak_ratio"] == 1.0
        r = by["linear", lat]
        assert (r["source"], r["case"], r["fallbacks"], r["rejected"]) == (
            "test",
            "breathing",
            0,
            0,
        )
    assert len(rows) == 4
    # Taking the outliers out (outlier_k) counts what it rejected: on breathing with 1 % of its
    # samples 3 mm off, about 1 % of 3000 samples' 3 axes each way.
    glitched = Source(
        "glitched", source.cases, StreamForm(rate_hz=25.0, outlier_share=0.01, seed=3)
    )
    settings = sel.PredictorSettings(outlier_k=4.0)
    rows = sel.measure([glitched], (sel.Candidate("taken out", "linear", settings),), (0.2,))
    assert 40 <= rows[0]["rejected"] <= 3 * 60


def test_a_motion_at_rest_is_measured_unjudged_and_unused():
    """A still motion: no prediction's error is 0, so the ratios are NaN, nothing moves after
    the warm-up (not judged) and no axis moves (used 0)."""
    from stewart_drake.references.samples import CubicSplineTrajectory

    still = CubicSplineTrajectory(np.array([0.0, 60.0]), np.tile([0, 0, 0, 0, 0, 0.3], (2, 1)))
    source = Source(
        "still", (StreamCase("still", made_by=lambda: still),), StreamForm(rate_hz=25.0)
    )
    (row,) = sel.measure([source], (sel.Candidate("linear", "linear"),), (0.2,))
    assert np.isnan(row["rms_ratio"]) and np.isnan(row["peak_ratio"])
    assert row["used"] == 0.0 and not row["judged"]


def _table_rows():
    """Two candidates on source A (two motions, 10 Hz in 0.1 mm steps) and B (one motion, as
    sampled), a motion of B not judged, and the fallback's two runs; their figures chosen so
    that every cell below is worked out by hand."""
    rows = [
        _row("A", "good", 0.2, 0.30, 0.90, "m1"), _row("A", "good", 0.2, 0.90, 1.00, "m2"),
        _row("A", "good", 0.5, 0.40, 1.00, "m1"), _row("A", "good", 0.5, 0.52, 1.00, "m2"),
        _row("B", "good", 0.2, 0.20, 0.80, "m1"), _row("B", "good", 0.5, 0.30, 1.00, "m1"),
        _row("A", "bad", 0.2, 0.60, 1.20, "m1"), _row("A", "bad", 0.2, 0.60, 1.20, "m2"),
        _row("A", "bad", 0.5, 0.70, 1.00, "m1"), _row("A", "bad", 0.5, 0.70, 1.00, "m2"),
        _row("B", "bad", 0.2, 0.50, 1.00, "m1"), _row("B", "bad", 0.5, 0.60, 1.00, "m1"),
        _row("B", "good", 0.2, 9.0, 9.0, "still", judged=False),
        _row("B", "bad", 0.2, 9.0, 9.0, "still", judged=False),
        _row("A", "good", 0.5, 9.0, 9.0, "early", judged=False),
    ]  # fmt: skip
    rows[0]["fallbacks"], rows[2]["fallbacks"] = 1, 5  # only 0.2 s's are counted
    fallback = [_row("walk", "good", 0.2, 1.0, 1.02, "walk 1"), _row("walk", "good", 0.5, 1.031,
                1.0, "walk 1")]  # fmt: skip
    fallback[0]["fallbacks"] = 3
    cases = (StreamCase("m1", "breathing"), StreamCase("m2", "breathing"))
    srcs = [Source("A", cases, StreamForm(rate_hz=10.0, quantum_m=1e-4)), Source("B", cases[:1])]
    return rows, fallback, srcs


def test_the_verdicts_say_what_the_rows_hold():
    """Per source left out, the candidate chosen on the other and each goal's figure (A: good
    chosen on B, as bad's peak on A is 1.2; A's means 0.60 and 0.46, its largest 0.90); then
    the fallback's largest ratio, 1.031 above 1.03."""
    rows, fallback, _ = _table_rows()
    assert sel.verdicts(rows, fallback) == [
        "A left out, good chosen on the others: 0.2 s, mean RMS ratio 0.60 (goal <= 0.45): "
        "MISSED; 0.2 s, largest RMS ratio 0.90 (goal <= 0.8): MISSED; 0.2 s, largest peak "
        "ratio 1.00 (goal <= 1.05): met; 0.5 s, mean RMS ratio 0.46 (goal <= 0.6): met",
        "B left out, good chosen on the others: 0.2 s, mean RMS ratio 0.20 (goal <= 0.45): "
        "met; 0.2 s, largest RMS ratio 0.20 (goal <= 0.8): met; 0.2 s, largest peak ratio 0.80 "
        "(goal <= 1.05): met; 0.5 s, mean RMS ratio 0.30 (goal <= 0.6): met",
        "where prediction cannot pay (2 runs): the largest RMS or peak ratio 1.031 "
        "(goal <= 1.03): MISSED",
    ]
    assert sel.fallback_checks(fallback) == [
        ("walk", "walk 1", 0.2, 1.0, 1.02, 3, True),
        ("walk", "walk 1", 0.5, 1.031, 1.0, 0, False),
    ]
    assert sel.verdicts(rows)[-1].startswith("B left out")  # no fallback: no line for it
    fallback[1]["rms_ratio"] = 1.03  # at the goal: met
    assert sel.verdicts(rows, fallback)[-1] == (
        "where prediction cannot pay (2 runs): the largest RMS or peak ratio 1.030 "
        "(goal <= 1.03): met"
    )
    assert [c[6] for c in sel.fallback_checks(fallback)] == [True, True]
    fallback[0]["peak_ratio"] = 1.03  # at the goal: met
    assert [c[6] for c in sel.fallback_checks(fallback)] == [True, True]
    fallback[0]["peak_ratio"] = 1.0301
    assert [c[6] for c in sel.fallback_checks(fallback)] == [False, True]


def test_the_tables_say_what_the_rows_hold(tmp_path):
    """Every cell worked out by hand: the sources left out (motions and form, the choice,
    mean (range) of each figure, 0.2 s's fallbacks, the goals missed), every candidate on every
    source with its score on all (good: the mean of 0.60, 0.46, 0.20, 0.30; bad: of 0.60, 0.70,
    0.50, 0.60), the motion not judged once, the fallback's runs; written between the markers
    with what is around them kept."""
    rows, fallback, srcs = _table_rows()
    lines = sel.tables(rows, srcs, fallback)
    text = "\n".join(lines)
    assert lines[0] == "### The predictor chosen across sources, judged on the source left out"
    assert "at 0.2 s, mean <= 0.45, none above 0.8, peak within 1.05; at 0.5 s, mean <= 0.6" in (
        text
    )
    assert "within 1.05 on every motion at 0.2 s" in text
    assert "The shipped choice, on every source: **good**." in text
    for line in (
        "| source left out | motions, form | chosen on the others | RMS ratio, 0.2 s | peak "
        "ratio, 0.2 s | RMS ratio, 0.5 s | fallbacks | verdict |",
        "| A | 2, 10 Hz, 0.1 mm steps | good | 0.60 (0.30-0.90) | 0.95 (0.90-1.00) | 0.46 "
        "(0.40-0.52) | 1 | MISSED: 0.2 s, mean RMS ratio 0.60 > 0.45; 0.2 s, largest RMS ratio "
        "0.90 > 0.8 |",
        "| B | 1, as sampled | good | 0.20 (0.20-0.20) | 0.80 (0.80-0.80) | 0.30 (0.30-0.30) | 0 "
        "| met |",
        "#### Every candidate on every source at 0.2 s: mean RMS ratio / largest peak ratio",
        "| candidate | A | B | score on all (mean / peak) |",
        "| good | 0.60 / 1.00 | 0.20 / 0.80 | 0.390 / 1.00 |",
        "| bad | 0.60 / 1.20 | 0.50 / 1.00 | 0.600 / 1.20 |",
        "#### Where prediction cannot pay: good, beside no prediction",
        "| source | motion | latency | RMS ratio | peak ratio | fallbacks | verdict |",
        "| walk | walk 1 | 0.2 s | 1.000 | 1.020 | 3 | met |",
        "| walk | walk 1 | 0.5 s | 1.031 | 1.000 | 0 | MISSED |",
    ):
        assert line in lines, line
    assert text.count("still (B, 0.2 s)") == 1
    assert "any predictor and none): still (B, 0.2 s); early (A, 0.5 s).\n" in text
    assert "streamed 0.2 s and 0.5 s late" in text
    # Markdown's blank lines: after each heading and paragraph, around each table.
    for i, line in enumerate(lines):
        if line.startswith("#") or (line.startswith("|") and not lines[i - 1].startswith("|")):
            assert lines[i - 1 : i] in ([], [""]) and (line.startswith("|") or lines[i + 1] == "")
        if line.startswith("|") and i + 1 < len(lines):
            assert lines[i + 1].startswith("|") or lines[i + 1] == "", line
    assert "RMS and peak ratio <= 1.03." in text
    assert "Not judged" not in "\n".join(sel.tables([r for r in rows if r["judged"]], srcs))
    doc = tmp_path / "study.md"
    doc.write_text("before\n" + "\n".join(sel.TABLE_MARKERS) + "\nafter\n")
    assert sel.write_tables(doc, rows, srcs, fallback) == doc
    written = doc.read_text()
    assert written.startswith("before\n" + sel.TABLE_MARKERS[0]) and written.endswith(
        sel.TABLE_MARKERS[1] + "\nafter\n"
    )
    assert "\n".join([sel.TABLE_MARKERS[0], "", *lines, "", sel.TABLE_MARKERS[1]]) in written


def test_the_sources_hold_the_motions_and_forms_the_docs_name():
    """Each source's form in the words the table prints, and drawn from its own seed; the forms
    laid on the five breathing motions named; the irregular source's motions those of their
    labels' seed and variation (built here from the library by name); the library's 11."""
    from stewart_drake.studies.stream_study import case_reference

    by = {s.name: s for s in sources(None)}
    assert list(by) == [
        "library", "10 Hz", "10 Hz, 0.1 mm steps", "0.3 mm noise", "1 % outliers",
        "5 % dropouts", "irregular", "drifting",
    ]  # fmt: skip
    assert len(by["library"].cases) == 11 and all(c.tuned_on for c in by["library"].cases)
    words = {name: s.form.words() for name, s in by.items()}
    assert words == {
        "library": "as sampled", "10 Hz": "10 Hz", "10 Hz, 0.1 mm steps": "10 Hz, 0.1 mm steps",
        "0.3 mm noise": "25 Hz, 0.3 mm noise", "1 % outliers": "25 Hz, 1 % outliers of 3 mm",
        "5 % dropouts": "25 Hz, 5 % dropouts", "irregular": "as sampled",
        "drifting": "as sampled",
    }  # fmt: skip
    drawn = [by[n].form.seed for n in list(by)[2:6]]
    assert len(set(drawn)) == 4  # the forms that draw, each its own draws
    for name in list(by)[1:6]:
        assert [c.label for c in by[name].cases] == [
            "breathing", "irregular breathing", "breathing 4.2 s + heartbeat", "sharkfin",
            "hysteresis",
        ]  # fmt: skip
    t = np.arange(0.0, 60.0, 0.05)
    for case in by["irregular"].cases:
        p = dict(case.parameters)
        assert case.label == f"irregular breathing, seed {p['seed']}, cv {p['amplitude_cv']}"
        assert p["amplitude_cv"] == p["period_cv"] and 0.2 <= float(p["period_cv"]) <= 0.3
        expected = make_motion("irregular_breathing", p).evaluate(t)[0]
        np.testing.assert_array_equal(case_reference(case).evaluate(t)[0], expected)
    seeds = [dict(c.parameters)["seed"] for c in by["irregular"].cases]
    assert len(set(seeds)) == 4 and "3" not in seeds  # other seeds than the forms' base


def _cycle_means(case, period_s, step_s=0.01):
    """X's mean over each whole period of the breathing, mm, from 0 s: its baseline."""
    from stewart_drake.studies.stream_study import case_reference

    x = np.asarray(case_reference(case).evaluate(np.arange(0.0, 120.0, step_s))[0])[:, 3]
    n = int(round(period_s / step_s))
    return 1e3 * x[: x.size // n * n].reshape(-1, n).mean(axis=1)


def test_the_drifting_motions_drift_as_their_labels_say():
    """The baseline (X's mean over each breath): 5 mm away by 60 s and held; 3 mm back and forth
    with a period of 40 s; -4 mm by 90 s under breathing of 3.2 s. Read from the motion."""
    cases = {c.label: c for c in next(s for s in sources(None) if s.name == "drifting").cases}
    assert list(cases) == [
        "breathing, 5 mm drift over 60 s",
        "breathing, 3 mm drift back and forth every 40 s",
        "breathing 3.2 s, -4 mm drift over 90 s",
    ]
    five = _cycle_means(cases["breathing, 5 mm drift over 60 s"], 4.0)  # 30 breaths of 4 s
    assert five[15] - five[0] == pytest.approx(5.0, abs=0.3)  # 60-64 s
    assert np.ptp(five[16:]) < 0.05  # held after
    assert five[7] - five[0] == pytest.approx(2.5, abs=0.4)  # half-way at 28-32 s
    back = _cycle_means(cases["breathing, 3 mm drift back and forth every 40 s"], 4.0)
    assert np.ptp(back) == pytest.approx(3.0, abs=0.3)
    np.testing.assert_allclose(back[10:20], back[:10], rtol=0, atol=0.05)  # 40 s later
    assert np.ptp(back[:5]) > 2.0  # back and forth within 40 s, not a slower drift
    four = _cycle_means(cases["breathing 3.2 s, -4 mm drift over 90 s"], 3.2)
    assert four[29] - four[0] == pytest.approx(-4.0, abs=0.3)  # 92.8-96 s
    assert np.ptp(four[30:]) < 0.05 and four[14] - four[0] == pytest.approx(-2.0, abs=0.4)


def test_the_motions_where_prediction_cannot_pay_are_named_and_seeded():
    """Three random walks of their own seeds at 25 Hz, each 120 s from home; breathing with
    10 % of its samples 10 mm off, drawn from a seed of its own."""
    from stewart_drake.robot.geometry import X_HOME

    walks, outliers = hurting()
    assert [c.label for c in walks.cases] == [f"random walk, seed {s}" for s in (1, 2, 3)]
    assert walks.form.words() == "25 Hz" and outliers.form.words() == (
        "25 Hz, 10 % outliers of 10 mm"
    )
    assert [c.label for c in outliers.cases] == ["breathing"] and outliers.form.seed != 0
    t = np.arange(0.0, 120.0, 0.5)
    made = [np.asarray(c.made_by().evaluate(t)[0]) for c in walks.cases]
    np.testing.assert_array_equal(made[0], np.asarray(random_walk(1).evaluate(t)[0]))
    assert np.abs(made[0] - made[1]).max() > 1e-3 and np.abs(made[1] - made[2]).max() > 1e-3
    walk = random_walk(4)
    assert walk.name == "random walk 4" and walk.end_time == pytest.approx(120.0, abs=1e-9)
    d = np.diff(np.asarray(walk.evaluate(np.arange(0.0, 120.0, 0.01))[0])[:, 3:], axis=0)
    assert np.all(np.abs(d.mean(axis=0)) < 5 * 1e-4 / np.sqrt(len(d)))  # no drift of its own
    assert np.abs(walk.evaluate(0.5)[0][3:] - np.asarray(X_HOME)[3:]).max() > 1e-5  # from 0 s
    np.testing.assert_array_equal(walk.evaluate(0.0)[0], np.asarray(X_HOME, dtype=float))
    assert random_walk(4, 30.0).end_time == pytest.approx(30.0, abs=1e-9)


def test_a_form_draws_the_same_samples_every_time_and_centred():
    """A form's draws are its seed's: the same form, the same samples (two runs equal to the
    bit, another seed not); noise and outliers are centred on the true sample (their mean
    within 5 standard errors of 0); an outlier share of 0.5 is allowed, 0.51 refused."""
    s = _stream()
    form = StreamForm(noise_m=3e-4, outlier_share=0.01, dropout_share=0.05, seed=5)
    first, again = form.apply(s).poses, form.apply(s).poses
    np.testing.assert_array_equal(first, again)
    assert np.abs(StreamForm(noise_m=3e-4, seed=6).apply(s).poses - first).max() > 1e-4
    noise = StreamForm(noise_m=3e-4, seed=1).apply(s).poses[:, 3:] - s.poses[:, 3:]
    assert np.all(np.abs(noise.mean(axis=0)) < 5 * 3e-4 / np.sqrt(len(noise)))
    off = StreamForm(outlier_share=0.05, outlier_m=3e-3, seed=2).apply(s).poses - s.poses
    hit = off[np.any(off != 0, axis=1), 3:]
    assert np.all(np.abs(hit.mean(axis=0)) < 5 * 3e-3 / np.sqrt(len(hit)))
    assert StreamForm(dropout_share=0.5).dropout_share == 0.5
    with pytest.raises(InvalidConfigError, match="dropout_share must be in"):
        StreamForm(dropout_share=0.51)


def test_a_dropout_repeats_the_sample_before_it_never_the_first():
    """Every sample lost holds the one before it as written (a moving stream, so the one after
    would differ); the first sample, having none before it, is kept: seeds are searched for
    draws that lose sample 0 and sample 1, read from the form's own generator."""
    s = _stream(200)
    for seed in range(200):
        lost = np.random.default_rng(seed).random(200) < 0.3  # the form's only draws
        if lost[0] and lost[1] and not lost[2]:
            break
    dropped = StreamForm(dropout_share=0.3, seed=seed).apply(s).poses
    np.testing.assert_array_equal(dropped[0], s.poses[0])  # nothing before it
    np.testing.assert_array_equal(dropped[1], s.poses[0])  # the one before, itself kept
    for i in np.flatnonzero(lost[1:]) + 1:
        np.testing.assert_array_equal(dropped[i], dropped[i - 1])
    np.testing.assert_array_equal(dropped[~lost], s.poses[~lost])


def test_the_forms_are_laid_on_the_motions_they_name():
    """Each form's base motion is the library's motion of that name and parameters (the
    heartbeat's breathing of 4.2 s, the irregular breathing of seed 3), and the breathing
    with 10 % outliers is the library's breathing."""
    from stewart_drake.studies.stream_study import case_reference

    t = np.arange(0.0, 30.0, 0.05)
    cases = {c.label: c for c in next(s for s in sources(None) if s.name == "10 Hz").cases}
    expected = {
        "breathing": make_motion("breathing", {}),
        "irregular breathing": make_motion("irregular_breathing", {"seed": "3"}),
        "breathing 4.2 s + heartbeat": make_motion("breathing_heartbeat", {"period": "4.2s"}),
        "sharkfin": make_motion("sharkfin", {}),
        "hysteresis": make_motion("hysteresis", {}),
    }
    assert list(cases) == list(expected)
    for label, motion in expected.items():
        got = case_reference(cases[label]).evaluate(t)[0]
        np.testing.assert_array_equal(got, motion.evaluate(t)[0], err_msg=label)
    (breathing,) = hurting()[1].cases
    np.testing.assert_array_equal(
        case_reference(breathing).evaluate(t)[0], make_motion("breathing", {}).evaluate(t)[0]
    )


def test_the_choice_at_the_peak_limit_and_by_the_mean():
    """A peak exactly at the limit (1.05) keeps a candidate; among those kept the least mean
    wins, whatever their peaks; peaks at 0.5 s do not count (only 0.2 s's are judged)."""
    rows = _rows({
        "edge": {"A": (0.30, 0.40, 1.05)},
        "calm": {"A": (0.50, 0.60, 1.00)},
    })  # fmt: skip
    assert sel.choose(rows) == "edge"
    late = _rows({"late": {"A": (0.20, 0.30, 1.00)}, "calm": {"A": (0.50, 0.60, 1.00)}})
    for r in late:
        if r["candidate"] == "late" and r["latency_s"] == 0.5:
            r["peak_ratio"] = 2.0
    assert sel.score(late, "late") == pytest.approx((0.25, 1.0)) and sel.choose(late) == "late"


def test_each_candidate_is_what_its_label_says():
    """Every candidate's settings are those its label names (history, record), with the
    guards every candidate carries; the three others are their predictor by name with the
    shipped record. A label that no longer says its settings (as when the shipped record
    changed under labels that did not name it) fails here."""
    import re

    from stewart_drake.references.prediction import PredictorSettings

    labels = [c.label for c in sel.CANDIDATES]
    assert len(set(labels)) == len(labels) == 11
    settings = {
        (c.settings.history_s, c.settings.min_record_s, c.predictor) for c in sel.CANDIDATES
    }
    assert len(settings) == 11  # no two alike
    for c in sel.CANDIDATES:
        assert c.settings.record_margin == 0.1 and c.settings.envelope_s == 120.0
        words = re.fullmatch(r"linear, ([\d.]+) s history, (\d) s record", c.label)
        if words:
            assert c.predictor == "linear"
            assert c.settings.history_s == float(words[1])
            assert c.settings.min_record_s == float(words[2])
        else:
            assert c.label == c.predictor and c.predictor in ("mulin", "wlms", "kalman")
            assert c.settings.min_record_s == PredictorSettings().min_record_s


def test_a_candidate_is_built_from_its_label_predictor_and_settings():
    """The candidates' builder: the regression unless another predictor is named, the settings
    given and the shipped ones otherwise."""
    from stewart_drake.references.prediction import PredictorSettings

    c = sel._c("two", history_s=2.0, record_margin=0.2)
    assert (c.label, c.predictor) == ("two", "linear")
    assert c.settings == PredictorSettings(history_s=2.0, record_margin=0.2)
    assert sel._c("k", "kalman") == sel.Candidate("k", "kalman", PredictorSettings())
