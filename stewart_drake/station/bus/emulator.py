"""A DYNAMIXEL bus on a pseudo-terminal: X-series servos answering Protocol 2.0, a motion model
behind them stepping in real time.

:class:`BusEmulator` opens a pty (``os.openpty``, raw mode), gives its slave path
(``BusEmulator.port``) to the driver, which opens it through the vendor's ``PortHandler``
as it would ``/dev/ttyUSB0``, and answers in a thread: PING, READ, WRITE, SYNC_READ and
SYNC_WRITE (other instructions answer an Instruction Error), with the status packets, errors and
CRC of the protocol (:mod:`.protocol`). Each servo keeps its control table as bytes, with the
e-Manual's access rules that matter here and its bus watchdog.

The motion: a :class:`~.servo_models.ServoBackend` (:mod:`.servo_models`) stepped towards the
wall clock in a thread of its own every ``tick_s`` (or per torque command, ``command_step_s``);
the bus thread answers meanwhile from the last present values. What is emulated and what is not:
docs/hardware_bus.md, "What is emulated".
"""

from __future__ import annotations

import gc
import math
import os
import select
import termios
import threading
import time
import tty

import numpy as np

from ...base.errors import InvalidConfigError
from . import protocol as p
from .bus_timing import BusTiming
from .servo_firmware import FirmwareLoops
from .servo_models import FirstOrderServos, ServoBackend
from .servo_table import ServoTable
from .servos import DEFAULT_MODEL, servo_spec

#: The X series' control table size: addresses 0..146 (Present Temperature is the last used).
TABLE_SIZE = p.X_SERIES.size


class BusEmulator(FirmwareLoops):
    """Servos ``ids`` of model ``model`` on a pseudo-terminal, answering in a thread.

    Use as a context manager, or :meth:`start` and :meth:`close`. ``port`` is the path the
    driver opens. The backend's servo ``k`` is ``ids[k]``; positions are reported as
    ``zero_counts[k] + q_k * counts_per_rev / 2 pi`` (the horn's count at angle 0; the model's
    counts a turn, 4096 on the X series).

    Args:
        ids: servo ids (distinct, 0..252).  model: a
            :data:`~stewart_drake.station.bus.servos.SERVO_SPECS` key.
        backend: the motion; default
            :meth:`~.servo_models.FirstOrderServos.from_catalogue` at rest at 0.
        zero_counts: (n,) counts at the backend's angle 0; default the model's mid-range (2048
            on the X series, 0 on the P series).
        tick_s: the model is stepped at least this often, s.  ambient_C: Present Temperature.
        max_step_s: the longest step of the model in one advance, s: a model (or a starved
            thread) slower than real time drops the rest (``slipped_s``) instead of
            answering later and later.
        models: {id: model} of the servos of another model than ``model`` (a surrogate's
            stage beside the cranks, say); None: every servo is ``model``.
        command_step_s: None (default): the model follows the wall clock. A period, s: the
            model advances exactly this much at each SYNC_WRITE of Goal Current (the driver's
            torque command) and not otherwise, so its physics follow the commands, not the
            machine's speed: a loop that runs late on a loaded machine meets the plant where
            its own clock says it is. The bus watchdog still counts wall time. For tests and
            rehearsals of a loop whose period is ``command_step_s``; a real bus has no such
            mode.
        catch_up: with ``command_step_s``, each command first carries the model the period
            up to its own instant under the commands before it, then acts (the first command
            carries it nowhere): a read after a command finds the robot where it is when the
            command arrives, as on a wall clock. False (default): the model advances the period
            under the command just written.
        timing: None (default): packets at the pseudo-terminal's memory speed. A
            :class:`~.bus_timing.BusTiming`: each instruction acts after its bytes' time on the
            wire, each reply comes after each answering servo's Return Delay Time (its control
            table's), its bytes' time and the USB adapter's latency timer, with jitter, and a
            share of the status packets corrupt or lost.
        return_delay_us: the Return Delay Time every servo's table starts with, us (the
            factory's is 500; the driver may write its own).

    A servo in Position Control Mode (operating mode 3, the torque on) runs its own position
    loop (:class:`~.servo_firmware.PositionFirmware`, from its table's Position Gains, Goal
    Position and Profile Velocity) every :attr:`FIRMWARE_PERIOD_S` of the model, on its own
    reading, its PWM driving the backend's winding (:meth:`~.servo_models.ServoBackend.
    pwm_currents`); it starts from where it is when its torque goes on, towards its Goal
    Position. Goals written while the model steps act from its next step.

    Raises:
        InvalidConfigError: bad ids or model, a backend of another size.
    """

    def __init__(
        self,
        ids,
        model: str = DEFAULT_MODEL,
        backend: ServoBackend | None = None,
        zero_counts=None,
        tick_s: float = 0.002,
        ambient_C: float = 30.0,
        max_step_s: float = 0.02,
        command_step_s: float | None = None,
        models: dict | None = None,
        timing: BusTiming | None = None,
        return_delay_us: float = 0.0,
        catch_up: bool = False,
    ):
        ids = [int(i) for i in ids]
        if command_step_s is not None and not (0 < command_step_s < math.inf):
            raise InvalidConfigError(
                f"command_step_s = {command_step_s!r} must be a positive period in s, or None"
            )
        if not ids or len(set(ids)) != len(ids) or not all(0 <= i <= p.MAX_ID for i in ids):
            raise InvalidConfigError(f"ids {ids} must be distinct integers in 0..{p.MAX_ID}")
        spec = servo_spec(model, torque_control=False)
        self.ids = ids
        self.backend = backend or FirstOrderServos.from_catalogue(model, np.zeros(len(ids)))
        if len(self.backend.positions_rad()) != len(ids):
            raise InvalidConfigError(
                f"the backend moves {len(self.backend.positions_rad())} servos, not {len(ids)}"
            )
        self.zero_counts = (
            np.full(len(ids), spec.zero_count) if zero_counts is None else np.asarray(zero_counts)
        )
        specs = {int(i): servo_spec(m, torque_control=False) for i, m in (models or {}).items()}
        self.servos = {
            i: ServoTable(i, specs.get(i, spec), ambient_C, return_delay_us) for i in ids
        }
        self.timing = timing
        self.tick_s = float(tick_s)
        self.max_step_s = float(max_step_s)
        self.command_step_s = None if command_step_s is None else float(command_step_s)
        self.catch_up = bool(catch_up)
        #: With ``catch_up``: the model's step under way (set when done), what it asks for
        #: (currents, commands, its event) and the present values it left.
        self._stepping: threading.Event | None = None
        self._step_request: tuple | None = None
        self._stepped: list = []
        self._wake = threading.Event()  # the model thread's: a step is asked for
        #: Wall-clock time the model did not follow, s: the sum of the excess of every gap
        #: between two advances over ``max_step_s`` (0 while the model keeps real time).
        self.slipped_s = 0.0
        #: Every instruction packet received, (perf_counter time, Packet), newest last (bounded).
        self.received: list[tuple[float, p.Packet]] = []
        self.muted = False
        #: What stopped the model, one line (None while it runs).
        self.model_error: str | None = None
        #: Ids that neither answer nor execute (:meth:`disconnect`).
        self.disconnected: set[int] = set()
        self._lock = threading.Lock()  # the control tables
        self._model_lock = threading.Lock()  # the backend
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._model_thread: threading.Thread | None = None
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave, termios.TCSANOW)
        tty.setraw(self._master, termios.TCSANOW)
        # Never block the thread on a port nobody reads: a reply that does not fit is dropped.
        os.set_blocking(self._master, False)
        self.dropped_bytes = 0
        self.port = os.ttyname(self._slave)
        self._t = time.perf_counter()
        #: {servo index: (PositionFirmware, its command)} of the servos in Position Control Mode.
        self._firmware: dict[int, tuple] = {}
        self._pwm_currents: dict[int, float] = {}
        self._update_present()

    # --- lifetime ----------------------------------------------------------------------------

    def start(self) -> BusEmulator:
        """Start answering and moving (two daemon threads), the servos' firmware compiled (or
        loaded) first: not in the middle of a step. The caller's unreachable objects are
        collected here, on its own thread: otherwise the bus thread's next allocation may
        destroy them (a Drake diagram built and dropped before) in the middle of a reply."""
        if self._thread is None:
            from .servo_firmware import warm_up

            warm_up()
            gc.collect()
            self._thread = threading.Thread(
                target=self._run, name="dynamixel-bus-emulator", daemon=True
            )
            self._model_thread = threading.Thread(
                target=self._run_model, name="dynamixel-bus-model", daemon=True
            )
            self._thread.start()
            self._model_thread.start()
        return self

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the threads (waits at most ``timeout_s`` each) and close the pty. Idempotent."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            if self._model_thread is not None:
                self._model_thread.join(timeout_s)
            self._thread = self._model_thread = None
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()

    # --- test hooks --------------------------------------------------------------------------

    def set_hardware_error(self, servo_id: int, bits: int) -> None:
        """Raise Hardware Error Status ``bits`` (:data:`~.protocol.HW_OVERHEATING`, ...) on a
        servo as its firmware would (e-Manual, "Hardware Error Status(70)"): Torque Enable is
        cleared, the output is zero, every status packet carries the Alert bit; only a REBOOT
        clears it (not emulated: make a new emulator)."""
        with self._lock:
            servo = self.servos[servo_id]
            t = servo.items
            servo.put(t.hardware_error_status, servo.get(t.hardware_error_status) | int(bits))
            servo.put(t.torque_enable, 0)

    def mute(self, muted: bool = True) -> None:
        """Stop (or resume) answering and executing: a cut cable. Packets are still logged in
        ``received``."""
        self.muted = bool(muted)

    def disconnect(self, servo_id: int, cut: bool = True) -> None:
        """Cut (or restore) one servo's cable: it neither answers nor executes; its control
        table keeps what it had (its torque stays as it was, until its bus watchdog trips)."""
        if cut:
            self.disconnected.add(int(servo_id))
        else:
            self.disconnected.discard(int(servo_id))

    def read_item(self, servo_id: int, item) -> int:
        """A servo's control-table value (unsigned), as the bus would read it."""
        with self._lock:
            return self.servos[servo_id].get(item)

    def applied_current_A(self) -> np.ndarray:
        """(n,) the currents the servos drive now, A (ids order)."""
        with self._lock:
            return np.array([self.servos[i].current_A() for i in self.ids])

    def with_backend(self, fn):
        """``fn(backend)``, called between two steps of the model: reading a model that the
        model thread steps (a Drake context) must not race it."""
        with self._model_lock:
            return fn(self.backend)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """The backend's (positions rad, velocities rad/s) (ids order)."""
        return self.with_backend(lambda b: (b.positions_rad(), b.velocities_rad_s()))

    # --- the thread --------------------------------------------------------------------------

    def _run(self) -> None:
        buf = bytearray()
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], self.tick_s)
                if ready:
                    buf += os.read(self._master, 4096)
            except OSError:
                if self._stop.is_set():
                    return
                time.sleep(self.tick_s)  # the driver closed its end: wait for it to reopen
                continue
            clock = time.perf_counter()  # when the bytes were there
            while True:
                with self._lock:
                    packet, used, crc_ok = p.parse_packet(buf)
                    del buf[:used]
                    if packet is None:
                        break
                    self._log(packet)
                if self.muted:
                    continue
                # With a timing: a write acts once its bytes are on the wire; a read is
                # answered from the values of when it arrived, its reply held until its bytes,
                # the servos' return delays and the adapter's timer are through. One sleep a
                # packet: each wake-up waits for the model thread's turn at the GIL.
                instruction_s = 0.0 if self.timing is None else self.timing.instruction_s(used)
                reads = packet.instruction in (p.READ, p.SYNC_READ, p.PING)
                if instruction_s and not reads:
                    clock = _sleep_until(clock + instruction_s)
                with self._lock:
                    reply = self._answer(packet, crc_ok)
                    late_s = 0.0
                    if reply and self.timing is not None:
                        reply, late_s = self._timed(reply)
                if reads and (instruction_s or late_s):
                    clock = _sleep_until(clock + instruction_s + late_s)
                if reply:
                    try:
                        os.write(self._master, reply)
                    except BlockingIOError:
                        self.dropped_bytes += len(reply)  # nobody reads the port

    def _timed(self, reply: bytes) -> tuple[bytes, float]:
        """``reply`` (status packets, concatenated) as the bus delivers it, and when: each
        status after its servo's Return Delay Time and its bytes, a lost one ending the reply
        (the servos after it wait for it), a corrupt one with a byte changed; the delay after
        the instruction, s (:meth:`~.bus_timing.BusTiming.reply_s`)."""
        timing = self.timing
        assert timing is not None
        out, statuses, k = bytearray(), [], 0
        while k + 7 <= len(reply):
            n = 7 + int.from_bytes(reply[k + 5 : k + 7], "little")
            status = bytearray(reply[k : k + n])
            servo = self.servos.get(status[4])
            fate = timing.fate()
            if fate == "lost":
                break
            if fate == "corrupt":
                status[-3] ^= 0x5A  # a byte before the CRC: the CRC no longer holds
            out += status
            statuses.append((n, servo.return_delay_s() if servo is not None else 0.0))
            k += n
        return bytes(out), timing.reply_s(statuses)

    def _log(self, packet: p.Packet) -> None:
        self.received.append((time.perf_counter(), packet))
        if len(self.received) > 10000:
            del self.received[:5000]

    def _run_model(self) -> None:
        """Step the model until stopped; a model that raises goes silent with the bus (its
        servos stop answering: the driver's next read times out and it removes the torque),
        the error kept in ``model_error``."""
        try:
            while not self._stop.is_set():
                wait = self._step_model()
                if wait > 0:
                    self._wake.wait(wait)
                    self._wake.clear()
        except Exception as err:  # noqa: BLE001 - the servos fall silent, the error is kept
            self.model_error = f"{type(err).__name__}: {err}"
            self.muted = True

    def _step_model(self) -> float:
        """Step the backend towards now (at most ``max_step_s``; a servo's watchdog trip at
        the moment it runs out, not when the thread next looks) and refresh the present
        values. The table's lock is not held while the model steps: the bus answers meanwhile
        from the last present values. With ``command_step_s`` the commands move the model
        (:meth:`_step_commanded`) and this only trips the watchdogs. Returns how long the
        model may wait, s."""
        if self.command_step_s is not None:
            request, self._step_request = self._step_request, None
            if request is None:
                return self._trip_watchdogs()
            currents, commands, done = request
            with self._model_lock:
                self._advance(self.command_step_s, currents, commands)
                self._stepped = self._present()
            done.set()
            return 0.0
        with self._model_lock:
            with self._lock:
                now = time.perf_counter()
                if now - self._t > self.max_step_s:  # slower than real time: slip, boundedly
                    self.slipped_s += now - self._t - self.max_step_s
                    self._t = now - self.max_step_s
                t_trip = min((t for t, _ in self._armed()), default=math.inf)
                t_next = min(now, max(t_trip, self._t))
                currents, commands = self._commands()
            self._advance(t_next - self._t, currents, commands, self._t)
            with self._lock:
                self._t = t_next
                for t, servo in self._armed():  # re-read: an instruction may have come
                    if t <= t_next:
                        servo.put(servo.items.bus_watchdog, p.WATCHDOG_TRIPPED)
                self._update_present()
        if t_next < now:
            return 0.0
        return min(self.tick_s, max(0.0, t_trip - now))

    def _trip_watchdogs(self) -> float:
        """The commanded clock's model thread: trip every bus watchdog whose time is up (wall
        time, as a servo counts it). Returns how long it may wait, s. Never waits for the
        tables: a command catching up (``catch_up``) holds them until this thread has made its
        step, so the watchdogs are looked at again a tick later."""
        if not self._lock.acquire(blocking=False):
            return self.tick_s
        try:
            now = time.perf_counter()
            armed = self._armed()
            for t, servo in armed:
                if t <= now:
                    servo.put(servo.items.bus_watchdog, p.WATCHDOG_TRIPPED)
            t_trip = min((t for t, _ in armed if t > now), default=math.inf)
        finally:
            self._lock.release()
        return min(self.tick_s, max(0.0, t_trip - now))

    def _step_commanded(self) -> None:
        """The commanded clock: the model advances ``command_step_s`` under the commands just
        written, and the present values follow (called by the bus thread, the table's lock
        held: the next read waits for the step)."""
        step_s = float(self.command_step_s or 0.0)  # set: only the commanded clock calls this
        currents, commands = self._commands()
        with self._model_lock:
            self._advance(step_s, currents, commands)
            self._update_present()

    def _armed(self) -> list:
        """[(expiry time, servo)] of the servos whose bus watchdog is running."""
        return [
            (s.last_instruction + limit * p.WATCHDOG_UNIT_S, s)
            for s in self.servos.values()
            if s.get(s.items.torque_enable) and 0 < (limit := s.get(s.items.bus_watchdog)) <= 127
        ]

    def _update_present(self) -> None:
        self._put_present(self._present())

    def _present(self) -> list:
        """[(Present Position counts, Velocity units, Current units)] of each servo, from the
        backend now."""
        q, v = self.backend.positions_rad(), self.backend.velocities_rad_s()
        drives = getattr(self.backend, "currents_A", None)
        currents = drives() if drives is not None else None
        out = []
        for k, i in enumerate(self.ids):
            s = self.servos[i]
            spec = s.spec
            unit = spec.current_unit_A
            amps = s.current_A() if currents is None or k >= len(currents) else currents[k]
            if currents is None and k in self._pwm_currents:
                amps = self._pwm_currents[k]
            out.append(
                (
                    int(round(float(q[k]) / spec.rad_per_count + float(self.zero_counts[k]))),
                    round(float(v[k]) / spec.velocity_unit_rad_s),
                    round(amps / unit) if unit else 0,
                )
            )
        return out

    def _put_present(self, values: list) -> None:
        for (counts, velocity, current), i in zip(values, self.ids, strict=True):
            s = self.servos[i]
            t = s.items
            s.put(t.present_position, counts)
            s.put(t.present_velocity, velocity)
            s.put(t.present_current, current)

    def _catch_up(self) -> None:
        """Before a command is written (``catch_up``; the bus thread, the tables' lock held):
        wait for the model's step to this command's instant, begun at the command before, and
        put where it left the robot in the tables. Bounded: a model that does not finish in
        30 s (a loaded machine's stall is seconds) goes silent with the bus, as one that
        raises."""
        done = self._stepping
        if done is None:
            return  # the first command: its instant is where the model is
        if not done.wait(timeout=30.0):
            self.model_error = "the model did not finish its step to a command in time"
            self.muted = True
            return
        self._put_present(self._stepped)

    def _begin_step(self) -> None:
        """After a command is written (``catch_up``; the bus thread, the tables' lock held):
        the model thread carries the model a period to the next command's instant under the
        commands the tables now hold; the present values stay the command's instant's
        meanwhile."""
        currents, commands = self._commands()
        self._stepping = threading.Event()
        self._step_request = (currents, commands, self._stepping)
        self._wake.set()

    # --- the protocol ------------------------------------------------------------------------

    def _status(self, s: ServoTable, error: int, params: bytes = b"") -> bytes:
        alert = p.ALERT if s.get(s.items.hardware_error_status) else 0
        return p.build_status(s.id, error | alert, params)

    def _answer(self, packet: p.Packet, crc_ok: bool) -> bytes:
        """The status packets (concatenated) that ``packet`` calls for."""
        now = time.perf_counter()
        targets = list(self.servos) if packet.servo_id == p.BROADCAST_ID else [packet.servo_id]
        targets = [i for i in targets if i in self.servos and i not in self.disconnected]
        for i in targets:
            self.servos[i].last_instruction = now
        if not targets:
            return b""
        if not crc_ok:
            if packet.servo_id == p.BROADCAST_ID:
                return b""
            return self._status(self.servos[packet.servo_id], p.ERR_CRC)
        ins, par = packet.instruction, packet.params
        if ins == p.PING:
            return b"".join(
                self._status(
                    self.servos[i],
                    0,
                    p.to_unsigned(self.servos[i].get(p.MODEL_NUMBER), 2).to_bytes(2, "little")
                    + bytes([self.servos[i].get(p.FIRMWARE_VERSION)]),
                )
                for i in targets
            )
        if packet.servo_id == p.BROADCAST_ID and ins in (p.READ, p.WRITE):
            if ins == p.WRITE and len(par) > 2:
                for i in targets:
                    self.servos[i].write(int.from_bytes(par[:2], "little"), par[2:])
            return b""  # no status to a broadcast READ/WRITE (e-Manual, Status Return Level)
        if ins == p.READ:
            s = self.servos[targets[0]]
            if len(par) != 4:
                return self._status(s, p.ERR_DATA_LENGTH)
            address, size = int.from_bytes(par[:2], "little"), int.from_bytes(par[2:], "little")
            if address + size > s.items.size:
                return self._status(s, p.ERR_DATA_RANGE)
            return self._status(s, 0, bytes(s.table[address : address + size]))
        if ins == p.WRITE:
            s = self.servos[targets[0]]
            if len(par) < 3:
                return self._status(s, p.ERR_DATA_LENGTH)
            return self._status(s, s.write(int.from_bytes(par[:2], "little"), par[2:]))
        if ins == p.SYNC_WRITE:
            address, size = int.from_bytes(par[:2], "little"), int.from_bytes(par[2:4], "little")
            rows = par[4:]
            goals = {s.items.goal_current[0] for s in self.servos.values()}
            goals |= {s.items.profile_velocity[0] for s in self.servos.values()}
            goals |= {s.items.goal_position[0] for s in self.servos.values()}
            # the period's command addresses the cranks (the first servo); a surrogate's own
            # Goal Current beside their goals does not move the commanded clock
            addressed = {rows[k] for k in range(0, len(rows) - size, size + 1)}
            stepped = self.command_step_s is not None and address in goals
            stepped = stepped and self.ids[0] in addressed
            if stepped and self.catch_up:
                self._catch_up()
            for k in range(0, len(rows) - size, size + 1):
                if rows[k] in targets:
                    self.servos[rows[k]].write(address, rows[k + 1 : k + 1 + size])
            if stepped:
                self._begin_step() if self.catch_up else self._step_commanded()
            return b""
        if ins == p.SYNC_READ:
            address, size = int.from_bytes(par[:2], "little"), int.from_bytes(par[2:4], "little")
            out = b""
            for i in par[4:]:
                if i in targets:
                    s = self.servos[i]
                    if address + size > s.items.size:
                        out += self._status(s, p.ERR_DATA_RANGE)
                    else:
                        out += self._status(s, 0, bytes(s.table[address : address + size]))
            return out
        if packet.servo_id == p.BROADCAST_ID:
            return b""
        return self._status(self.servos[targets[0]], p.ERR_INSTRUCTION)


def _sleep_until(t: float) -> float:
    """Sleep until ``time.perf_counter()`` is ``t`` (at once if past); returns ``t``."""
    wait = t - time.perf_counter()
    if wait > 0:
        time.sleep(wait)
    return t


def main(argv=None) -> None:
    """``python -m stewart_drake.station.bus.emulator --ids 1 2 3 4 5 6``: a bus in
    its own process (no GIL shared with the driver). Prints the port path on the first line of
    stdout, then serves until its stdin closes (the parent's end of a pipe, or Ctrl-D) or
    SIGTERM/Ctrl-C."""
    import argparse
    import sys

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--ids", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    parser.add_argument("--model", default=DEFAULT_MODEL)
    args = parser.parse_args(argv)
    with BusEmulator(args.ids, args.model) as emulator:
        print(emulator.port, flush=True)
        try:
            while sys.stdin.read(1):
                pass
        except KeyboardInterrupt:
            pass


if __name__ == "__main__":
    main()
