"""``verify`` itself (:mod:`~stewart_drake.verification.verify`) on synthetic motions of
known clock, delay, offsets and frames, 20 s at 50 Hz: the latency, the shift, the offsets
removed and the window against the values the motion was made with, the registered frames
against the emulated tracker's truth; and each step's rules (the shifts searched, the window of
whole cycles, the samples' gaps, the axes not measured, the words of what was removed) against
numbers written out here. Unit tests of a fraction of a second each: tools/mutation.py runs them
to mutate the module."""

import math

import numpy as np
import pytest
from harmonic_motion import Harmonics, along

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.calibration.tracker import emulated_setup
from stewart_drake.organ_motion.fidelity import AXES, time_lag
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.verification import measured_span as span
from stewart_drake.verification import verify as vn
from stewart_drake.verification.alignment import Frames
from stewart_drake.verification.measured_motion import MeasuredMotion
from stewart_drake.verification.verdict_notes import uncompared_words
from stewart_drake.verification.verify import verify

#: A breath along X with a tilt about Y, every 4 s, about a pose 0.3 m up.
MOTION = Harmonics(
    np.array(along("X", 5e-3, 1.5e-3)) + along("theta", 0.02, -0.005),
    phase=(0.0, 0.8),
    centre=(0.0, 0.0, 0.0, 0.01, -0.02, 0.3),
)
#: The tracker's clock at its first sample, s, and where the motion was then on its own.
CLOCK_START_S, REFERENCE_START_S = 100.0, 2.0
CLOCK_OFFSET_S = REFERENCE_START_S - CLOCK_START_S
LATENCY_S = 0.06
TOLERANCE = (1e-4, math.radians(0.1))
XYZ = np.array([False] * 3 + [True] * 3)
SETUP = emulated_setup(StewartGeometry())


def run(seconds=20.0, rate_hz=50.0, latency_s=LATENCY_S, reference=MOTION):
    """(t (n,) s on the tracker's clock, (n, 6) the platform's poses in B): the phantom following
    the reference ``latency_s`` late."""
    t = CLOCK_START_S + np.arange(int(round(seconds * rate_hz))) / rate_hz
    return t, reference.evaluate(t + CLOCK_OFFSET_S - latency_s)[0]


def positions(x, offsets=(0.4, -1.2, 0.9)):
    """A marker of positions only at the platform's origin, seen by a tracker whose axes are
    the base's (its origin at -offsets)."""
    y = np.array(x, dtype=float)
    y[:, 3:] += offsets
    y[:, :3] = np.nan
    return y


# -- verify ----------------------------------------------------------------------------------------


def test_the_base_axes_with_the_clocks_known():
    t, x = run()
    ver = verify(
        MOTION,
        MeasuredMotion("/d/m.csv", "tracker", t, positions(x), XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        tolerance=TOLERANCE,
    )
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-5)
    assert ver.shift_s == pytest.approx(CLOCK_OFFSET_S - LATENCY_S, abs=1e-5)
    assert ver.clock_offset_s == CLOCK_OFFSET_S and ver.clock == "given (--clock-offset)"
    assert ver.searched_s == pytest.approx((CLOCK_OFFSET_S - 1.5, CLOCK_OFFSET_S + 1.5))
    assert ver.max_latency_s == 0.5 and ver.name == "harmonics" and ver.reference is MOTION
    assert ver.frame.how == "axes"
    np.testing.assert_allclose(ver.offsets, [0, 0, 0, 0.4, -1.2, 0.9], atol=1e-9)
    assert list(ver.offsets[:3]) == [0.0, 0.0, 0.0]
    # On the reference's clock: the motion's time 1.94 s at the first sample.
    r = ver.result
    np.testing.assert_allclose(r.t, t + CLOCK_OFFSET_S - LATENCY_S, atol=1e-5)
    np.testing.assert_allclose(r.x[:, 3:], x[:, 3:], atol=1e-8)
    assert np.all(np.isnan(r.x[:, :3]))
    np.testing.assert_allclose(r.x_d, MOTION.evaluate(r.t)[0], atol=0)
    # The window: the whole cycles after the motion's first, which the recording holds.
    np.testing.assert_allclose(ver.cycle_starts, [4.0, 8.0, 12.0, 16.0, 20.0])
    assert ver.fidelity["window_s"] == pytest.approx((4.0, 20.0))
    assert ver.startup["window_s"] == pytest.approx((r.t[0], 4.0))
    assert math.isnan(ver.startup["rms_rotation_rad"])
    assert ver.startup["rms_translation_m"] < 1e-8
    fid = ver.fidelity
    assert fid["measured"] == ["X", "Y", "Z"] and math.isnan(fid["rms_rotation_rad"])
    assert fid["rms_translation_m"] < 1e-8
    # The figures know the motion's cycles and its fundamental: X's harmonics are its sines.
    np.testing.assert_allclose(fid["cycles"]["starts"], [4.0, 8.0, 12.0, 16.0])  # each cycle's
    harmonics = {(h["axis"], h["k"]): h["reference"] for h in fid["harmonics"]}
    assert harmonics[("X", 1)] == pytest.approx(5e-3, rel=1e-3)
    assert harmonics[("X", 2)] == pytest.approx(1.5e-3, rel=1e-3)
    assert ("theta", 1) not in harmonics  # not measured
    assert ver.judgement.passed, ver.judgement.line
    assert ver.learning == "measured by the tracker, m.csv" and ver.resolution() == (0.0, 0.0)
    clock, frames, outside = ver.removed
    assert clock.startswith("the clock: the measured motion shifted by -98.06 s onto")
    assert "the clock offset -98 s (given (--clock-offset)) less the latency, 60 ms" in clock
    assert frames.startswith("the frames: each measured axis") and "X +400 mm, Y -1200 mm" in frames
    assert outside == (
        "what the figures leave out: the figures are over whole cycles, t = 4-20 s: 2.06 s "
        "before (the motion's first cycle, the start-up) and 1.92 s after are outside them"
    )


def test_the_offsets_removed_are_the_means_over_the_window_and_the_start_up_its_own():
    # The tracker's X drifts 2 um/s and the phantom ran 0.5 mm off during its first breath:
    # the offset removed is the mean over the whole cycles, the start-up's error its own.
    t, x = run()
    y = positions(x)
    drift = 2e-6 * (t - t[0])
    y[:, 3] += drift
    first = t + CLOCK_OFFSET_S - LATENCY_S < 4.0
    y[first, 4] += 5e-4
    ver = verify(
        MOTION, MeasuredMotion("m.csv", "tracker", t, y, XYZ), clock_offset_s=CLOCK_OFFSET_S
    )
    w0, w1 = ver.fidelity["window_s"]
    inside = (ver.result.t >= w0 - 1e-9) & (ver.result.t <= w1 + 1e-9)
    assert ver.offsets[3] == pytest.approx(0.4 + np.mean(drift[inside]), abs=1e-9)
    assert ver.offsets[4] == pytest.approx(-1.2, abs=1e-9)
    assert ver.startup["rms_translation_m"] == pytest.approx(
        np.sqrt(np.mean((drift[first] - np.mean(drift[inside])) ** 2 + 5e-4**2)), rel=1e-3
    )


def test_a_recording_that_starts_after_the_first_breath_has_no_start_up():
    # The tracker started 5 s later in the motion: at its 7 s.
    t = CLOCK_START_S + np.arange(1000) / 50.0
    x = MOTION.evaluate(t + CLOCK_OFFSET_S + 5.0 - LATENCY_S)[0]
    measured = MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ)
    ver = verify(MOTION, measured, CLOCK_OFFSET_S + 5.0)
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-5)
    assert ver.fidelity["window_s"] == pytest.approx((8.0, 24.0))
    assert ver.startup["window_s"] == pytest.approx((6.94, 6.94), abs=1e-5)
    assert ver.startup["rms_translation_m"] == 0.0
    assert "part of a cycle" in ver.removed[-1]


def test_a_single_axis_sensor_keeps_its_translation_figures():
    t, x = run()
    y = np.full_like(x, np.nan)
    y[:, 3] = x[:, 3] + 0.02
    only_x = np.array([False] * 3 + [True, False, False])
    ver = verify(MOTION, MeasuredMotion("d.csv", "tracker", t, y, only_x), CLOCK_OFFSET_S)
    assert ver.fidelity["measured"] == ["X"]
    assert ver.fidelity["rms_translation_m"] < 1e-8 and ver.offsets[3] == pytest.approx(0.02)
    assert math.isnan(ver.fidelity["rms"][4]) and math.isnan(ver.fidelity["rms_rotation_rad"])
    assert ver.startup["rms_translation_m"] < 1e-8  # over X, the start-up


def test_without_the_clocks_the_whole_shift_is_the_latency_not_judged():
    t, x = run(latency_s=0.9)
    ver = verify(MOTION, MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ))
    assert ver.clock == "not known" and ver.clock_offset_s == 0.0
    assert ver.latency_s == pytest.approx(-ver.shift_s)
    # Found modulo the 4 s period, anywhere in the shifts searched.
    off = (ver.shift_s - (CLOCK_OFFSET_S - 0.9)) % 4.0
    assert min(off, 4.0 - off) == pytest.approx(0.0, abs=1e-5)  # either side of a period
    # The recording's start from a tenth of its 19.98 s before the motion's start (the whole
    # recording compared, a tenth of it at most left out) to a period after.
    assert ver.searched_s == pytest.approx((-CLOCK_START_S - 1.998, -CLOCK_START_S + 4.0))
    assert ver.judgement.passed and not ver.judgement.latency_judged
    assert "The clocks' relation was not given" in ver.removed[0]


def test_a_latency_beyond_the_bound_is_found_and_fails():
    t, x = run(latency_s=0.9)
    ver = verify(
        MOTION,
        MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        max_latency_s=0.5,
    )
    assert ver.latency_s == pytest.approx(0.9, abs=1e-5)
    assert not ver.judgement.passed
    assert ver.judgement.causes == ["latency 900 ms beyond --max-latency 500 ms"]
    # A smaller bound searches less, 0.3 s either way of the offset: the latency is found at
    # its edge (to a step of the search), and said to be at least that.
    ver = verify(
        MOTION,
        MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        max_latency_s=0.1,
    )
    assert ver.searched_s == pytest.approx((CLOCK_OFFSET_S - 0.3, CLOCK_OFFSET_S + 0.3))
    assert ver.max_latency_s == 0.1 and 0.3 <= ver.latency_s <= 0.32
    assert ver.judgement.causes[-1].startswith("latency at least 3")
    assert "(at the edge of the shifts searched)" in ver.judgement.causes[-1]


def test_the_base_frame_keeps_a_constant_error_and_judges_it():
    t, x = run()
    y = x.copy()
    y[:, 4] += 3e-4
    ver = verify(
        MOTION,
        MeasuredMotion("m.csv", "tracker", t, y, np.ones(6, bool)),
        clock_offset_s=CLOCK_OFFSET_S,
        frame="base",
        tolerance=TOLERANCE,
    )
    assert ver.frame.how == "base" and list(ver.offsets) == [0.0] * 6
    assert ver.fidelity["rms"][4] == pytest.approx(3e-4, rel=1e-5)
    assert ver.fidelity["rms_rotation_rad"] < 1e-9
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-5)
    assert not ver.judgement.passed
    assert ver.judgement.causes[0].startswith("a constant offset of Y +0.3 mm")
    assert "the frames: none: the file gives the platform's poses" in ver.removed[1]


def test_a_registered_tracker_of_positions_only_is_judged_in_the_base_frame():
    t, x = run()
    y = SETUP.tracker_poses(x)  # the marker 50 mm off the platform, in a tracker 1 m away
    y[:, :3] = np.nan
    ver = verify(
        MOTION,
        MeasuredMotion("m.csv", "tracker", t, y, XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        registration=SETUP.registration(),
        tolerance=TOLERANCE,
    )
    assert ver.frame.how == "registration" and not ver.frame.removes_offsets
    np.testing.assert_allclose(ver.frame.p_EM, SETUP.X_PM.translation(), atol=1e-15)
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-5)
    np.testing.assert_allclose(ver.result.x[:, 3:], x[:, 3:], atol=1e-9)
    assert list(ver.offsets) == [0.0] * 6
    assert ver.judgement.passed, ver.judgement.line
    assert "registered to the base frame" in ver.judgement.compared


def test_a_registered_6dof_marker_is_mapped_whole():
    t, x = run()
    y = SETUP.tracker_poses(x)
    ver = verify(
        MOTION,
        MeasuredMotion("m.csv", "tracker", t, y, np.ones(6, bool)),
        clock_offset_s=CLOCK_OFFSET_S,
        registration=SETUP.registration(),
        tolerance=TOLERANCE,
    )
    assert ver.frame.how == "registration" and not np.any(ver.frame.p_EM)
    np.testing.assert_allclose(ver.result.x, x, atol=1e-9)
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-5)
    assert ver.fidelity["rms_rotation_rad"] < 1e-9 and ver.judgement.passed
    assert ver.startup["rms_rotation_rad"] < 1e-9


def test_the_encoder_log_is_on_the_references_clock():
    t = np.arange(0.0, 14.0, 0.02)
    x = MOTION.evaluate(t - 0.015)[0]
    ver = verify(MOTION, MeasuredMotion("/d/run_encoders.csv", "encoders", t, x, np.ones(6, bool)))
    assert ver.clock_offset_s == 0.0 and ver.frame.how == "encoders"
    assert ver.clock == "the encoder log's t_path is the reference's own clock"
    assert ver.latency_s == pytest.approx(0.015, abs=1e-5)
    assert ver.learning == "measured by the encoders, run_encoders.csv"
    assert ver.fidelity["measured"] == list(AXES)
    # It started with the motion: the start-up is the first cycle, the recording before 0 none.
    assert ver.fidelity["window_s"] == pytest.approx((4.0, 12.0), abs=0.02)  # to a sample
    assert ver.result.t[0] == pytest.approx(0.02 - 0.015, abs=1e-5)  # from the reference's 0


def test_a_motion_without_cycles_is_judged_over_the_whole_overlap():
    ended = Harmonics(
        MOTION.amplitude, phase=MOTION.phase, centre=MOTION.centre, periodic=False, end_time=15.0
    )
    t, x = run(reference=ended)
    ver = verify(ended, MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ), CLOCK_OFFSET_S)
    assert ver.cycle_starts.size == 0
    w0, w1 = ver.fidelity["window_s"]
    assert w0 == pytest.approx(REFERENCE_START_S - LATENCY_S, abs=1e-5)
    assert w1 == pytest.approx(15.0, abs=0.02)  # its end, to a sample
    assert ver.result.t[-1] <= 15.0
    assert ver.startup["window_s"][1] == pytest.approx(w0)  # no start-up apart
    assert ver.judgement.passed


def test_uneven_samples_are_judged_at_their_own_times_and_said():
    t, x = run()
    t = t + np.random.default_rng(0).uniform(-0.002, 0.002, len(t))
    x = MOTION.evaluate(t + CLOCK_OFFSET_S - LATENCY_S)[0]
    ver = verify(MOTION, MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ), CLOCK_OFFSET_S)
    assert ver.latency_s == pytest.approx(LATENCY_S, abs=1e-5)
    np.testing.assert_allclose(ver.result.x[:, 3:], x[:, 3:], atol=1e-8)
    assert ver.removed[2].startswith("the samples' steps range ")
    assert ver.removed[2].endswith("each is judged at its own time, nothing resampled")


def test_what_verify_refuses():
    t, x = run()
    measured = MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ)
    with pytest.raises(InvalidConfigError, match="frame must be 'axes' or 'base', got 'fit'"):
        verify(MOTION, measured, frame="fit")
    for bad in (math.nan, math.inf, -math.inf, 1.0000001e10, 1e300):
        with pytest.raises(
            InvalidConfigError, match=r"clock offset must be a number within \+-1e\+10 s"
        ):
            verify(MOTION, measured, clock_offset_s=bad)
    assert verify(MOTION, measured, clock_offset_s=-1e5 + 1e5).clock_offset_s == 0.0
    with pytest.raises(InvalidConfigError, match="no overlap"):
        verify(MOTION, measured, clock_offset_s=-1e5)
    only_z = np.array([False] * 5 + [True])
    with pytest.raises(InvalidConfigError, match="measures Z, along which harmonics does not"):
        verify(MOTION, MeasuredMotion("m.csv", "tracker", t, x * [0, 0, 0, 0, 0, 1], only_z))
    with pytest.raises(InvalidConfigError, match="lasts 2.98 s, shorter than one cycle"):
        verify(MOTION, MeasuredMotion("m.csv", "tracker", t[:150], x[:150], XYZ))
    gap = np.concatenate([t[:500], t[500:] + 0.6])
    with pytest.raises(InvalidConfigError, match="stop for 620 ms after t = 109.98 s"):
        verify(MOTION, MeasuredMotion("m.csv", "tracker", gap, positions(x), XYZ))
    verify(MOTION, MeasuredMotion("m.csv", "tracker", gap, positions(x), XYZ), max_gap_s=0.7)


# -- a recording over part of a long trace, the clocks unknown -----------------------------------

#: A trace of 200 s that repeats every 50 s (a 5 s breath over a slow drift), as a clinic's
#: programmed traces repeat: a clock search can match a stretch a repeat away.
LONG = Harmonics(
    along("X", 2e-3, *([0.0] * 8), 5e-3),
    period_s=50.0,
    periodic=False,
    end_time=200.0,
    centre=(0.0, 0.0, 0.0, 0.0, 0.0, 0.3),
)


def part_of_long(stop_at=None, reversed_until=None, reference=LONG, seconds=120.0, start=80.0):
    """(t on a tracker's clock from 1000 s, positions) of a phantom that followed ``reference``
    from its t = ``start`` s, 60 ms late; held still from the reference's ``stop_at`` s on, or
    running reversed about its mean until ``reversed_until``."""
    t = 1000.0 + np.arange(int(round(seconds * 20.0))) / 20.0
    u = t - 1000.0 + start - LATENCY_S
    x = reference.evaluate(u)[0]
    if stop_at is not None:
        x[u >= stop_at] = reference.evaluate(stop_at)[0]
    if reversed_until is not None:
        early = u < reversed_until
        x[early, 3:] = 2 * np.asarray(reference.centre)[3:] - x[early, 3:]
    return t, positions(x)


def judged(t, y, reference=LONG, **options):
    return verify(reference, MeasuredMotion("m.csv", "tracker", t, y, XYZ), **options)


def test_a_right_recording_over_part_of_a_long_trace_passes_whole():
    ver = judged(*part_of_long())
    assert ver.judgement.verdict == "PASS", ver.judgement.line
    assert ver.shift_s == pytest.approx(-920.0 - LATENCY_S, abs=1e-3)
    assert ver.uncompared["before"] == ver.uncompared["after"] == 0
    assert "not compared" not in ver.judgement.line


@pytest.mark.parametrize("how", [{"stop_at": 140.0}, {"stop_at": 170.0}, {"reversed_until": 120.0}])
def test_a_robot_that_stopped_or_ran_reversed_for_part_of_it_fails(how):
    """Compared whole, the stop or the reversal is in the figures: FAIL, never a PASS of the
    part that followed (a search free to leave half the recording out matched that part a
    repeat away and passed it)."""
    ver = judged(*part_of_long(**how))
    assert ver.judgement.verdict == "FAIL", ver.judgement.line
    left = ver.uncompared["before"] + ver.uncompared["after"]
    assert left <= 0.1 * ver.uncompared["samples"]


def test_a_recording_longer_than_its_reference_is_judged_on_what_no_clock_could_compare():
    """A 60 s trace followed, then 60 s at rest after its end: no shift compares the whole
    recording, and half of it is left out whatever the clock. The clock's own choice leaves
    nothing more out, so the verdict judges the 60 s, the clock known or not, and says that the
    recording outlasts the reference (IntERAct's camera recorded 53.6 s past a 302 s motion)."""
    short = Harmonics(LONG.amplitude, period_s=50.0, periodic=False, end_time=60.0,
                      centre=LONG.centre)  # fmt: skip
    t, y = part_of_long(stop_at=60.0, reference=short, start=0.0)
    for clock in (None, -1000.0):
        ver = judged(t, y, reference=short, clock_offset_s=clock)
        assert ver.judgement.verdict == "PASS", ver.judgement.line
        assert ver.uncompared["longer_s"] == pytest.approx(119.95 - 60.0)
        n, after = ver.uncompared["samples"], ver.uncompared["after"]
        # 60 ms late at 20 Hz: the first two samples before the reference's start (at -60 and
        # -10 ms), and those past its 60 s from the tracker's 60.1 s to 119.95 s
        assert (n, ver.uncompared["before"], after) == (2400, 2, 1198)
        assert (
            "; 1200 of 2400 measured samples not compared (50%: its first 100 ms, before the "
            "reference's start; its last 59.9 s, after the reference's end; the recording "
            "59.95 s longer than the reference); " in ver.judgement.line
        )
    assert ver.uncompared["whole"] is True  # the clock given


def test_a_longer_recording_whose_clock_leaves_out_more_than_it_must_cannot_be_judged():
    """The words' rule at its edge: 50 % left out of a recording that outlasts its reference by
    40 % of it is 10 % of the clock's own choosing (judged); by 39 %, 11 % (cannot judge)."""
    base = {"whole": False, "samples": 1000, "before": 0, "after": 500, "before_s": 0.0,
            "after_s": 50.0, "span_s": 100.0}  # fmt: skip
    words, cannot = uncompared_words({**base, "longer_s": 40.0})
    assert cannot == "" and "the recording 40 s longer than the reference" in words
    _, cannot = uncompared_words({**base, "longer_s": 39.0})
    assert cannot.startswith("the clock found leaves 500 of 1000 measured samples")
    # A clock known, or searched over whole comparisons, is never refused for it.
    assert uncompared_words({**base, "longer_s": 0.0, "whole": True})[1] == ""


def test_a_recording_that_runs_on_past_the_motion_fails_and_says_what_would_tell():
    """The last 60 s of a 140 s trace, then 60 s at rest: without the clock it is a robot that
    stopped as much as a recording past the motion's end. Compared whole it FAILs, and the
    verdict says that a part matches and what to give; the clock given, it PASSes the part."""
    short = Harmonics(LONG.amplitude, period_s=50.0, periodic=False, end_time=140.0,
                      centre=LONG.centre)  # fmt: skip
    t, y = part_of_long(stop_at=140.0, reference=short)
    ver = judged(t, y, reference=short)
    assert ver.judgement.verdict == "FAIL", ver.judgement.line
    assert "a part of it matches, leaving " in ver.judgement.causes[-1]
    assert "give --clock-offset" in ver.judgement.causes[-1]
    given = judged(t, y, reference=short, clock_offset_s=-920.0)
    assert given.judgement.verdict == "PASS", given.judgement.line


def test_the_words_on_the_samples_left_out():
    from stewart_drake.verification.verdict_notes import uncompared_words

    counts = {"samples": 1000, "before": 60, "after": 41, "before_s": 3.0, "after_s": 0.5}
    words, why = uncompared_words({**counts, "whole": True})
    assert words == (
        "101 of 1000 measured samples not compared (10%: its first 3 s, before the reference's "
        "start; its last 500 ms, after the reference's end)"
    )
    assert why == ""  # the clock given or searched whole: said, judged
    words, why = uncompared_words({**counts, "whole": False})
    assert why.startswith("the clock found leaves 101 of 1000 measured samples not compared")
    assert "over 10% of the recording" in why and "give --clock-offset" in why
    counts["after"] = 40  # a tenth: still judged
    assert uncompared_words({**counts, "whole": False})[1] == ""
    assert uncompared_words({"samples": 10, "before": 0, "after": 0, "whole": False}) == ("", "")


# -- the steps -------------------------------------------------------------------------------------


def test_the_words_on_the_samples_steps():
    t = 0.02 * np.arange(100)
    assert vn._samples(t, 0.5) == ("", ())
    t[50:] += 0.0001  # one step 0.5 % long: even
    assert vn._samples(t, 0.5) == ("", ())
    t[60:] += 0.0003  # one 1.5 % long
    assert vn._samples(t, 0.5) == (
        "the samples' steps range 20-20.3 ms (median 20 ms): each is judged at its own time, "
        "nothing resampled",
        (),
    )
    t[70:] += 0.47
    assert vn._samples(t, 0.5)[0].startswith("the samples' steps range 20-490 ms")
    t[70:] += 0.011
    with pytest.raises(InvalidConfigError) as err:
        vn._samples(t, 0.5)
    assert str(err.value).startswith(
        "the measured samples stop for 501 ms after t = 1.3804 s of the file, longer than "
        "--measured-max-gap 500 ms: verify compares"
    )
    # A registration's refusal does not offer a pause it cannot take.
    with pytest.raises(InvalidConfigError) as err:
        vn._samples(t, 0.5, pausable=False)
    assert "--measured-pauses" not in str(err.value) and "lost the marker" in str(err.value)
    # As a pause: named, and the steps' words are those within the segments (20-20.3 ms).
    words, pauses = vn._samples(t, 0.5, pauses=True)
    assert pauses == (pytest.approx((1.3804, 0.501)),)
    assert words.startswith("the samples' steps range 20-20.3 ms")
    # A step of the largest gap exactly is judged across.
    t = 0.25 * np.arange(40)
    t[20:] += 0.25
    assert vn._samples(t, 0.5)[0].startswith("the samples' steps range 250-500 ms")


def test_the_shifts_searched():
    t = np.linspace(100.0, 120.0, 11)
    periodic = MOTION
    ended = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False, end_time=60.0)
    endless = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False)
    # Known clocks: the latencies up to 3 times the bound, at most 0.45 of a period.
    assert span.search_range(ended, t, -98.0, 0.5)[0] == pytest.approx((-99.5, -96.5))
    assert span.search_range(periodic, t, -98.0, 0.5)[0] == pytest.approx((-99.5, -96.5))
    assert span.search_range(periodic, t, -98.0, 1.0)[0] == pytest.approx((-99.8, -96.2))
    # Unknown: the shifts that compare the whole 20 s recording, either end up to a tenth of it
    # (2 s) outside the reference: its start from 2 s before the motion's to its end 2 s past
    # the reference's (60 s), or a period on (4 s), or MAX_SEARCH_S without an end.
    assert span.search_range(ended, t, None, 0.5)[0] == pytest.approx(
        (-102.0, -100.0 + 60.0 - 20.0 + 2.0)
    )
    assert span.search_range(periodic, t, None, 0.5)[0] == pytest.approx((-102.0, -96.0))
    assert span.search_range(endless, t, None, 0.5)[0] == pytest.approx((-102.0, -100.0 + 3600.0))
    # A recording longer than the reference (20 s against 5 s) fits no such shift: its start
    # from half its length before the motion's to the end less half of it (none: 0).
    short = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False, end_time=5.0)
    assert span.search_range(short, t, None, 0.5) == (pytest.approx((-110.0, -100.0)), False)
    assert (
        span.search_range(ended, t, None, 0.5)[1] and span.search_range(periodic, t, -98.0, 0.5)[1]
    )
    # One that fits, 21 s: its start from 2 s before the motion's to 3 s after (its end 2 s
    # past the reference's); one of 16 s, 4 s shorter than the recording, just fits.
    fits = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False, end_time=21.0)
    assert span.search_range(fits, t, None, 0.5)[0] == pytest.approx((-102.0, -97.0))
    just = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False, end_time=16.0)
    assert span.search_range(just, t, None, 0.5)[0] == pytest.approx((-102.0, -102.0))


def test_the_window_is_the_whole_cycles_after_the_first():
    window, starts, holds = span.cycle_window(MOTION, 1.0, 30.0)
    assert window == (4.0, 28.0) and holds
    np.testing.assert_array_equal(starts, [4, 8, 12, 16, 20, 24, 28])
    window, starts, holds = span.cycle_window(MOTION, 8.0, 16.0)  # the edges are in
    assert window == (8.0, 16.0) and not holds and list(starts) == [8, 12, 16]
    window, starts, holds = span.cycle_window(MOTION, 4.0, 12.0)  # from the first cycle's end
    assert window == (4.0, 12.0) and not holds
    with pytest.raises(InvalidConfigError, match="not one whole cycle"):
        span.cycle_window(MOTION, 0.5, 4.0)  # the first cycle alone
    window, starts, holds = span.cycle_window(MOTION, 5.0, 15.9)
    assert window == (8.0, 12.0) and not holds
    with pytest.raises(InvalidConfigError) as err:
        span.cycle_window(MOTION, 5.0, 11.0)
    assert str(err.value) == (
        "the measured motion covers t = 5-11 s of harmonics once aligned: not one whole cycle "
        "(4 s) after the motion's first; record at least two cycles"
    )
    endless = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False, name="trace")
    window, starts, holds = span.cycle_window(endless, 1.5, 5.5)
    assert window == (1.5, 5.5) and starts.size == 0 and not holds
    with pytest.raises(InvalidConfigError, match="covers 3.99 s of trace once aligned, shorter"):
        span.cycle_window(endless, 1.5, 5.49)


def test_the_length_of_a_recording_is_one_cycle_at_least():
    span.check_length(MOTION, np.array([0.0, 4.0]))
    with pytest.raises(InvalidConfigError) as err:
        span.check_length(MOTION, np.array([0.0, 3.99]))
    assert str(err.value) == (
        "the measured motion lasts 3.99 s, shorter than one cycle of harmonics (4 s): record at "
        "least two cycles"
    )
    # A reference without repeat_period_s: its cycles found from its motion (here 5 s), or a
    # breath without any.
    cycling = Harmonics(MOTION.amplitude, phase=MOTION.phase, period_s=5.0, name="c")
    unsaid = type(
        "Unsaid", (), {"name": "u", "evaluate": cycling.evaluate, "cycles": cycling.cycles}
    )()
    span.check_length(unsaid, np.array([0.0, 5.0]))
    with pytest.raises(InvalidConfigError, match="shorter than one cycle of u \\(5 s\\)"):
        span.check_length(unsaid, np.array([0.0, 4.9]))
    endless = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False, name="e")
    span.check_length(endless, np.array([0.0, 4.0]))
    with pytest.raises(InvalidConfigError, match="shorter than one cycle of e \\(4 s\\)"):
        span.check_length(endless, np.array([0.0, 3.9]))


class Lengthening:
    """A trace whose breaths lengthen, 3 s, 3.2 s, 3.4 s...: no repeat_period_s, 20 s long."""

    name = "slowing"
    end_time = 20.0

    def evaluate(self, t):
        return MOTION.evaluate(t)

    def cycles(self, t_end):
        starts = np.cumsum([0.0] + [3.0 + 0.2 * k for k in range(40)])
        k = int(np.searchsorted(starts, t_end - 1e-9))
        return starts[: k + 1], np.ones(k)


def test_a_trace_with_an_end_is_cut_into_its_own_cycles():
    # Its cycles up to its end (3 to 4 s, median 3.5 s), not those past it.
    span.check_length(Lengthening(), np.array([0.0, 3.5]))
    with pytest.raises(InvalidConfigError, match="shorter than one cycle of slowing \\(3.5 s\\)"):
        span.check_length(Lengthening(), np.array([0.0, 3.45]))


def test_a_reference_that_says_nothing_of_itself():
    # Only what the Reference protocol requires: a name and evaluate.
    bare = type("Bare", (), {"name": "bare", "evaluate": staticmethod(MOTION.evaluate)})()
    assert vn._frequencies(bare) == {}
    t = np.linspace(100.0, 120.0, 11)
    assert span.search_range(bare, t, None, 0.5)[0] == pytest.approx((-102.0, -100.0 + 3600.0))
    assert span.search_range(bare, t, -98.0, 0.5)[0] == pytest.approx((-99.5, -96.5))


def test_the_fundamentals_of_a_motion_that_repeats_only():
    assert vn._frequencies(MOTION) == {"breathing": 0.25}
    endless = Harmonics(MOTION.amplitude, phase=MOTION.phase, periodic=False)
    assert vn._frequencies(endless) == {}
    silent = type("Silent", (), {"repeat_period_s": 4.0, "frequencies_hz": None})()
    assert vn._frequencies(silent) == {}


def fidelity_of_six():
    return {
        "rms": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        "peak": [1.5] * 6,
        "rms_fraction": [0.1] * 6,
        "peak_fraction": [0.2] * 6,
        "p2p": [0.0, 0.04, 0.0, 0.01, 0.0, 0.0],
        "cycles": {
            "starts": [4.0, 8.0],
            "rms_rotation_rad": [0.1],
            "rms_translation_m": [0.2],
            "peak_translation_m": [0.3],
            "rms": [[0.01, 0.02, 0.03, 0.04, 0.05, 0.06]],
        },
        "rms_rotation_rad": 0.1,
        "peak_rotation_rad": 0.2,
        "rms_translation_m": 0.3,
        "peak_translation_m": 0.4,
        "lag_s": {"theta": 0.01, "X": 0.02},
        "lag_all_s": 99.0,
        "harmonics": [{"axis": "theta", "k": 1}, {"axis": "X", "k": 1}],
        "moving": ["theta", "X"],
        "window_s": (4.0, 16.0),
    }


def test_the_axes_not_measured_are_nan_and_named():
    fid = fidelity_of_six()
    t = np.arange(2.0, 18.0, 0.02)
    x_d = MOTION.evaluate(t)[0]
    x = MOTION.evaluate(t - 0.05)[0]  # 50 ms late
    out = vn._not_measured(fid, XYZ, t, x, x_d)
    assert fid == fidelity_of_six()  # not changed
    nan3 = [math.nan] * 3
    for key, values in (("rms", [4.0, 5.0, 6.0]), ("peak", [1.5] * 3), ("rms_fraction", [0.1] * 3)):
        np.testing.assert_array_equal(out[key], nan3 + values)
    np.testing.assert_array_equal(out["peak_fraction"], nan3 + [0.2] * 3)
    assert math.isnan(out["rms_rotation_rad"]) and math.isnan(out["peak_rotation_rad"])
    assert out["rms_translation_m"] == 0.3 and out["peak_translation_m"] == 0.4
    assert np.isnan(out["cycles"]["rms_rotation_rad"]).all()
    assert out["cycles"]["rms_translation_m"] == [0.2]
    np.testing.assert_array_equal(out["cycles"]["rms"], [nan3 + [0.04, 0.05, 0.06]])
    assert out["lag_s"] == {"X": 0.02}
    assert out["harmonics"] == [{"axis": "X", "k": 1}]
    assert out["measured"] == ["X", "Y", "Z"]
    assert out["lag_all_s"] == pytest.approx(0.05, abs=1e-3)  # from X alone
    # Rotations only: the translations' figures NaN.
    out = vn._not_measured(fid, ~XYZ, t, x, x_d)
    assert math.isnan(out["rms_translation_m"]) and math.isnan(out["peak_translation_m"])
    assert np.isnan(out["cycles"]["rms_translation_m"]).all()
    assert np.isnan(out["cycles"]["peak_translation_m"]).all()
    assert out["rms_rotation_rad"] == 0.1 and out["cycles"]["rms_rotation_rad"] == [0.1]
    assert out["lag_s"] == {"theta": 0.01} and out["measured"] == ["phi", "theta", "psi"]
    assert out["lag_all_s"] == pytest.approx(0.05, abs=1e-3)
    # X alone (a single-axis sensor): the translations' 3-D figures are over it.
    out = vn._not_measured(fid, np.array([0, 0, 0, 1, 0, 0], bool), t, x, x_d)
    assert out["rms_translation_m"] == 0.3 and out["cycles"]["peak_translation_m"] == [0.3]
    # Only axes the reference does not move along: the lag of the whole motion is left.
    out = vn._not_measured(fid, np.array([1, 0, 0, 0, 1, 1], bool), t, x, x_d)
    assert out["lag_all_s"] == 99.0
    # Every axis: nothing NaN.
    out = vn._not_measured(fid, np.ones(6, bool), t, x, x_d)
    assert out == {**fidelity_of_six(), "measured": list(AXES)}


def test_the_lag_of_the_measured_axes_is_over_the_window():
    # 50 ms late inside the window [4, 16] s, on time outside it.
    fid = fidelity_of_six()
    t = np.arange(2.0, 18.0, 0.02)
    x_d = MOTION.evaluate(t)[0]
    inside = (t >= 4.0 - 1e-9) & (t <= 16.0 + 1e-9)
    x = np.where(inside[:, None], MOTION.evaluate(t - 0.05)[0], x_d)
    out = vn._not_measured(fid, XYZ, t, x, x_d)
    expected = time_lag(t[inside], x[inside][:, [3]], x_d[inside][:, [3]], weights=[100.0])
    assert out["lag_all_s"] == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(0.05, abs=1e-3)


def test_the_lag_of_the_measured_axes_weighs_each_by_its_motion():
    # theta 60 ms late, X on time: weighted by 1 / peak to peak, each counts alike.
    fid = fidelity_of_six()
    t = np.arange(2.0, 18.0, 0.02)
    x_d = MOTION.evaluate(t)[0]
    x = x_d.copy()
    x[:, 1] = MOTION.evaluate(t - 0.06)[0][:, 1]
    seen = np.array([0, 1, 0, 1, 0, 0], bool)
    out = vn._not_measured(fid, seen, t, x, x_d)
    assert 0.02 < out["lag_all_s"] < 0.04


def test_a_file_none_of_whose_axes_move_is_refused():
    fid = {"moving": ["theta", "X"]}
    measured = MeasuredMotion("/d/z.csv", "tracker", np.zeros(2), np.zeros((2, 6)), np.zeros(6))
    vn._check_judgeable(MOTION, fid, np.array([0, 1, 0, 0, 0, 0], bool), measured)
    with pytest.raises(InvalidConfigError) as err:
        vn._check_judgeable(MOTION, fid, np.array([0, 0, 0, 0, 1, 1], bool), measured)
    assert str(err.value) == (
        "/d/z.csv measures Y, Z, along which harmonics does not move (it moves theta, X): "
        "nothing of the motion can be judged; measure along an axis it moves"
    )
    with pytest.raises(InvalidConfigError, match=r"\(it moves along no axis\)"):
        vn._check_judgeable(MOTION, {"moving": []}, np.ones(6, bool), measured)


def test_a_registration_needs_the_markers_positions_and_three_rotations_or_none():
    reg = SETUP.registration()

    def measured(mask):
        return MeasuredMotion("/d/m.csv", "tracker", np.zeros(2), np.zeros((2, 6)), np.array(mask))

    frames = vn._registered(reg, measured([True] * 6))
    assert frames.how == "registration" and frames.note == reg.words()
    np.testing.assert_array_equal(frames.p_EM, np.zeros(3))
    np.testing.assert_array_equal(frames.R_BT, np.eye(3))
    frames = vn._registered(reg, measured([False] * 3 + [True] * 3))
    np.testing.assert_allclose(frames.p_EM, SETUP.X_PM.translation(), atol=1e-15)
    for mask in ([False] * 4 + [True] * 2, [True, False, False, True, True, True]):
        with pytest.raises(InvalidConfigError) as err:
            vn._registered(reg, measured(mask))
        assert str(err.value).startswith(
            "/d/m.csv: a registration maps a tracker's marker (its X, Y and Z, and its three "
            "rotations or none) to the platform; this file measures "
        )
    assert "this file measures phi, X, Y, Z: judge it without --registration" in str(err.value)


def test_the_words_on_the_clock_and_the_frames():
    frames = Frames("base")
    known = vn._removed_words(-0.06, 0.0, 0.06, "given (--clock-offset)", frames, None, None, "")
    assert known == [
        "the clock: the measured motion shifted by -0.06 s onto the reference's clock (the shift "
        "of least distance, by FFT, then to a fraction of a sample): the clock offset +0 s "
        "(given (--clock-offset)) less the latency, 60 ms (> 0: the phantom late)",
        "the frames: none: the file gives the platform's poses in the base frame; nothing removed",
    ]
    unknown = vn._removed_words(-121.5, 0.0, 121.5, "not known", frames, None, None, "uneven")
    assert unknown[0] == (
        "the clock: the measured motion shifted by -121.5 s onto the reference's clock (the "
        "shift of least distance, by FFT, then to a fraction of a sample). The clocks' relation "
        "was not given, so the whole shift is reported as the latency (121.5 s) with clock "
        "offset 0 and is not judged: it holds any offset of the tracker's clock; give "
        "--clock-offset S (the measured time + S = the reference's) to separate the phantom's "
        "own lag and judge it"
    )
    assert unknown[2] == "uneven" and len(unknown) == 3


def test_the_words_on_what_the_figures_leave_out():
    t_all = np.arange(-1.0, 25.0, 0.5)
    t_ref = t_all[(t_all >= 0.0) & (t_all <= 22.0)]
    assert span.outside_words(t_all, t_ref, (4.0, 20.0), True) == [
        "what the figures leave out: 1 s of the recording before the reference's start and 2.5 s "
        "after its end are not compared; the figures are over whole cycles, t = 4-20 s: 4 s "
        "before (the motion's first cycle, the start-up) and 2 s after are outside them"
    ]
    assert span.outside_words(t_ref, t_ref, (4.0, 20.0), False) == [
        "what the figures leave out: the figures are over whole cycles, t = 4-20 s: 4 s before "
        "(part of a cycle) and 2 s after are outside them"
    ]
    assert span.outside_words(t_all, t_ref, (0.0, 22.0), False) == [
        "what the figures leave out: 1 s of the recording before the reference's start and 2.5 s "
        "after its end are not compared"
    ]
    assert span.outside_words(t_ref, t_ref, (0.0, 22.0), False) == []
    assert span.outside_words(t_ref, t_ref, (0.5, 22.0), False) == [
        "what the figures leave out: the figures are over whole cycles, t = 0.5-22 s: 0.5 s "
        "before (part of a cycle) and 0 s after are outside them"
    ]
    assert span.outside_words(t_ref, t_ref, (0.0, 21.5), False)[0].endswith(
        "0 s before (part of a cycle) and 0.5 s after are outside them"
    )
    # Only after, or only before.
    assert "0 s of the recording before" in span.outside_words(t_ref, t_ref[:-1], (0, 21.5), 0)[0]
    assert (
        "1 s of the recording before the reference's start and 0 s after its end"
        in (span.outside_words(t_all[:-5], t_ref, (0, 22.0), 0)[0])
    )


@pytest.mark.parametrize("dy_mm, said", [(5.5, True), (0.101, True), (0.099, False), (0.0, False)])
def test_a_constant_removed_beyond_the_tolerance_is_said_on_the_verdict_line(dy_mm, said):
    # A localisation error of dy on Y, the tracker's axes the base's: --frame axes removes it
    # and passes; the verdict line says so when it is larger than the 0.1 mm tolerance.
    t, x = run()
    measured = MeasuredMotion("m.csv", "tracker", t, positions(x, (0.0, dy_mm * 1e-3, 0.0)), XYZ)
    ver = verify(MOTION, measured, clock_offset_s=CLOCK_OFFSET_S, tolerance=TOLERANCE)
    assert ver.judgement.passed and ver.offsets[4] == pytest.approx(dy_mm * 1e-3, abs=1e-9)
    words = f"a constant removed and not judged, larger than the tolerance: Y +{dy_mm:.4g} mm ("
    assert (words in ver.judgement.line) is said
    assert ("constant removed" in ver.judgement.line) is said
    # The base frame removes nothing: the same 5.5 mm is judged, and fails.
    if dy_mm == 5.5:
        base = verify(
            MOTION, measured, clock_offset_s=CLOCK_OFFSET_S, tolerance=TOLERANCE, frame="base"
        )
        assert not base.judgement.passed and "constant removed" not in base.judgement.line
        assert "Y 5.5 mm" in base.judgement.line


def _paused(x_of_t, t, start=140.0, stop=190.825):
    """The tracker's samples of ``x_of_t`` with none from ``start`` to ``stop`` (its clock, s):
    a planned pause of 50.8 s between two imaging arcs."""
    keep = ~((t > start) & (t < stop))
    return MeasuredMotion("m.csv", "tracker", t[keep], positions(x_of_t)[keep], XYZ)


def test_a_planned_pause_is_refused_by_default_naming_the_option_and_judged_as_segments():
    t, x = run(seconds=120.0, rate_hz=20.0)
    measured = _paused(x, t)
    with pytest.raises(InvalidConfigError, match="give --measured-pauses to judge") as err:
        verify(MOTION, measured, clock_offset_s=CLOCK_OFFSET_S, tolerance=TOLERANCE)
    # The samples at 140 s and 190.85 s of the tracker's 20 Hz clock either side.
    assert "stop for 50.85 s after t = 140 s of the file" in str(err.value)
    for clock in (CLOCK_OFFSET_S, None):
        ver = verify(MOTION, measured, clock_offset_s=clock, tolerance=TOLERANCE, pauses=True)
        assert ver.judgement.passed and ver.pauses == (pytest.approx((140.0, 50.85)),)
        assert (
            "; judged in 2 segments across a pause (50.85 s after t = 140 s of the file): each "
            "sample at its own time, nothing bridged" in ver.judgement.line
        )
        # The steps within the segments are even: no word on them.
        assert not any("steps range" in w for w in ver.removed)
    # A robot that stopped during the pause and never moved again fails, clock known or not.
    held = x.copy()
    held[t > 140.0] = x[np.flatnonzero(t > 140.0)[0]]
    for clock in (CLOCK_OFFSET_S, None):
        ver = verify(
            MOTION, _paused(held, t), clock_offset_s=clock, tolerance=TOLERANCE, pauses=True
        )
        assert not ver.judgement.passed and ver.judgement.line.startswith("FAIL")
    # Without a pause, pauses changes nothing.
    plain = verify(
        MOTION,
        MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ),
        clock_offset_s=CLOCK_OFFSET_S,
        tolerance=TOLERANCE,
        pauses=True,
    )
    assert plain.pauses == () and "segments" not in plain.judgement.line


def test_many_pauses_are_counted_past_the_third():
    from stewart_drake.verification.verdict_notes import pause_words

    words = pause_words(((10.0, 1.0), (20.0, 2.0), (30.0, 3.0), (40.0, 4.0), (50.0, 5.0)))
    assert words == (
        "; judged in 6 segments across 5 pauses (1 s after t = 10 s, 2 s after t = 20 s, 3 s "
        "after t = 30 s and 2 more of the file): each sample at its own time, nothing bridged"
    )
    assert pause_words(()) == ""


def _glitched(t, x, every=5, size_m=0.03, seed=3):
    """The tracker's positions with every ``every``-th frame's marker mis-detected: ``size_m``
    off on a random axis, either sign (163 of 874 frames up to 51 mm in a clinic's export)."""
    y = positions(x)
    rng = np.random.default_rng(seed)
    bad = np.arange(7, len(t), every)
    axes = 3 + rng.integers(0, 3, bad.size)
    y[bad, axes] += size_m * rng.choice([-1.0, 1.0], bad.size) * rng.uniform(0.2, 1.0, bad.size)
    return y, bad


def test_outliers_are_counted_and_named_with_the_verdict_of_the_rest_and_can_be_excluded():
    t, x = run(seconds=40.0, rate_hz=20.0)
    y, bad = _glitched(t, x)
    measured = MeasuredMotion("m.csv", "tracker", t, y, XYZ)
    ver = verify(MOTION, measured, clock_offset_s=CLOCK_OFFSET_S, tolerance=TOLERANCE)
    line = ver.judgement.line
    assert line.startswith("FAIL")
    # Every glitched frame compared is flagged, and nothing else (the clock puts the first
    # frame 60 ms before the reference's start: not compared).
    t_ref = t + CLOCK_OFFSET_S - LATENCY_S
    compared = bad[t_ref[bad] >= 0.0]
    assert sorted(ver.outliers["indices"]) == sorted(compared)
    assert ver.outliers["samples"] == np.count_nonzero(t_ref >= 0.0)
    assert (
        f"; {compared.size} of {ver.outliers['samples']} frames compared are outliers (beyond 6 "
        "robust SD and 5x" in line
    )
    assert "within the tolerance; --exclude-outliers judges without them" in line
    # The rest's RMS: the clean frames, on a clock the outliers moved by ~10 ms (the breath's
    # 5 mm at 0.25 Hz moves 0.08 mm in 10 ms: X's, the others' far less).
    rest = ver.outliers["rest_rms"][3:]
    assert rest[0] < 0.1e-3 and np.all(rest[1:] < 0.03e-3)
    # Excluded: PASS, the count said; the clock the same.
    clean = verify(MOTION, measured, clock_offset_s=CLOCK_OFFSET_S, tolerance=TOLERANCE,
                   exclude_outliers=True)  # fmt: skip
    assert clean.judgement.passed, clean.judgement.line
    assert clean.excluded == compared.size
    assert (
        f"; {compared.size} frames excluded as outliers (--exclude-outliers" in clean.judgement.line
    )
    assert clean.latency_s == pytest.approx(LATENCY_S, abs=1e-4)


@pytest.mark.parametrize("size_mm, flagged", [(0.45, False), (0.6, True)])
def test_a_frame_is_an_outlier_only_beyond_five_tolerances(size_mm, flagged):
    # One frame off by 4.5 or 6 tolerances (0.1 mm) on a clean run: the robust SD is ~0, so the
    # tolerance's multiple decides.
    t, x = run(seconds=20.0, rate_hz=50.0)
    y = positions(x)
    y[500, 4] += size_mm * 1e-3
    ver = verify(MOTION, MeasuredMotion("m.csv", "tracker", t, y, XYZ),
                 clock_offset_s=CLOCK_OFFSET_S, tolerance=TOLERANCE)  # fmt: skip
    assert (ver.outliers["frames"] == 1) is flagged
    assert ("frames compared are outliers" in ver.judgement.line) is flagged
    assert ver.judgement.passed  # one frame in 1000 moves the RMS by ~size / 31


def test_the_result_carries_the_tolerance_it_was_judged_at_and_its_report_states_it(tmp_path):
    """The verdict's tolerance travels with the result: the page, the figure's JSON and the
    record read it from there, none is given it again. 0.25 mm | 0.3 deg, a tolerance no
    default holds: the page states it and the JSON's verdict is the one judged at it."""
    from stewart_drake.verification.report import verification_markdown, write_verification

    t, x = run()
    measured = MeasuredMotion("m.csv", "tracker", t, positions(x), XYZ)
    wide = (2.5e-4, math.radians(0.3))
    ver = verify(MOTION, measured, clock_offset_s=CLOCK_OFFSET_S, tolerance=wide)
    assert ver.tolerance == pytest.approx(wide, rel=1e-15)
    assert ver.judgement.tolerance == pytest.approx(wide, rel=1e-15)
    assert "0.25 mm | 0.3 deg" in verification_markdown(ver)
    md, _, _ = write_verification(ver, tmp_path, "v")
    assert "0.25 mm | 0.3 deg" in md.read_text()
    assert "0.1 mm | 0.1 deg" not in md.read_text()
