"""A recorded trace joined without its measurement noise: the noise estimated from the samples,
the reference closer to the motion than the samples are, no acceleration invented, and a clean
recording followed to within its rounding."""

import numpy as np
import pytest

from stewart_drake.references.trace_cleaning import noise_estimate, smoothed_spline
from stewart_drake.references.traces import load_trace


def _breathing(t):
    """A breath of 4 s, 12 mm peak to peak, with a second harmonic (mm)."""
    return 6.0 * np.sin(2 * np.pi * t / 4.0) + 1.5 * np.sin(4 * np.pi * t / 4.0 + 0.7)


@pytest.mark.parametrize("sigma_mm", [0.02, 0.1, 0.3])
def test_the_noise_is_estimated_from_the_samples_whatever_the_motion(sigma_mm):
    t = np.arange(0.0, 120.0, 0.2)  # 5 Hz, as the liver traces
    noise = np.random.default_rng(3).normal(0.0, sigma_mm, t.size)
    estimate = noise_estimate(_breathing(t) + noise)
    assert estimate == pytest.approx(sigma_mm, rel=0.2)
    assert noise_estimate(_breathing(t)) < 0.003  # the motion alone is not noise
    step = np.where(t > 60.0, 10.0, 0.0)  # an excursion is not noise either
    assert noise_estimate(_breathing(t) + noise + step) == pytest.approx(estimate, rel=0.05)


def _written(tmp_path, t, si, name):
    path = tmp_path / name
    path.write_text("t [s], SI [mm]\n" + "".join(f"{a:.2f}, {b:.4f}\n" for a, b in zip(t, si)))
    return path


def test_a_noisy_trace_becomes_the_motion_not_the_noise(tmp_path):
    """0.1 mm of white noise at 5 Hz: the reference is closer to the motion than the samples
    are, departs from them by the noise (said in the report), and asks for the motion's
    acceleration, where a spline through every sample invents 3x more."""
    t = np.arange(0.0, 60.0, 0.2)
    clean = _breathing(t)
    noisy = clean + np.random.default_rng(7).normal(0.0, 0.1, t.size)
    path = _written(tmp_path, t, noisy, "noisy.csv")
    smooth = load_trace(path, centre_on="none")
    exact = load_trace(path, centre_on="none", smoothing="none")
    tt = np.arange(1.0, 59.0, 0.01)
    x_s, _, a_s = smooth.evaluate(tt)
    _, _, a_e = exact.evaluate(tt)
    rms = lambda v: float(np.sqrt(np.mean(np.square(v))))  # noqa: E731
    assert rms(x_s[:, 3] * 1e3 - _breathing(tt)) < rms(noisy - clean)
    ((axis, departure),) = smooth.info.departures
    assert axis == "X" and departure * 1e3 == pytest.approx(0.1, rel=0.2)
    assert "departs from the samples by X 0.1 mm RMS" in smooth.info.smoothing_words()
    h = 1e-3
    truth_a = (_breathing(tt + h) - 2 * _breathing(tt) + _breathing(tt - h)) / h**2
    invented_s = rms(a_s[:, 3] * 1e3 - truth_a)
    assert invented_s < 0.2 * rms(truth_a)
    assert rms(a_e[:, 3] * 1e3 - truth_a) > 3 * invented_s
    assert exact.info.smoothing_words() == "joined through every sample (no smoothing)"


def test_a_clean_trace_is_followed_to_within_its_rounding(tmp_path):
    """Written to 0.1 um at 10 Hz: the smoothed reference stays within 0.5 um of every sample
    (the rounding is 0.03 um RMS; the spline's natural ends bend the last samples most)."""
    t = np.arange(0.0, 30.0, 0.1)
    path = _written(tmp_path, t, _breathing(t), "clean.csv")
    ref = load_trace(path, centre_on="none")
    x = ref.evaluate(t)[0][:, 3] * 1e3
    assert np.max(np.abs(x - np.round(_breathing(t), 4))) < 5e-4
    assert ref.info.departures[0][1] < 1e-7


def test_a_looped_recording_has_its_seams_found_and_blended(tmp_path):
    """A 28 s recording that drifts 2 mm, repeated four times: its loop and three seams are
    found, each blended over 2 s (the report says so), the reference is the recording outside
    the blends, and the acceleration at a seam is the blend's (5.8 x 2 mm / (2 s)^2), not the
    2 mm step's in one sample."""
    t1 = np.arange(0.0, 28.0, 0.2)
    one = _breathing(t1) + 2.0 * t1 / 28.0
    si = np.tile(one, 4)
    t = np.arange(si.size) * 0.2
    path = _written(tmp_path, t, si, "looped.csv")
    ref = load_trace(path, centre_on="none")
    assert ref.info.loop_period_s == pytest.approx(28.0)
    assert ref.info.seams == 3
    assert ref.info.seam_words().startswith("a loop of 28 s: 3 seams blended over 2 s")
    seams = np.array([28.0, 56.0, 84.0]) - 0.1
    far = np.min(np.abs(t[:, None] - seams[None, :]), axis=1) > 1.1
    inner = far & (t > 1.0) & (t < t[-1] - 1.0)
    assert np.max(np.abs(ref.evaluate(t[inner])[0][:, 3] * 1e3 - si[inner])) < 1e-3
    tt = np.arange(26.0, 30.0, 0.01)
    a = ref.evaluate(tt)[2][:, 3] * 1e3
    a_breath = (2 * np.pi / 4) ** 2 * 6.0 + np.pi**2 * 1.5  # mm/s^2
    assert np.max(np.abs(a)) < a_breath + 5.8 * 2.0 / 2.0**2
    raw = load_trace(path, centre_on="none", seam_blend_s=0.0)
    assert raw.info.seam_words() == "a loop of 28 s: its 3 seams left as recorded"
    assert np.max(np.abs(raw.evaluate(tt)[2][:, 3] * 1e3)) > 2.5 * np.max(np.abs(a))
    long = load_trace(path, centre_on="none", seam_blend_s=40.0)  # blends that do not meet
    assert long.info.seam_words().startswith("a loop of 28 s: 3 seams blended over 14 s")
    # a synthetic periodic motion repeats exactly too, but is no loop
    short = _written(tmp_path, t[:150], np.tile(one[:20], 8)[:150], "periodic.csv")
    assert load_trace(short).info.seam_words() == "not a loop"


@pytest.mark.parametrize("loop_s", [217.6, 355.0, 202.4])
def test_a_long_loop_of_one_rounded_axis_is_found_at_its_own_seams(tmp_path, loop_s):
    """A 20-minute trace of one axis written to 0.1 mm, a recording of ``loop_s`` repeated: its
    rows equal earlier ones by chance all through it (a value comes back every breath), which
    are no seams; the loop is the recording, its seams where its end meets its start."""
    rate = 5.0
    t1 = np.arange(round(loop_s * rate)) / rate
    phase = 2 * np.pi * np.cumsum(1 / (4 + 0.5 * np.sin(t1 / 23))) / rate
    truth = (5 + np.sin(t1 / 31)) * np.sin(phase) + 1.5 * t1 / t1[-1]
    one = np.round(truth, 1)
    si = np.tile(one, 7)[: int(1200 * rate)]
    t = np.arange(si.size) / rate
    ref = load_trace(_written(tmp_path, t, si, "long_loop.csv"), centre_on="none")
    copies = int(1200 // loop_s)
    assert ref.info.loop_period_s == pytest.approx(loop_s)
    assert ref.info.seams == copies
    assert ref.info.seam_words().startswith(f"a loop of {loop_s:g} s: {copies} seams blended")
    # The jump at a seam, said with its size: the step from the copy's end to its start less
    # the mean of the steps either side (each copy's seam alike).
    y0, y1, y2, y3 = one[-2], one[-1], one[0], one[1]
    jump = abs((y2 - y1) - 0.5 * ((y1 - y0) + (y3 - y2)))
    assert dict(ref.info.seam_jumps)["X"] * 1e3 == pytest.approx(jump, abs=1e-9)
    # Away from the seams, the reference is the recording without its rounding (0.05 mm at
    # most, 0.029 mm RMS), which the smoothing spline takes for noise: closer than the file in
    # RMS, and at most two rounding steps off it where a breath turns.
    seams = np.arange(1, copies + 1) * len(one) / rate - 0.1
    far = np.min(np.abs(t[:, None] - seams[None, :]), axis=1) > 1.1
    inner = far & (t > 1.0) & (t < t[-1] - 1.0)
    error = ref.evaluate(t[inner])[0][:, 3] * 1e3 - np.tile(truth, 7)[: si.size][inner]
    assert np.sqrt(np.mean(error**2)) < 0.029 and np.max(np.abs(error)) < 0.1


def test_a_file_that_repeats_inside_without_starting_again_is_no_loop(tmp_path):
    """A recording whose second half repeats a stretch from its middle (not its start) has
    rows equal to earlier ones for most of it, but never starts again: not a loop, nothing
    blended."""
    rate = 5.0
    t1 = np.arange(0.0, 300.0, 1 / rate)
    one = np.round(5 * np.sin(2 * np.pi * t1 / 4.3) + 2 * np.sin(t1 / 17), 1)
    si = np.concatenate([one, one[200:], one[200:]])
    t = np.arange(si.size) / rate
    ref = load_trace(_written(tmp_path, t, si, "inner_repeat.csv"), centre_on="none")
    assert ref.info.seam_words() == "not a loop"


def test_a_piece_fitpack_fails_on_is_refitted_and_stays_within_its_samples():
    # Clean 5 Hz samples of a breath after a 0.95 s dropout behind the first two: FITPACK
    # returns, for the piece of samples 1050-1250, "a theoretically impossible result" and a
    # curve 2.9e12 times the motion there (scipy 1.14-1.16). Each piece is held within its
    # samples' range widened by their span, and refitted when it is not.
    t = np.arange(1821) / 5.0
    t[2:] += 0.9521352266613923
    y = 1.6793701890884476 * np.sin(2 * np.pi * t / 5.541719692216681)
    y[:2] += 0.1512047059784977
    curve, departure = smoothed_spline(t, y)
    grid = np.linspace(t[0], t[-1], 100_000)
    values = curve(grid)
    assert values.max() <= y.max() + np.ptp(y) and values.min() >= y.min() - np.ptp(y)
    # ... and follows the breath: between the samples as the sine itself, to 0.1 % of it.
    inside = grid > t[2]
    truth = 1.6793701890884476 * np.sin(2 * np.pi * grid[inside] / 5.541719692216681)
    assert np.max(np.abs(values[inside] - truth)) < 2e-3 * 1.68
    assert departure < 1e-6
