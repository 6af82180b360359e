"""An internal motion and its external surrogate measured on one clock, judged together
(``stewart-drake verify INTERNAL --surrogate EXTERNAL --measured ... --measured-surrogate ...``):
the shipped example pair (trace.txt's AP, surrogate.txt on SI: breaths of 3.6-4.4 s, the chest
0.2 s ahead) seen by one depth camera (its own clock, 26.5-36.5 ms steps, 0.2 mm of noise, an
offset of its own per platform), both platforms 5.45 s after the camera started. The relative
latency is held to the delays the files were made with; the battery of wrong inputs (the
surrogate at rest, reversed, 0.3 s late; the internal 0.3 s late; the files swapped; another
motion) FAILs each naming its cause, and the right pair PASSes."""

import json

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.organ_motion.examples import FOLDER
from stewart_drake.references.traces import load_trace
from stewart_drake.verification.measured_motion import read_measured
from stewart_drake.verification.measured_verdict import seconds
from stewart_drake.verification.pair_judgement import (
    MAX_RELATIVE_LATENCY_S,
    RELATIVE_SEARCH_S,
    verify_pair,
)

TRACE, SURROGATE = FOLDER / "trace.txt", FOLDER / "surrogate.txt"
#: When both platforms started on the camera's clock, s; the camera's offsets and noise, mm.
DELAY_S, OFFSETS_MM, NOISE_MM = 5.45, (412.3, 388.7), 0.2
TOLERANCE = (1e-3, np.radians(1.0))


def camera_clock(seed=0, seconds=125.0):
    """(n,) s: a depth camera's times from 0, steps of 26.5-36.5 ms."""
    steps = np.random.default_rng(seed).uniform(0.0265, 0.0365, int(seconds / 0.0315))
    t = np.concatenate([[0.0], np.cumsum(steps)])
    return t[t < seconds]


def seen(column_of, path, t_cam, delay_s, sign=1.0, offset_mm=0.0, seed=1):
    """(n,) mm: the camera's depth of a platform that followed ``path``'s column (a cubic
    spline through its samples, held before and after) ``delay_s`` late, with its noise."""
    data = np.loadtxt(path)
    spline = CubicSpline(data[:, 0], data[:, column_of])
    u = np.clip(t_cam - delay_s, data[0, 0], data[-1, 0])
    noise = np.random.default_rng(seed).normal(0.0, NOISE_MM, len(t_cam))
    return offset_mm + sign * spline(u) + noise


def write_depth(path, t, depth):
    """A camera's file, ``t [s],depth [mm]``."""
    rows = ["t [s],depth [mm]"] + [f"{a:.5f},{b:.4f}" for a, b in zip(t, depth)]
    path.write_text("\n".join(rows) + "\n")
    return path


def pair_files(tmp_path, internal=None, surrogate=None):
    """(internal's file, surrogate's file): the camera's two depths, each the right one unless
    given (n,) mm."""
    t = camera_clock()
    if internal is None:
        internal = seen(3, TRACE, t, DELAY_S, offset_mm=OFFSETS_MM[0], seed=1)
    if surrogate is None:
        surrogate = seen(1, SURROGATE, t, DELAY_S, offset_mm=OFFSETS_MM[1], seed=2)
    return (
        write_depth(tmp_path / "depth_internal.csv", t, internal),
        write_depth(tmp_path / "depth_surrogate.csv", t, surrogate),
    )


def judge(internal_file, surrogate_file, **options):
    """verify_pair of the example pair on the two files (the internal's depth on AP, the
    surrogate's on SI)."""
    return verify_pair(
        load_trace(TRACE),
        load_trace(SURROGATE),
        read_measured(internal_file, axis_map={"depth": "AP"}),
        read_measured(surrogate_file, axis_map={"depth": "SI"}),
        tolerance=TOLERANCE,
        **options,
    )


@pytest.mark.parametrize("lag_s", [0.0, 0.06, -0.08])
def test_the_relative_latency_is_the_delay_between_the_two_platforms(tmp_path, lag_s):
    t = camera_clock()
    internal = seen(3, TRACE, t, DELAY_S + lag_s, offset_mm=OFFSETS_MM[0], seed=1)
    pair = judge(*pair_files(tmp_path, internal=internal))
    # Made with the internal lag_s later than the surrogate: tau_rel = lag_s.
    assert pair.relative_latency_s == pytest.approx(lag_s, abs=0.005)
    assert -pair.internal_shift_s == pytest.approx(DELAY_S + lag_s, abs=0.005)
    assert -pair.surrogate_shift_s == pytest.approx(DELAY_S, abs=0.005)
    assert pair.judgement.passed and pair.passed, pair.judgement.line
    assert pair.judgement.line.startswith("PASS: depth_internal.csv (internal) against")
    # Each fidelity is the camera's noise, as verify alone gives it.
    for ver in (pair.internal, pair.surrogate):
        rms = np.nanmax(ver.fidelity["rms"])
        assert 0.8 * NOISE_MM < rms * 1e3 < 1.2 * NOISE_MM
    assert pair.internal.fidelity["measured"] == ["Z"]
    assert pair.surrogate.fidelity["measured"] == ["X"]


def test_the_relative_latency_holds_whatever_the_internal_s_clock_search_took(tmp_path):
    """The internal's clock given 50 ms off and its own search held to +-10 ms: its clock takes
    only part of its delay, the rest stays as its lag along its direction, and the pair's
    relative latency and the internal's shift on the one clock are the same as unbounded."""
    t = camera_clock()
    internal = seen(3, TRACE, t, DELAY_S + 0.06, offset_mm=OFFSETS_MM[0], seed=1)
    files = pair_files(tmp_path, internal=internal)
    bounded = judge(*files, clock_offset_s=-5.40, max_latency_s=0.01)
    left = bounded.internal.shift_s + DELAY_S + 0.06  # what the internal's clock did not take
    assert 0.02 < left < 0.07
    assert bounded.relative_latency_s == pytest.approx(0.06, abs=0.005)
    assert -bounded.internal_shift_s == pytest.approx(DELAY_S + 0.06, abs=0.005)
    assert bounded.judgement.passed


@pytest.mark.parametrize("lag_s", [0.7, -0.9])
def test_a_relative_latency_beyond_the_pair_s_usual_search_is_found_and_fails(tmp_path, lag_s):
    # Beyond the +-0.5 s every pair's relative latency searches first: searched again wider,
    # found to within 5 ms, and beyond the 0.1 s bound, named so.
    t = camera_clock()
    internal = seen(3, TRACE, t, DELAY_S + lag_s, offset_mm=OFFSETS_MM[0], seed=1)
    pair = judge(*pair_files(tmp_path, internal=internal))
    assert pair.relative_latency_s == pytest.approx(lag_s, abs=0.005)
    assert not pair.judgement.at_edge and pair.judgement.meaningful, pair.judgement.line
    assert not pair.judgement.passed
    assert f"beyond --max-relative-latency {seconds(MAX_RELATIVE_LATENCY_S)}" in pair.judgement.line


def test_the_clock_offset_cancels(tmp_path):
    """Given or not, the clocks' offset leaves the relative latency alone; given, each motion's
    own latency is judged as verify judges it."""
    files = pair_files(tmp_path)
    unknown = judge(*files)
    known = judge(*files, clock_offset_s=-DELAY_S)
    assert known.relative_latency_s == pytest.approx(unknown.relative_latency_s, abs=1e-3)
    assert known.internal.latency_s == pytest.approx(0.0, abs=0.005)
    assert known.surrogate.latency_s == pytest.approx(0.0, abs=0.005)
    assert known.internal.judgement.latency_judged and known.passed


def causes(pair) -> str:
    return "; ".join(pair.judgement.causes)


def test_a_surrogate_at_rest_fails(tmp_path):
    t = camera_clock()
    still = OFFSETS_MM[1] + np.random.default_rng(4).normal(0.0, NOISE_MM, len(t))
    pair = judge(*pair_files(tmp_path, surrogate=still))
    assert not pair.judgement.passed and not pair.judgement.meaningful
    # Its camera's 0.2 mm of noise is more than a tenth of its reference's motion: "did not
    # move" is judged against that motion, not the tolerance, and the noise is named instead.
    assert "the surrogate does not follow its reference on X" in causes(pair), causes(pair)
    assert "or noise" in causes(pair)
    assert "of no meaning" in pair.judgement.line
    assert not pair.surrogate.judgement.passed and not pair.passed


def test_an_internal_platform_at_rest_fails_naming_it_alone(tmp_path):
    t = camera_clock()
    still = OFFSETS_MM[0] + np.random.default_rng(4).normal(0.0, NOISE_MM, len(t))
    pair = judge(*pair_files(tmp_path, internal=still))
    assert not pair.judgement.passed and not pair.judgement.meaningful
    # The surrogate, judged on its own clock since the internal's means nothing, follows. The
    # camera's 0.2 mm of noise is more than a tenth of the internal's motion: named as noise.
    assert causes(pair).startswith("the internal target does not follow its reference"), causes(
        pair
    )
    assert "the surrogate" not in causes(pair)
    assert pair.surrogate.judgement.passed and not pair.internal.judgement.passed


def test_a_reversed_surrogate_fails(tmp_path):
    t = camera_clock()
    flipped = seen(1, SURROGATE, t, DELAY_S, sign=-1.0, offset_mm=OFFSETS_MM[1], seed=2)
    pair = judge(*pair_files(tmp_path, surrogate=flipped))
    assert not pair.judgement.passed
    assert "the surrogate runs the wrong way on X" in causes(pair)


@pytest.mark.parametrize(
    "late, expected, words",
    [
        ("surrogate", -0.3, "the surrogate late against the internal target"),
        ("internal", +0.3, "the internal target late against the surrogate"),
    ],
)
def test_a_platform_late_by_0_3_s_fails_naming_which(tmp_path, late, expected, words):
    t = camera_clock()
    if late == "surrogate":
        files = pair_files(
            tmp_path, surrogate=seen(1, SURROGATE, t, DELAY_S + 0.3, offset_mm=OFFSETS_MM[1])
        )
    else:
        files = pair_files(
            tmp_path, internal=seen(3, TRACE, t, DELAY_S + 0.3, offset_mm=OFFSETS_MM[0])
        )
    pair = judge(*files)
    assert pair.relative_latency_s == pytest.approx(expected, abs=0.005)
    assert not pair.judgement.passed and pair.judgement.meaningful
    assert f"beyond --max-relative-latency 100 ms: {words}" in causes(pair)
    # Each motion alone follows its reference: verify alone, clocks unknown, passes both.
    assert pair.internal.judgement.passed and pair.surrogate.judgement.passed
    # Within a wider bound it passes.
    assert judge(*files, max_relative_latency_s=0.35).judgement.passed


def test_a_relative_latency_beyond_the_search_is_at_least_its_edge(tmp_path):
    t = camera_clock()
    late = seen(1, SURROGATE, t, DELAY_S + 2.5, offset_mm=OFFSETS_MM[1])
    pair = judge(*pair_files(tmp_path, surrogate=late))
    # 2.5 s is more than half a breath: only "at least" the edge is known, and a breath earlier
    # may be nearer than the true one (the edge's sign is not asserted).
    assert not pair.judgement.passed and pair.judgement.at_edge
    assert RELATIVE_SEARCH_S - 0.05 <= abs(pair.relative_latency_s) <= RELATIVE_SEARCH_S
    assert "relative latency at least" in causes(pair)
    assert "(at the edge of the relative latencies searched)" in causes(pair)
    # On its own the surrogate finds its own clock, 2.5 s later than the internal's.
    assert -pair.surrogate.shift_s == pytest.approx(DELAY_S + 2.5, abs=0.005)
    # Its own match is at least 1 s (2.5 less the 1.5 searched) earlier on the reference's clock
    # than the pair's: the note says so, and says the search.
    apart = pair.surrogate.shift_s - pair.surrogate_shift_s
    assert apart <= -(2.5 - RELATIVE_SEARCH_S) + 0.01
    assert pair.notes == [
        f"on its own, depth_surrogate.csv matches its reference best {seconds(-apart)} earlier "
        "than on the internal's clock: its fidelity is that of its own best match, the relative "
        "latency that of the pair's (searched within +-1.5 s of the internal's)"
    ]


@pytest.mark.parametrize("early_s", [2.5, 1.7])
def test_a_surrogate_whose_own_match_is_later_is_said_so(tmp_path, early_s):
    t = camera_clock()
    early = seen(1, SURROGATE, t, DELAY_S - early_s, offset_mm=OFFSETS_MM[1])
    pair = judge(*pair_files(tmp_path, surrogate=early))
    apart = pair.surrogate.shift_s - pair.surrogate_shift_s
    assert apart >= (early_s - RELATIVE_SEARCH_S) - 0.01
    assert pair.notes == [
        f"on its own, depth_surrogate.csv matches its reference best {seconds(apart)} later "
        "than on the internal's clock: its fidelity is that of its own best match, the relative "
        "latency that of the pair's (searched within +-1.5 s of the internal's)"
    ]


def test_swapped_files_fail_as_swapped(tmp_path):
    internal, surrogate = pair_files(tmp_path)
    pair = judge(surrogate, internal)
    assert not pair.judgement.passed
    assert causes(pair).startswith("the two measurements swapped: depth_surrogate.csv comes")
    # The right files are not taken for swapped.
    assert judge(internal, surrogate).judgement.causes == []


def test_another_motion_on_the_surrogate_fails(tmp_path):
    t = camera_clock()
    other = (
        OFFSETS_MM[1]
        + 2.0 * np.sin(2 * np.pi * t / 5.3)
        + np.random.default_rng(6).normal(0.0, NOISE_MM, len(t))
    )
    pair = judge(*pair_files(tmp_path, surrogate=other))
    assert not pair.judgement.passed and not pair.judgement.meaningful
    text = causes(pair)
    assert "the surrogate does not follow its reference on X" in text or (
        "the surrogate repeats every" in text
    ), text


def test_two_measurements_that_do_not_overlap_are_refused(tmp_path):
    internal, _ = pair_files(tmp_path)
    t = camera_clock() + 1000.0
    later = write_depth(tmp_path / "later.csv", t, seen(1, SURROGATE, t - 1000.0, DELAY_S))
    with pytest.raises(InvalidConfigError, match="they do not overlap, so they are not on one"):
        judge(internal, later)
    with pytest.raises(InvalidConfigError, match="must be a positive number"):
        judge(*pair_files(tmp_path), max_relative_latency_s=0.0)


def run(tmp_path, internal, surrogate, *options):
    """``verify trace.txt --surrogate surrogate.txt`` in process: (exit code, the pair's JSON)."""
    out = tmp_path / "out"
    argv = ["verify", str(TRACE), "--surrogate", str(SURROGATE), "--measured", str(internal)]
    argv += ["--measured-map", "depth=AP", "--measured-surrogate", str(surrogate)]
    argv += ["--measured-surrogate-map", "depth=SI", "--tolerance", "1mm,1deg"]
    code = main(argv + ["--out", str(out), *options])
    found = sorted(out.glob("verify_*_pair.json"))
    return code, (json.loads(found[0].read_text()) if found else None)


def test_the_command_reports_both_fidelities_and_the_relative_latency(tmp_path, capsys):
    t = camera_clock()
    internal, surrogate = pair_files(
        tmp_path, internal=seen(3, TRACE, t, DELAY_S + 0.05, offset_mm=OFFSETS_MM[0], seed=1)
    )
    code, figures = run(tmp_path, internal, surrogate)
    out = capsys.readouterr().out.splitlines()
    assert code == 0, out
    assert out[0].startswith("PASS: depth_internal.csv (Z; each axis's offset removed) against")
    assert out[1].startswith("PASS: depth_surrogate.csv (X; each axis's offset removed) against")
    assert out[2].startswith("PASS: depth_internal.csv (internal) against depth_surrogate.csv")
    assert figures["relative_latency_s"] == pytest.approx(0.05, abs=0.005)
    assert figures["relative"]["max_relative_latency_s"] == MAX_RELATIVE_LATENCY_S
    assert figures["definition"].startswith("relative latency = the internal target's latency")
    assert {p.name for p in (tmp_path / "out").iterdir()} == {
        f"verify_{stem}.{suffix}"
        for stem in ("trace_depth_internal", "surrogate_depth_surrogate")
        for suffix in ("md", "png", "json")
    } | {"verify_trace_pair.md", "verify_trace_pair.json"}


def test_the_command_fails_a_relative_latency_beyond_its_bound(tmp_path):
    """A 50 ms lag fails a bound of 30 ms: exit 2, the cause in the line."""
    t = camera_clock()
    internal, surrogate = pair_files(
        tmp_path, internal=seen(3, TRACE, t, DELAY_S + 0.05, offset_mm=OFFSETS_MM[0], seed=1)
    )
    code, figures = run(tmp_path, internal, surrogate, "--max-relative-latency", "0.03")
    assert code == 2 and figures["relative"]["passed"] is False
    assert "beyond --max-relative-latency 30 ms" in figures["relative"]["line"]


def test_the_pair_s_exit_status_is_the_worst_of_its_three_verdicts(tmp_path, capsys):
    """At 50 mm neither motion can be judged (CANNOT JUDGE) while their timing passes: exit 3, as
    ``verify`` of either motion alone; with the timing failing too, exit 2 (FAIL before CANNOT
    JUDGE). Was: exit 0 beside a PASS line."""
    t = camera_clock()
    internal, surrogate = pair_files(
        tmp_path, internal=seen(3, TRACE, t, DELAY_S + 0.05, offset_mm=OFFSETS_MM[0], seed=1)
    )
    code, figures = run(tmp_path, internal, surrogate, "--tolerance", "50mm,10deg")
    assert figures["internal"]["verdict"] == figures["surrogate"]["verdict"] == "CANNOT JUDGE"
    assert figures["relative"]["passed"] is True and figures["verdict"] == "CANNOT JUDGE"
    assert code == 3, capsys.readouterr().out
    code, figures = run(
        tmp_path, internal, surrogate, "--tolerance", "50mm,10deg", "--max-relative-latency", "0.03"
    )
    assert figures["relative"]["passed"] is False and figures["internal"]["verdict"] != "FAIL"
    assert code == 2 and figures["verdict"] == "FAIL"


@pytest.mark.parametrize(
    "option, words",
    [
        (["--record"], "--record records one motion's verdict, and a pair has three"),
        (["--operator", "A"], "--operator records one motion's verdict, and a pair has three"),
        (["--action-level", "0.5mm,0.5deg"], "--action-level grades one motion's verdict, and a"),
    ],
)
def test_a_pair_refuses_the_records_options_before_any_work(tmp_path, capsys, option, words):
    """A record is of one motion's verdict, as is an action level; a pair has three: --record,
    the options it takes and --action-level are refused in one line, nothing written. Was: no
    record, and not a word."""
    code, figures = run(tmp_path, *pair_files(tmp_path), *option)
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and figures is None and not (tmp_path / "out").exists()
    assert words in err, err


@pytest.mark.parametrize(
    "options, words",
    [
        (["--measured-surrogate", "X.csv"], "--measured-surrogate judges the motion with its "),
        (["--surrogate", "S.txt"], "--surrogate judges the motion with its surrogate: give"),
        (["--max-relative-latency", "0"], "argument --max-relative-latency: must be > 0, got 0"),
    ],
)
def test_options_refused_in_one_line(tmp_path, capsys, options, words):
    internal, _ = pair_files(tmp_path)
    try:
        code = main(["verify", str(TRACE), "--measured", str(internal), *options])
    except SystemExit as stop:  # argparse's own refusal of a value
        code = stop.code
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and words in err, err


def test_a_right_pair_smaller_than_the_tolerance_passes_and_a_still_surrogate_fails(tmp_path):
    """At 50 mm neither motion can be told from rest by its fidelity (CANNOT JUDGE, said),
    yet the pair's timing is judged: the right pair PASSes; a surrogate at rest moved less than
    a tenth of its reference's motion, and "did not move" is said of it alone."""
    wide = (50e-3, np.radians(10.0))

    def judged(files):
        return verify_pair(
            load_trace(TRACE),
            load_trace(SURROGATE),
            read_measured(files[0], axis_map={"depth": "AP"}),
            read_measured(files[1], axis_map={"depth": "SI"}),
            tolerance=wide,
        )

    right = judged(pair_files(tmp_path))
    assert right.passed, right.judgement.line
    assert right.verdicts == ("CANNOT JUDGE", "CANNOT JUDGE", "PASS")
    assert right.surrogate.judgement.verdict == "CANNOT JUDGE"
    assert right.internal.judgement.verdict == "CANNOT JUDGE"
    t = camera_clock()
    still = OFFSETS_MM[1] + np.random.default_rng(4).normal(0.0, 0.01, len(t))  # a fine sensor
    wrong = judged(pair_files(tmp_path, surrogate=still))
    assert not wrong.passed
    assert "the surrogate did not move" in causes(wrong)
    assert "the internal target" not in causes(wrong)


@pytest.mark.parametrize("bound_s", [0.1, 1.0])
def test_swapped_files_fail_at_any_bound_and_the_right_pair_passes(tmp_path, bound_s):
    """The swap is looked for on every verdict: at a bound wide enough to hold the swapped
    pair's relative latency (-0.9 s) it still FAILs as swapped."""
    internal, surrogate = pair_files(tmp_path)
    swapped = judge(surrogate, internal, max_relative_latency_s=bound_s)
    assert not swapped.passed
    assert causes(swapped).startswith("the two measurements swapped")
    right = judge(internal, surrogate, max_relative_latency_s=bound_s)
    assert right.passed and right.judgement.causes == [], right.judgement.line


@pytest.mark.parametrize("bound_s", [0.6, 2.0])
@pytest.mark.parametrize("played", ["surrogate", "internal"])
def test_a_platform_that_played_the_others_trace_fails_at_any_bound(tmp_path, played, bound_s):
    """The surrogate platform given the internal trace (or the internal platform the
    surrogate's), the other right: the pair's relative latency, -450 ms, lies within a 0.6 s
    bound and each motion follows its reference well enough to give a clock, so only the match
    to the references tells it. The played measurement comes about 1.9 times nearer the other's
    reference (mean squared distances), the right one about 1.8 times nearer its own: FAIL,
    naming the platform, at either bound; the right pair at the same bounds PASSes above."""
    t = camera_clock()
    if played == "surrogate":
        files = pair_files(tmp_path, surrogate=seen(3, TRACE, t, DELAY_S, offset_mm=OFFSETS_MM[1]))
    else:
        files = pair_files(tmp_path, internal=seen(1, SURROGATE, t, DELAY_S, offset_mm=412.3))
    pair = judge(*files, max_relative_latency_s=bound_s)
    assert abs(pair.relative_latency_s) == pytest.approx(0.45, abs=0.01)
    assert not pair.passed and not pair.judgement.passed
    other = "internal" if played == "surrogate" else "surrogate"
    words = causes(pair)
    assert words.startswith(f"the {played} platform played the {other}'s trace: "), words
    ratio = float(words.split(" comes ")[1].split(" times")[0])
    own = float(words.split(" comes ")[2].split(" times")[0])
    assert 1.6 < ratio < 2.2 and 1.6 < own < 2.2, words
    right = judge(*pair_files(tmp_path), max_relative_latency_s=bound_s)
    assert right.passed and right.judgement.causes == [], right.judgement.line


@pytest.mark.parametrize("as_written, passes", [(True, True), (False, False)])
def test_a_surrogate_file_that_starts_later_is_taken_on_its_clock(tmp_path, as_written, passes):
    """The surrogate's file cut to start 0.4 s into the motion's clock, its times as written,
    is the same pair: PASS, relative latency 0 (it was re-zeroed onto the motion's start, and
    read -394 ms). The same samples written from 0 are a surrogate 0.4 s early: FAIL."""
    rows = [line.split() for line in SURROGATE.read_text().splitlines() if line.strip()]
    late = [(float(a), b) for a, b in rows if float(a) >= 0.4 - 1e-9]
    start = late[0][0] if not as_written else 0.0
    cut = tmp_path / "surrogate_late.txt"
    cut.write_text("\n".join(f"{a - start:.1f} {b}" for a, b in late) + "\n")
    internal, surrogate = pair_files(tmp_path)
    out = tmp_path / "out"
    argv = ["verify", str(TRACE), "--surrogate", str(cut), "--measured", str(internal)]
    argv += ["--measured-map", "depth=AP", "--measured-surrogate", str(surrogate)]
    argv += ["--measured-surrogate-map", "depth=SI", "--tolerance", "1mm,1deg"]
    code = main(argv + ["--out", str(out)])
    figures = json.loads(next(out.glob("verify_*_pair.json")).read_text())
    if passes:
        assert code == 0, figures["relative"]["line"]
        assert figures["relative_latency_s"] == pytest.approx(0.0, abs=0.005)
    else:
        assert code == 2
        assert abs(figures["relative_latency_s"]) == pytest.approx(0.4, abs=0.01)


def test_a_surrogate_file_of_another_session_is_refused_as_not_overlapping(tmp_path, capsys):
    """The surrogate's samples written 1000 s later than the motion's file: they do not
    overlap, which is said in one line before any work (was: NaN and a made-up lead)."""
    rows = [line.split() for line in SURROGATE.read_text().splitlines() if line.strip()]
    later = tmp_path / "surrogate_later.txt"
    later.write_text("\n".join(f"{float(a) + 1000.0:.1f} {b}" for a, b in rows) + "\n")
    internal, surrogate = pair_files(tmp_path)
    out = tmp_path / "out"
    argv = ["verify", str(TRACE), "--surrogate", str(later), "--measured", str(internal)]
    argv += ["--measured-map", "depth=AP", "--measured-surrogate", str(surrogate)]
    argv += ["--measured-surrogate-map", "depth=SI", "--tolerance", "1mm,1deg"]
    code = main(argv + ["--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and "do not overlap: they were not recorded together" in err, err
    assert "t = 1000-" in err and not list(out.glob("verify_*_pair.json"))
