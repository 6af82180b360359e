"""The robot following a motion live over LCM (live/follow.py): a breathing motion's samples
published at their rate, each 0.2 s after it happened, on ``DrakeLcm("memq://")`` (in process:
no network), followed by the robot on the bus emulator in this process, on the commanded clock
(:func:`conftest.bus_emulator`); and a source that falls silent, sends a sample out of order or
a NaN, or never sends, each ending the run with the torque off and one line.

Where a test judges how well the robot follows, or which sample a failure names, the motion runs
on the loop's clock, as the emulator's plant does (:class:`LoopClockSource`): on a loaded machine
the loop runs late and moves its schedule on after a missed deadline, and a motion on the wall
clock would run ahead of the loop's (at a load of 7, 6.5 s of 9 skipped: the breath played 1.6
times as fast, in the loop's time, as the one the robot was following), a change of the motion
that is the machine's, not the follower's. A live source's thread on the wall clock
(:class:`Source`) feeds the tests of the session itself (its real-time loop, its first sample).
The truth's clock is mapped onto the loop's by the arrivals the follower stamped (their
``utime`` plus the latency against when each was read): the median of those offsets.
"""

import threading
import time

import numpy as np
import pytest
from conftest import HANG_S, LOADED_MACHINE_BUS, bus_emulator, robot_bus_yaml

pytest.importorskip("dynamixel_sdk")

from pydrake.lcm import DrakeLcm  # noqa: E402

from stewart_drake.cli.main import main  # noqa: E402
from stewart_drake.lcmtypes import lcmt_stewart_pose_sample  # noqa: E402
from stewart_drake.live import follow  # noqa: E402
from stewart_drake.live.follow import follow_on_robot  # noqa: E402
from stewart_drake.references.organ.library import make_motion  # noqa: E402
from stewart_drake.references.prediction import PredictorSettings  # noqa: E402
from stewart_drake.robot.kinematics import X_HOME  # noqa: E402
from stewart_drake.run.result import load_result  # noqa: E402
from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario  # noqa: E402
from stewart_drake.station.bus import protocol as p  # noqa: E402
from stewart_drake.station.bus.servos import DynamixelBusConfig  # noqa: E402

IDS = [1, 2, 3, 4, 5, 6]
X_REST = X_HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, -0.01])  # 10 mm below home
LATENCY_S, RATE_HZ, CHANNEL = 0.2, 25.0, "BREATH"
#: The library's breathing: 15 mm on X (SI), 4 s.
MOTION = make_motion("breathing", {})
#: The predictor may be used after 2 s of record (5 s shipped): a short run reaches it.
SETTINGS = PredictorSettings(min_record_s=2.0)


def _sample(j: int, spoil=None) -> bytes | None:
    """MOTION's sample j, taken at j / RATE_HZ s, as the source sends it; ``spoil(j, message)``
    may change the message (or return bytes, or None: nothing more is sent)."""
    t = j / RATE_HZ
    message = lcmt_stewart_pose_sample()
    message.utime, message.seq = int(round(t * 1e6)), j
    message.pose = [float(v) for v in np.asarray(MOTION.evaluate(t)[0]).reshape(6)]
    if spoil is not None:
        message = spoil(j, message)
        if message is None:
            return None
    return message if isinstance(message, bytes) else message.encode()


class Source:
    """Publishes MOTION's samples on ``lcm`` from a thread, on the wall clock: sample j (taken
    at j / RATE_HZ s after the start) LATENCY_S after it was taken (``spoil``: as
    :func:`_sample`'s). A live source's thread; :class:`LoopClockSource` where a test's figures
    or messages must not depend on the machine's load."""

    def __init__(self, lcm, spoil=None):
        self.lcm, self.spoil = lcm, spoil
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(HANG_S)

    def _run(self):
        start = time.perf_counter()
        j = 0
        while not self.stop.is_set():
            self.stop.wait(max(0.0, start + j / RATE_HZ + LATENCY_S - time.perf_counter()))
            data = _sample(j, self.spoil)
            if data is None:
                return
            self.lcm.Publish(CHANNEL, data)
            j += 1


class LoopClockSource:
    """MOTION's samples published on ``lcm`` on the loop's own clock: sample j (taken at
    j / RATE_HZ s) when the loop's time reaches j / RATE_HZ, from the loop's thread as it reads
    the bus (:meth:`install`, a ``before_torque`` hook); sample 0 as the session starts to wait
    for one (``monkeypatch``: LCM delivers to the subscriptions made before a message only). In
    the loop's time each arrives LATENCY_S after it happened (the truth at the loop's time t is
    the motion at t + LATENCY_S), however late the loop runs on the wall clock. ``spoil``: as
    :func:`_sample`'s."""

    def __init__(self, lcm, monkeypatch, spoil=None):
        self.lcm, self.spoil, self.sent, self.stopped = lcm, spoil, 0, False
        wait = follow.LcmPoseSource.wait

        def first_then_wait(source, timeout_s):
            self._publish_until(0.0)
            return wait(source, timeout_s)

        monkeypatch.setattr(follow.LcmPoseSource, "wait", first_then_wait)

    def _publish_until(self, t: float) -> None:
        while not self.stopped and self.sent / RATE_HZ <= t + 1e-9:
            data = _sample(self.sent, self.spoil)
            if data is None:  # the source falls silent
                self.stopped = True
                return
            self.lcm.Publish(CHANNEL, data)
            self.sent += 1

    def install(self, sd, simulator) -> None:
        """Publish, at every read of the bus, the samples due by the loop's time."""
        bus = sd.station.bus
        read = bus.read_state

        def read_and_publish():
            self._publish_until(simulator.get_context().get_time())
            return read()

        bus.read_state = read_and_publish


def _scenario(emu):
    scenario = load_scenario(ROBOT_SCENARIO)
    scenario.bus = DynamixelBusConfig(**(LOADED_MACHINE_BUS | {"port": emu.port}))
    return scenario


def _follow(emu, tmp_path, lcm, source=None, **kw):
    """(run, lines said, the FollowReference) of a session on ``emu`` listening on ``lcm``
    (``source``: a :class:`LoopClockSource` to install in the loop)."""
    lines, kept = [], []
    kw = {"loop_timeout_s": 5.0, "out": tmp_path, "say": lines.append, "settings": SETTINGS} | kw

    def before_torque(sd, simulator, reference):
        kept.append(reference)
        if source is not None:
            source.install(sd, simulator)

    run = follow_on_robot(
        _scenario(emu), lcm, CHANNEL, LATENCY_S, rate_hz=RATE_HZ, before_torque=before_torque, **kw
    )
    return run, lines, kept[0] if kept else None


def _torque_enables(emu):
    return [
        packet.servo_id
        for _, packet in emu.received
        if packet.instruction == p.WRITE
        and packet.params[:1] == bytes([p.TORQUE_ENABLE[0]])
        and packet.params[2:3] == b"\x01"
    ]


def test_the_robot_follows_breathing_published_live_with_the_latency_predicted_away(
    tmp_path, monkeypatch
):
    """12 s of the library's breathing (15 mm, 4 s) arriving 0.2 s late at 25 Hz, on the loop's
    clock (:class:`LoopClockSource`). From 9 s on (the predictor may be chosen once it has 2 s
    of history and 5 s of record, about 7.4 s, and is moved onto over 1 s), the
    reference the robot was given is within 0.3 mm RMS of the true motion and the robot's
    measured pose within 1.5 mm (the shipped bus scenario's LQI at 10 ms tracks its reference
    to about 0.6-0.9 mm), under 0.6 of what following the newest sample exactly would be off
    (2.2 mm). On the loop's clock, with the plant on the commanded clock, these figures are
    the same however loaded the machine. The torque is off at the end, the logs kept, and the
    summary says what was received and predicted."""
    lcm = DrakeLcm("memq://")
    with bus_emulator(X_REST, 0.01) as emu:
        source = LoopClockSource(lcm, monkeypatch)
        run, lines, reference = _follow(emu, tmp_path, lcm, source, duration_s=12.0)
        torque = [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]
    assert run.ok and run.exit_code == 0 and run.torque_off_confirmed, run.reason
    assert torque == [0] * 6 and run.reason == "followed BREATH for 12 s"
    assert run.encoder_log == tmp_path / "robot_follow_encoders.csv" and run.timing_lines
    assert lines[0].startswith("torque on: following BREATH (0.2 s late, predictor linear)")
    assert lines[-1].startswith("followed BREATH: ") and "admissible throughout" in lines[-1]
    log = np.array(reference.source.log)  # (arrival s, seq, utime us)
    assert np.all(np.diff(log[:, 1]) == 1) and reference.follower.filled == 0
    read = log[:, 0] > 0.5  # not the samples queued before the start, read at t = 0
    result = load_result(run.logs)
    t = np.asarray(result.t, dtype=float)
    on = t > 9.0
    t = t[on]
    truth = np.asarray(MOTION.evaluate(t - _offsets(log[read], t))[0])[:, 3:]
    newest = np.searchsorted(log[:, 0], t, side="right") - 1  # the newest sample read by t
    held = np.asarray(MOTION.evaluate(log[newest, 2] * 1e-6)[0])[:, 3:]

    def rms(x):
        return float(np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))))

    robot = rms(np.asarray(result.x[on, 3:6], dtype=float))
    given = rms(np.asarray(result.x_d[on, 3:6], dtype=float))
    loop = run.timing_lines[0]  # the loop's periods and misses: not the figures' cause here
    assert t[-1] > 11.9 and rms(truth.mean(axis=0)) > 4e-3  # it breathes
    assert given < 0.3e-3, f"its reference {given * 1e3:.3f} mm RMS from the true motion; {loop}"
    assert robot < 1.5e-3, f"the robot {robot * 1e3:.3f} mm RMS from the true motion; {loop}"
    assert robot < 0.6 * rms(held), (robot, rms(held), loop)


def _offsets(log, t) -> np.ndarray:
    """(N,) the loop's clock minus the truth's at times ``t`` (s): the median over the samples
    read within 1 s of each of (when read - when taken - the latency); constant but for the
    period a sample waits to be read, on the loop's clock."""
    offset = log[:, 0] - log[:, 2] * 1e-6 - LATENCY_S
    return np.array([np.median(offset[np.abs(log[:, 0] - ti) <= 1.0]) for ti in t])


def _out_of_order(j, message):
    if j == 30:
        message.seq = 27
    return message


def _nan(j, message):
    if j == 30:
        message.pose = [0.0, 0.0, 0.0, float("nan"), 0.0, 0.3]
    return message


def _silent(j, message):
    return message if j < 30 else None


def _cut(j, message):
    """Sample 30 cut to 40 bytes, its fingerprint intact."""
    return message.encode()[:40] if j == 30 else message


@pytest.mark.parametrize(
    "spoil, said",
    [
        (_silent, r"BREATH: no sample for 0\.5\d* s after sample 29 \(the timeout is 0\.5 s\)"),
        (
            _out_of_order,
            r"BREATH: sample 27 \(utime 1200000\) after sample 29 .*: out of order or repeated",
        ),
        (_nan, r"BREATH: sample 30 is not 6 finite numbers: \[0, 0, 0, nan, 0, 0\.3\]"),
        (_cut, r"BREATH: a message that is not an lcmt_stewart_pose_sample \(40 bytes\)"),
    ],
    ids=["silent", "out-of-order", "nan", "cut"],
)
def test_a_source_that_fails_ends_the_run_with_the_torque_off_in_one_line(
    tmp_path, monkeypatch, spoil, said
):
    """Each failure at sample 30, on the loop's clock (:class:`LoopClockSource`): on the wall
    clock, a thread a loaded machine starved for half a second was a silence of its own, at
    another sample than the one under test."""
    import re

    lcm = DrakeLcm("memq://")
    with bus_emulator(X_REST, 0.01) as emu:
        source = LoopClockSource(lcm, monkeypatch, spoil)
        run, lines, _ = _follow(emu, tmp_path, lcm, source, duration_s=30.0)
        torque = [emu.read_item(i, p.TORQUE_ENABLE) for i in IDS]
        enabled = _torque_enables(emu)
    assert not run.ok and run.exit_code == 1 and run.torque_off_confirmed
    assert enabled and torque == [0] * 6  # it ran, and the torque is off
    assert re.fullmatch(f"LiveSourceError: {said}", run.reason), run.reason
    assert "\n" not in run.reason and run.logs is not None


def test_following_asks_for_a_realtime_loop_as_a_session_does(tmp_path, monkeypatch):
    """``realtime=True`` (the command's default): the loop asks what ``run_on_robot``'s does;
    where the OS refuses (simulated, as without the privilege), one line before the torque
    comes on, the run goes on, and the timing says what the loop was given."""
    from stewart_drake.live import realtime

    def refused(*args):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(realtime.os, "sched_setscheduler", refused)
    monkeypatch.setattr(realtime, "_memory_lock_refusal", lambda: "the memory lock limit is 8 kB")
    lcm = DrakeLcm("memq://")
    with bus_emulator(X_REST, 0.01) as emu, Source(lcm):
        run, lines, _ = _follow(emu, tmp_path, lcm, duration_s=1.0, realtime=True)
    assert run.ok and run.exit_code == 0 and run.torque_off_confirmed, run.reason
    said = [k for k, line in enumerate(lines) if line.startswith("realtime")]
    on = next(k for k, line in enumerate(lines) if line.startswith("torque on"))
    assert len(said) == 1 and said[0] < on and "not granted: SCHED_FIFO" in lines[said[0]]
    assert run.timing_lines[0].startswith("realtime: the normal policy (SCHED_OTHER), pinned")


def test_a_source_that_never_sends_powers_nothing(tmp_path):
    with bus_emulator(X_REST, 0.01) as emu:
        run, lines, reference = _follow(emu, tmp_path, DrakeLcm("memq://"), first_sample_s=0.3)
        enabled = _torque_enables(emu)
    assert reference is None and lines == [] and enabled == []
    assert run.reason == "LiveSourceError: BREATH: no sample within 0.3 s; nothing was powered"
    assert not run.ok and run.exit_code == 1 and run.torque_off_confirmed


def _robot(tmp_path, *args):
    return main(["robot", *args, "--scenario", str(robot_bus_yaml(tmp_path)), "--no-progress",
                 "--out", str(tmp_path / "out")])  # fmt: skip


def test_the_command_follows_a_channel_and_says_when_nothing_comes(tmp_path, capsys, monkeypatch):
    """Through ``main``: ``robot --follow-lcm`` on the emulated bus, listening on memq:// where
    nothing is published: one end line, exit 1, nothing powered."""
    monkeypatch.setattr(follow, "FIRST_SAMPLE_S", 0.3)
    with bus_emulator(X_REST, 0.01) as emu:
        code = _robot(tmp_path, "--follow-lcm", CHANNEL, "--latency", "0.2", "--lcm-url",
                      "memq://", "--port", emu.port, "--duration", "5")  # fmt: skip
        enabled = _torque_enables(emu)
    out, err = capsys.readouterr()
    assert code == 1 and enabled == [], (out, err)
    assert err.strip().splitlines()[-1] == (
        "stewart-drake robot: LiveSourceError: BREATH: no sample within 0.3 s; nothing was "
        "powered; torque off (confirmed by every servo)"
    )


@pytest.mark.parametrize(
    "args, said",
    [
        (["--latency", "0.2"], "--latency: for --follow-lcm CHANNEL, give one"),
        (["--follow-lcm", "B"], "--follow-lcm needs --latency S"),
        (["--follow-lcm", "B", "--latency", "0"], "latency must be in (0, 10] s"),
        (["--follow-lcm", "B", "--latency", "nan"], "latency must be in (0, 10] s"),
        (["--follow-lcm", "B", "--latency", "0.2", "--follow-rate", "0"], "--follow-rate must"),
        (["--follow-lcm", "B", "--latency", "0.2", "--lcm-url", "file:///tmp/x"], "--lcm-url"),
        (["--follow-lcm", "B" * 64, "--latency", "0.2"], "a channel is 1 to 63 printable"),
        (["breathing", "--follow-lcm", "B", "--latency", "0.2"], "it takes no reference (MOTION)"),
        (["--follow-lcm", "B", "--latency", "0.2", "--dry-run"], "it takes no --dry-run"),
    ],
    ids=["latency-alone", "no-latency", "zero", "nan", "rate", "file-url", "long", "motion", "dry"],
)
def test_bad_follow_options_are_refused_in_one_line_before_the_bus(tmp_path, capsys, args, said):
    assert _robot(tmp_path, *args, "--port", "/dev/null-no-such-port") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0], err
    assert not (tmp_path / "out").exists()


def test_the_parsers_constants_are_the_librarys():
    """The command's parser is built without numpy: its follow constants are written out."""
    from stewart_drake.live import follow_command
    from stewart_drake.references import prediction, stream

    assert follow_command.PREDICTORS == prediction.PREDICTORS
    assert follow_command.DEFAULT_PREDICTOR == prediction.DEFAULT_PREDICTOR
    assert follow_command.DEFAULT_RATE_HZ == stream.DEFAULT_STREAM_RATE_HZ
