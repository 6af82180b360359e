"""verify's judgement of a pair (surrogate/pair_judgement.py) piece by piece, as a user reads it:
the verdict's line word for word on each side of its bound and its search's edge, the width
searched, the refusal of two measurements not on one clock, the samples compared, and the
pair's JSON key by key. The pair judged whole, on a camera's files, is
tests/test_relative_latency.py's."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.verification.pair_judgement import (
    MIN_INSIDE,
    RELATIVE_SEARCH_S,
    check_one_clock,
    judge_relative,
    search_half_width,
    span_mask,
)
from stewart_drake.verification.verify import judged_window

NAMES = ("a.csv", "b.csv")
HEAD = "a.csv (internal) against b.csv (surrogate) on one clock: "


def _judge(tau, bound=0.1, half=1.5, not_following=(None, None), swapped=None):
    return judge_relative(tau, bound, half, NAMES, not_following, swapped)


@pytest.mark.parametrize(
    "tau, passed, figure",
    [
        (0.06, True, "relative latency 60 ms (the internal target late against the surrogate) "
         "within +-100 ms"),
        (-0.06, True, "relative latency -60 ms (the surrogate late against the internal target) "
         "within +-100 ms"),
        (0.1, True, "relative latency 100 ms (the internal target late against the surrogate) "
         "within +-100 ms"),  # at the bound: taken
        (0.0, True, "relative latency 0 ms (neither late) within +-100 ms"),
    ],
)  # fmt: skip
def test_a_relative_latency_within_its_bound_passes_in_one_line(tau, passed, figure):
    judged = _judge(tau)
    assert judged.line == f"PASS: {HEAD}{figure}"
    assert judged.passed and judged.meaningful and not judged.at_edge and judged.causes == []
    assert judged.relative_latency_s == tau and judged.max_relative_latency_s == 0.1


def test_a_relative_latency_beyond_its_bound_fails_naming_which_is_late():
    judged = _judge(0.1001)
    cause = (
        "relative latency 100.1 ms beyond --max-relative-latency 100 ms: the internal target "
        "late against the surrogate"
    )
    assert judged.line == (
        f"FAIL: {HEAD}relative latency 100.1 ms (the internal target late against the "
        f"surrogate) beyond +-100 ms; cause: {cause}"
    )
    assert not judged.passed and judged.meaningful and judged.causes == [cause]
    assert _judge(-0.3).causes == [
        "relative latency -300 ms beyond --max-relative-latency 100 ms: the surrogate late "
        "against the internal target"
    ]


def test_a_relative_latency_at_the_edge_of_the_search_is_at_least_it():
    """Within EDGE_S (50 ms) of the half width searched it is at the edge, whatever its bound;
    50 ms or more inside it is not."""
    judged = _judge(-1.46, bound=2.0)
    late = "which one is late is not known beyond the relative latencies searched"
    cause = (
        f"relative latency at least -1.46 s beyond --max-relative-latency 2 s: {late} (at the "
        "edge of the relative latencies searched)"
    )
    assert judged.line == (
        f"FAIL: {HEAD}relative latency at least -1.46 s ({late}) beyond +-2 s; cause: {cause}"
    )
    assert judged.at_edge and not judged.passed and judged.causes == [cause]
    inside = _judge(1.45, bound=2.0)  # 50 ms inside the edge
    assert inside.passed and not inside.at_edge and "at least" not in inside.line


def test_a_relative_latency_of_no_meaning_names_every_cause():
    judged = _judge(0.02, not_following=(None, "is at rest"), swapped="the files swapped")
    assert judged.line == (
        f"FAIL: {HEAD}relative latency 20 ms of no meaning while the cause holds; cause: the "
        "files swapped; the surrogate is at rest"
    )
    assert not judged.meaningful and not judged.passed
    assert judged.causes == ["the files swapped", "the surrogate is at rest"]
    both = _judge(0.5, not_following=("moves another way", "is at rest"))
    assert both.causes == ["the internal target moves another way", "the surrogate is at rest"]
    assert json.loads(json.dumps(both.as_dict())) == {
        "passed": False,
        "line": both.line,
        "relative_latency_s": 0.5,
        "max_relative_latency_s": 0.1,
        "meaningful": False,
        "at_edge": False,
        "causes": both.causes,
    }


def test_the_width_searched_is_the_wider_of_its_two_and_below_half_a_breath():
    assert RELATIVE_SEARCH_S == 1.5
    once = SimpleNamespace()  # no repeat_period_s: a motion that does not repeat
    assert search_half_width(once, 0.1) == 1.5
    assert search_half_width(once, 0.8) == pytest.approx(2.4, rel=1e-12)  # 3 x the bound
    assert search_half_width(SimpleNamespace(repeat_period_s=4.0), 0.1) == 1.5  # 1.8 > 1.5
    assert search_half_width(SimpleNamespace(repeat_period_s=2.0), 0.1) == pytest.approx(0.9)
    assert search_half_width(SimpleNamespace(repeat_period_s=None), 0.1) == 1.5


@pytest.mark.parametrize(
    "t_internal, t_surrogate",
    [
        ([0.0, 1.0, 2.0, 10.0], [9.5, 20.0, 21.0, 22.0]),  # overlap 9.5-10: its last sample
        ([0.0, 1.0, 2.0, 10.0], [-5.0, -4.0, -3.0, 0.5]),  # overlap 0-0.5: its first sample
        ([9.5, 20.0, 21.0, 22.0], [0.0, 1.0, 2.0, 10.0]),
        ([-5.0, -4.0, -3.0, 0.5], [0.0, 1.0, 2.0, 10.0]),
    ],
)
def test_two_measurements_overlapping_by_their_end_samples_are_on_one_clock(
    t_internal, t_surrogate
):
    check_one_clock(
        SimpleNamespace(t=np.array(t_internal), path="a.csv"),
        SimpleNamespace(t=np.array(t_surrogate), path="b.csv"),
    )


def test_two_measurements_that_only_touch_are_not_on_one_clock():
    with pytest.raises(InvalidConfigError) as refused:
        check_one_clock(
            SimpleNamespace(t=np.array([0.0, 1.0, 2.0]), path="a.csv"),
            SimpleNamespace(t=np.array([2.0, 3.0, 4.5]), path="b.csv"),
        )
    assert str(refused.value) == (
        "a.csv spans t = 0-2 s and b.csv t = 2-4.5 s: they do not overlap, so they are not on "
        "one clock; give two measurements made together on one clock (one camera seeing both "
        "platforms, or instruments sharing a clock)"
    )


def test_the_samples_compared_are_those_inside_the_references_span():
    t_ref = np.arange(-10, 71) / 10.0  # -1 to 7 s by 0.1 s, 0 and 5 exactly
    mask = span_mask(SimpleNamespace(end_time=5.0), t_ref)
    np.testing.assert_array_equal(mask, (t_ref >= 0.0) & (t_ref <= 5.0))
    assert mask[10] and mask[60] and np.count_nonzero(mask) == 51  # both ends taken
    np.testing.assert_array_equal(span_mask(SimpleNamespace(), t_ref), t_ref >= 0.0)
    np.testing.assert_array_equal(span_mask(SimpleNamespace(end_time=None), t_ref), t_ref >= 0.0)
    # Exactly MIN_INSIDE inside: those alone; one fewer: all of them.
    assert MIN_INSIDE == 10
    ten = span_mask(SimpleNamespace(end_time=0.9), t_ref)
    assert ten.dtype == bool and np.count_nonzero(ten) == 10
    nine = span_mask(SimpleNamespace(end_time=0.8), t_ref)
    assert nine.dtype == bool and nine.shape == t_ref.shape and nine.all()


def test_a_window_holds_its_ends_and_fills_an_axis_not_measured_with_the_reference():
    t = np.arange(6, dtype=float)
    x_d = np.arange(36, dtype=float).reshape(6, 6)
    x = x_d + 0.5
    x[:, :5] = np.nan  # Z measured only
    ver = SimpleNamespace(
        result=SimpleNamespace(t=t, x=x, x_d=x_d), fidelity={"window_s": (1.0, 4.0)}
    )
    tw, xw, xdw = judged_window(ver)
    np.testing.assert_array_equal(tw, [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(xdw, x_d[1:5])
    want = x_d[1:5].copy()
    want[:, 5] += 0.5
    np.testing.assert_array_equal(xw, want)
    assert xw.dtype == float


def test_the_pairs_json_holds_every_figure_under_its_name(tmp_path):
    from test_relative_latency import judge, pair_files

    pair = judge(*pair_files(tmp_path))
    d = json.loads(json.dumps(pair.as_dict(), allow_nan=False))  # no NaN in the JSON
    assert set(d) == {
        "verdict", "passed", "relative_latency_s", "definition", "internal_shift_s",
        "surrogate_shift_s", "searched_s", "relative", "internal", "surrogate", "notes",
    }  # fmt: skip
    assert d["passed"] is pair.passed is True and d["verdict"] == "PASS"
    assert d["relative_latency_s"] == pair.relative_latency_s
    assert d["internal_shift_s"] == pair.internal_shift_s
    assert d["surrogate_shift_s"] == pair.surrogate_shift_s
    assert d["searched_s"] == [-1.5, 1.5] and d["notes"] == pair.notes == []
    assert d["definition"].startswith("relative latency = the internal target's latency - ")
    assert d["relative"] == pair.judgement.as_dict()
    for key, ver, axis in (("internal", pair.internal, 5), ("surrogate", pair.surrogate, 3)):
        one = d[key]
        assert set(one) == {
            "reference", "measured", "axes", "shift_s", "latency_s", "clock", "rms",
            "window_s", "verdict", "passed", "line",
        }  # fmt: skip
        assert one["reference"] == ver.name and one["measured"] == ver.measured.path
        assert one["axes"] == ver.fidelity["measured"] and one["clock"] == ver.clock
        assert one["shift_s"] == ver.shift_s and one["latency_s"] == ver.latency_s
        assert one["window_s"] == list(ver.fidelity["window_s"])
        assert one["verdict"] == ver.judgement.verdict and one["passed"] is ver.judgement.passed
        assert one["line"] == ver.judgement.line
        # The one axis measured keeps its RMS; the five not measured are None, not NaN.
        assert one["rms"][axis] == ver.fidelity["rms"][axis] and 0 < one["rms"][axis] < 1e-3
        assert [v is None for v in one["rms"]] == [k != axis for k in range(6)]
        assert all(math.isnan(ver.fidelity["rms"][k]) for k in range(6) if k != axis)


def test_the_pairs_options_reach_verify_as_given(tmp_path):
    """Without a tolerance, verify's default (0.1 mm); a latency bound, a largest gap and
    frames given are each the one verify judges with."""
    from test_relative_latency import DELAY_S, SURROGATE, TRACE, pair_files

    from stewart_drake.references.traces import load_trace
    from stewart_drake.verification.measured_motion import read_measured
    from stewart_drake.verification.pair_judgement import verify_pair
    from stewart_drake.verification.verify import DEFAULT_TOLERANCE

    files = pair_files(tmp_path)

    def pair(**options):
        return verify_pair(
            load_trace(TRACE),
            load_trace(SURROGATE),
            read_measured(files[0], axis_map={"depth": "AP"}),
            read_measured(files[1], axis_map={"depth": "SI"}),
            **options,
        )

    assert DEFAULT_TOLERANCE[0] == 1e-4
    assert "per axis beyond 0.1 mm | 0.1 deg" in pair().internal.judgement.line  # 0.2 mm noise
    # The clocks' offset given 0.2 s off: a latency of 0.2 s, within 0.5 s, beyond 0.1 s.
    offset, wide = -DELAY_S + 0.2, (1e-3, math.radians(1.0))
    within = pair(clock_offset_s=offset, tolerance=wide).internal
    assert abs(within.latency_s) == pytest.approx(0.2, abs=0.01)
    assert within.judgement.latency_judged and within.judgement.passed, within.judgement.line
    late = pair(clock_offset_s=offset, tolerance=wide, max_latency_s=0.1).internal.judgement
    assert not late.passed and "latency" in late.line
    with pytest.raises(InvalidConfigError, match="--measured-max-gap 20 ms"):
        pair(max_gap_s=0.02)  # the camera's steps are 26.5-36.5 ms
    assert pair(frame="base").internal.frame.how == "base"


# -- the pair's relative latency on the internal's clock -------------------------------------------


class _Motion:
    """A reference of sines (evaluate(t) -> (poses,)): rotations a 2 deg tilt of 5 s about X,
    translations a 10 mm, 4 s breath along X and a quarter of it on Y; ``only_x`` the
    surrogate's, a 4 mm, 4 s sine on X 0.3 s ahead with its second harmonic."""

    end_time = None

    def __init__(self, only_x=False):
        self.only_x = only_x

    def evaluate(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.zeros((t.size, 6))
        if self.only_x:
            phi = 2 * np.pi * (t + 0.3) / 4.0
            x[:, 3] = 4e-3 * (np.sin(phi) + 0.25 * np.sin(2 * phi))
            return (x,)
        x[:, 0] = math.radians(1.0) * np.sin(2 * np.pi * t / 5.0)
        x[:, 3] = 5e-3 * np.sin(2 * np.pi * t / 4.0)
        x[:, 4] = 0.25 * x[:, 3]
        return (x,)


#: The internal's clock shift (the measured time + D_I = the reference's), s; the lags put in
#: on the internal's clock, s: its translations', its rotations' and the surrogate's.
D_I, LAG_TRANSLATION, LAG_ROTATION, LAG_SURROGATE = -5.0, 0.002, 0.03, 0.05


def _pair(seen, surrogate_from=None, nan_row=None):
    """(internal, its surrogate reference, the surrogate measured): the internal's samples on
    its reference's clock at a camera's uneven steps over 0-30 s, its translations
    LAG_TRANSLATION late and its rotations LAG_ROTATION late, ``seen`` (6,) the axes it
    measured (the others NaN); the surrogate's samples every 20 ms on the measured clock
    LAG_SURROGATE late, from ``surrogate_from`` (measured clock, s) on."""
    steps = np.random.default_rng(3).uniform(0.0265, 0.0365, 1000)
    t = np.cumsum(steps)
    t = t[t < 30.0]
    internal_reference, surrogate_reference = _Motion(), _Motion(only_x=True)
    x_d = internal_reference.evaluate(t)[0]
    x = np.hstack(
        [
            internal_reference.evaluate(t - LAG_ROTATION)[0][:, :3],
            internal_reference.evaluate(t - LAG_TRANSLATION)[0][:, 3:],
        ]
    )
    x[:, ~np.asarray(seen, dtype=bool)] = np.nan
    if nan_row is not None:
        x[nan_row] = np.nan  # a sample the tracker lost
    s_t = np.arange(t[0] - D_I if surrogate_from is None else surrogate_from, 36.0, 0.02)
    s_poses = surrogate_reference.evaluate(s_t + D_I - LAG_SURROGATE)[0]
    internal = SimpleNamespace(
        result=SimpleNamespace(t=t, x=x, x_d=x_d),
        shift_s=D_I,
        measured=SimpleNamespace(measured=np.asarray(seen, dtype=bool)),
    )
    measured_x = np.array([False, False, False, True, False, False])
    surrogate = SimpleNamespace(t=s_t, poses=s_poses, measured=measured_x)
    return internal, surrogate_reference, surrogate


def test_the_pair_s_lags_are_each_motion_s_own_along_what_it_measured():
    from stewart_drake.verification.pair_judgement import pair_relative_latency

    every = np.ones(6, dtype=bool)
    lat = pair_relative_latency(*_pair(every), 1.5)
    # The internal's along its translations' principal direction (its rotations lag otherwise).
    assert lat.internal_lag_s == pytest.approx(LAG_TRANSLATION, abs=2e-5)
    assert lat.external_lag_s == pytest.approx(LAG_SURROGATE, abs=2e-5)
    assert lat.relative_s == pytest.approx(LAG_TRANSLATION - LAG_SURROGATE, abs=3e-5)
    np.testing.assert_allclose(lat.direction, np.array([1.0, 0.25, 0.0]) / math.hypot(1, 0.25))
    # A tracker of rotations alone: the internal's lag is its rotations'.
    rotations = np.array([True, True, True, False, False, False])
    lat = pair_relative_latency(*_pair(rotations), 1.5)
    assert lat.internal_lag_s == pytest.approx(LAG_ROTATION, abs=2e-5)
    # One translation measured: the others take no part (they lag as the measured one here).
    z_less = np.array([False, False, False, True, False, False])
    assert pair_relative_latency(*_pair(z_less), 1.5).internal_lag_s == pytest.approx(
        LAG_TRANSLATION, abs=2e-5
    )


def test_the_pair_compares_only_where_both_measured_and_each_sample_it_has():
    from stewart_drake.base.lag import inner_mask
    from stewart_drake.verification.pair_judgement import pair_relative_latency

    every = np.ones(6, dtype=bool)
    # The surrogate's file starts 12 s later on the measured clock: the internal's samples
    # before it are not compared, rather than against its first sample held.
    internal, reference, surrogate = _pair(every, surrogate_from=17.0)
    lat = pair_relative_latency(internal, reference, surrogate, 1.5)
    t = internal.result.t
    both = t[t - D_I >= 17.0]
    assert lat.samples == np.count_nonzero(inner_mask(both, 0.5))
    assert lat.external_lag_s == pytest.approx(LAG_SURROGATE, abs=2e-5)
    # A sample the tracker lost is left out, not compared as the reference.
    lost = pair_relative_latency(*_pair(every, nan_row=400), 1.5)
    whole = pair_relative_latency(*_pair(every), 1.5)
    assert lost.samples == whole.samples - 1
    assert lost.internal_lag_s == pytest.approx(LAG_TRANSLATION, abs=2e-5)


def test_the_pair_s_samples_end_with_the_surrogate_s_file_and_its_reference():
    """The internal's samples compared are those inside the surrogate's file, its first and last
    samples' times included (put here exactly on two of the internal's, on the measured clock),
    and inside the surrogate reference's span: a reference that ends at 22 s ends the pair
    there."""
    from stewart_drake.base.lag import inner_mask
    from stewart_drake.verification.pair_judgement import pair_relative_latency

    every = np.ones(6, dtype=bool)
    internal, reference, surrogate = _pair(every)
    t = internal.result.t
    j, k = 100, 700  # the surrogate's file from the internal's sample j to its sample k
    s_t = np.concatenate([[t[j] - D_I], np.arange(t[j] - D_I + 0.01, t[k] - D_I, 0.02)])
    s_t = np.append(s_t, t[k] - D_I)
    s_poses = reference.evaluate(s_t + D_I - LAG_SURROGATE)[0]
    inside = SimpleNamespace(t=s_t, poses=s_poses, measured=surrogate.measured)
    lat = pair_relative_latency(internal, reference, inside, 1.5)
    assert lat.samples == np.count_nonzero(inner_mask(t[j : k + 1], 0.5))
    assert lat.external_lag_s == pytest.approx(LAG_SURROGATE, abs=2e-5)
    ending = _Motion(only_x=True)
    ending.end_time = 22.0
    lat = pair_relative_latency(internal, ending, surrogate, 1.5)
    assert lat.samples == np.count_nonzero(inner_mask(t[t <= 22.0], 0.5))


def test_a_surrogate_lag_beyond_the_usual_search_is_searched_wider_only_then():
    from stewart_drake.base.pair_figures import LAG_SEARCH_S
    from stewart_drake.verification import pair_judgement

    every = np.ones(6, dtype=bool)
    internal, reference, surrogate = _pair(every)
    narrow = pair_judgement.pair_relative_latency(internal, reference, surrogate, 1.5)
    # The usual search's samples: those more than LAG_SEARCH_S from either end.
    from stewart_drake.base.lag import inner_mask

    assert narrow.samples == np.count_nonzero(inner_mask(internal.result.t, LAG_SEARCH_S))
    # The surrogate 0.9 s later still: beyond the usual +-0.5 s, found by the +-1.5 s search,
    # over the samples more than 1.5 s from either end of where both were measured.
    late = SimpleNamespace(t=surrogate.t + 0.9, poses=surrogate.poses, measured=surrogate.measured)
    wide = pair_judgement.pair_relative_latency(internal, reference, late, 1.5)
    assert wide.external_lag_s == pytest.approx(LAG_SURROGATE + 0.9, abs=2e-5)
    t = internal.result.t
    both = t[t - D_I >= late.t[0]]
    assert wide.samples == np.count_nonzero(inner_mask(both, 1.5))


def test_the_surrogate_s_own_match_is_noted_beyond_two_coarse_steps_either_way():
    """The note that the surrogate alone matches its reference elsewhere: none at two of
    verify's coarse steps from the pair's shift, one beyond, naming the side."""
    from stewart_drake.verification.pair_judgement import _own_match_notes
    from stewart_drake.verification.verify import COARSE_STEP_S

    for apart in (2 * COARSE_STEP_S, -2 * COARSE_STEP_S, 0.0):
        assert _own_match_notes(apart, "surrogate.csv", 1.5) == []
    (later,) = _own_match_notes(2.5 * COARSE_STEP_S, "surrogate.csv", 1.5)
    (earlier,) = _own_match_notes(-2.5 * COARSE_STEP_S, "surrogate.csv", 1.5)
    assert "surrogate.csv matches its reference best" in later and " later than " in later
    assert " earlier than " in earlier and "within +-1.5 s" in earlier
