"""The servos of the robot through the vendor's library: ``dynamixel_sdk`` (extra ``robot``).

:class:`DynamixelBus` opens the port, pings every id, configures the servos with the torque off
(Current Control Mode, current, temperature and position limits, the bus watchdog), reads the
configuration back, then each control period reads the state with one sync read (Present
Current, Velocity and Position: addresses 126..135) and writes the torques with one sync write
of Goal Current. Those two packets are the vendor's GroupSyncRead and GroupSyncWrite byte for
byte, but built once into preallocated buffers and parsed by compiled code
(:mod:`.kernels`) on the port's file descriptor: the vendor's Python builds and parses every
packet a list at a time, a third of a millisecond of the loop's CPU a period.
:meth:`DynamixelBus.torque_off` is safe to call at any time and is called on close, on
``__exit__`` and before a :class:`~stewart_drake.base.errors.BusError` is raised. Addresses,
units and conversions: :mod:`.protocol`; the models and the settings' check: :mod:`.servos`; the
vendor's module and its port: :mod:`.vendor_port`;
docs/hardware_bus.md.
"""

from __future__ import annotations

import collections
import os
import select
import termios
import threading
import time

import numpy as np

from ...base.checks import check_int
from ...base.errors import (
    BusError,
    InvalidConfigError,
    MissingServoError,
    ServoConfigMismatchError,
)
from ..surrogate.bus_servo import surrogate_settings
from . import protocol as p
from .position_mode import PositionMode, checked_gains
from .protocol import BusState
from .servos import (
    DEFAULT_MODEL,
    DEFAULT_TEMPERATURE_LIMIT_C,
    DEFAULT_WATCHDOG_S,
    DynamixelBusConfig,
    SurrogateServoConfig,
    check_bus_settings,
)
from .vendor_port import dynamixel_sdk, port_handler


class DynamixelBus(PositionMode):
    """Servos ``ids`` of one model on one port, torque-controlled.

    Args:
        port: serial port path ("/dev/ttyUSB0", or a :class:`~.emulator.BusEmulator`'s port).
        baud_rate: bps, one of :data:`~.servos.BAUD_RATES` (the servos' setting; not changed here).
        ids: (n,) servo ids, in the order of the cranks.
        model: a :data:`~.servos.SERVO_SPECS` key with Current Control Mode.
        zero_counts: (n,) Present Position at each crank's zero angle, counts; default 2048.
        directions: (n,) +1, or -1 for a servo whose counts grow against the crank's angle.
        current_limit_A: the servos' Current Limit, A (<= the model's maximum); default the
            model's maximum. Torques are clipped to it before they are sent.
        temperature_limit_C: the servos' Temperature Limit, deg C (<= 80, the e-Manual's
            operating maximum).
        position_limits_counts: (min, max) counts written to Min/Max Position Limit (the
            servo applies them in Position Control Mode only; docs/hardware_bus.md); default
            the model's whole range.
        watchdog_s: the servos' bus watchdog, s: a multiple of 20 ms in 0.02..2.54.
        reply_timeout_s: the least wait for a status packet, s; None: the SDK's (about 34 ms,
            for a USB adapter's 16 ms latency timer).
        position_gains_raw: the servos' own position loop (Position Control Mode) with these
            control-table (Position D, I, P, Feedforward 1st) Gains
            (:func:`~.servo_firmware.raw_position_gains`), its goals streamed by
            :meth:`write_goals`; None (default): Current Control Mode, torques by
            :meth:`write_torques`.
        read_retries: how many times a period's sync read is sent again after a corrupt
            status packet (the servos answered, a byte was hit: a bus's noise), counted in
            ``reads_retried``; a read whose retries fail too is a BusError, and so is a
            missing reply at once (a silent bus, its wait already past the period, is not
            waited out again while the servos hold their last command).
        timing_window: how many round trips :meth:`timing` keeps.
        surrogate: the external surrogate's servo (:class:`~.servos.SurrogateServoConfig`,
            checked), a seventh row of every sync read and sync write, configured, powered and
            unpowered with the cranks; None: the cranks alone.

    Raises:
        InvalidConfigError: any argument out of range, before the port is opened.
        MissingExtraError: dynamixel-sdk is not installed.
    """

    def __init__(
        self,
        port: str,
        baud_rate: int,
        ids,
        model: str = DEFAULT_MODEL,
        zero_counts=None,
        directions=None,
        current_limit_A: float | None = None,
        temperature_limit_C: int = DEFAULT_TEMPERATURE_LIMIT_C,
        position_limits_counts: tuple[int, int] | list[int] | None = None,
        watchdog_s: float = DEFAULT_WATCHDOG_S,
        reply_timeout_s: float | None = None,
        timing_window: int = 100_000,
        surrogate: SurrogateServoConfig | None = None,
        read_retries: int = 1,
        position_gains_raw: tuple[int, int, int, int] | None = None,
    ):
        settings = check_bus_settings(
            baud_rate,
            ids,
            model,
            zero_counts,
            directions,
            current_limit_A,
            temperature_limit_C,
            position_limits_counts,
            watchdog_s,
            reply_timeout_s,
        )
        self.spec = settings.spec
        #: rad a count, rad/s a velocity unit, K_t N m/A, A a current unit: once, not a period.
        self._units_per_count = (
            self.spec.rad_per_count,
            self.spec.velocity_unit_rad_s,
            self.spec.torque_constant_Nm_per_A,
            self.spec.amps_per_unit,
        )
        #: The cranks' control table (the surrogate's servo must keep its items there too).
        self.table = table = self.spec.table
        ids, zero, sign = settings.ids, settings.zero_counts, settings.directions
        limit_units, watchdog_units = settings.current_limit_units, settings.watchdog_units
        lo, hi = settings.position_limits_counts
        self.reply_timeout_s = reply_timeout_s
        self.read_retries = check_int("read_retries", read_retries, 0, 10)
        #: Sync reads sent again after a corrupt reply, {cause: count}.
        self.reads_retried: dict[str, int] = {}
        self.port_name, self.baud_rate, self.ids = str(port), int(baud_rate), ids
        self.zero_counts, self.directions = zero, sign
        self.current_limit_units = int(limit_units)
        self.settings = {  # written in this order with the torque off, then read back
            # Each servo answers at once (the factory's 500 us, six times in a sync read, would
            # be 3 ms of every period).
            "Return Delay Time": (p.RETURN_DELAY_TIME, 0),
            "Operating Mode": (table.operating_mode, p.CURRENT_CONTROL_MODE),
            "Current Limit": (table.current_limit, self.current_limit_units),
            "Temperature Limit": (table.temperature_limit, int(temperature_limit_C)),
            "Min Position Limit": (table.min_position_limit, lo),
            "Max Position Limit": (table.max_position_limit, hi),
            "Bus Watchdog": (table.bus_watchdog, watchdog_units),
        }
        #: The servos' own position loop's raw gains, or None (Current Control Mode).
        self.position_gains_raw = checked_gains(position_gains_raw, self.spec, surrogate)
        if self.position_gains_raw is not None:
            self._position_settings()
        #: The surrogate's servo (None: none), its model and its settings: the cranks', with
        #: its own Current Limit.
        self.surrogate = surrogate
        self._every_servo(ids, surrogate)
        self.read_times: collections.deque = collections.deque(maxlen=timing_window)
        self.write_times: collections.deque = collections.deque(maxlen=timing_window)
        #: Whether the last :meth:`torque_off` was confirmed by every servo.
        self.torque_off_confirmed = True
        #: Held around every transfer: a watchdog thread's :meth:`torque_off` waits for the
        #: transfer in progress (bounded by the reply timeout) instead of interleaving with it.
        self.lock = threading.RLock()
        self._sdk = dynamixel_sdk()
        self._port = None
        self._packets = self._sdk.PacketHandler(2.0)

    def _every_servo(self, ids, surrogate: SurrogateServoConfig | None) -> None:
        """Every servo on the bus (``all_ids``: the cranks' ids, then the surrogate's), each
        one's model and settings: the cranks', and the surrogate's own Current Limit."""
        self.all_ids = list(ids)
        self._specs = {i: self.spec for i in ids}
        self._settings_of = {i: self.settings for i in ids}
        if surrogate is not None:
            s_spec, units, s_settings = surrogate_settings(surrogate, self.spec, ids, self.settings)
            self.surrogate_spec, self.surrogate_limit_units = s_spec, units
            self.all_ids.append(int(surrogate.id))
            self._specs[int(surrogate.id)] = s_spec
            self._settings_of[int(surrogate.id)] = s_settings

    @classmethod
    def from_config(
        cls, config: DynamixelBusConfig, position_gains_raw: tuple | None = None
    ) -> DynamixelBus:
        """The bus of a scenario's ``bus`` section (:class:`~.servos.DynamixelBusConfig`, same
        names and units), not opened (``open``, ``configure``, ``enable_torque`` are the
        caller's); in Position Control Mode with ``position_gains_raw`` (its
        ``position_loop``'s, :meth:`~.position_mode.ServoPositionLoop.raw_gains` on the robot).

        Raises:
            InvalidConfigError: a setting out of range. MissingExtraError: dynamixel-sdk is not
                installed.
        """
        return cls(
            config.port,
            config.baud_rate,
            config.ids,
            model=config.model,
            zero_counts=config.zero_counts,
            directions=config.directions,
            current_limit_A=config.current_limit_A,
            temperature_limit_C=config.temperature_limit_C,
            position_limits_counts=config.position_limits_counts,
            watchdog_s=config.watchdog_s,
            reply_timeout_s=config.reply_timeout_s,
            surrogate=config.surrogate,
            read_retries=config.read_retries,
            position_gains_raw=position_gains_raw,
        )

    # --- lifetime ----------------------------------------------------------------------------

    def open(self) -> DynamixelBus:
        """Open the port and ping every id (checks the model number).

        Raises:
            BusError: the port does not open; a servo of another model.
            MissingServoError: an id that does not answer.
        """
        port = port_handler(self._sdk, self.port_name, self.reply_timeout_s)
        try:
            opened = port.openPort() and port.setBaudRate(self.baud_rate)
        except Exception as e:  # pyserial's SerialException, OSError, ...
            raise BusError(f"cannot open {self.port_name}: {e}") from None
        if not opened:
            raise BusError(f"cannot open {self.port_name} at {self.baud_rate} bps")
        self._port = port
        for i in self.all_ids:
            model, result, error = self._packets.ping(port, i)
            if result != self._sdk.COMM_SUCCESS:
                self.close()
                raise MissingServoError(i, self.port_name)
            spec = self._specs[i]
            if model != spec.model_number:
                self.close()
                raise BusError(
                    f"servo id {i} on {self.port_name} is model number {model}, not "
                    f"{spec.name} ({spec.model_number}): name the servos' model"
                )
        self._period_packets(port)
        return self

    def _period_packets(self, port) -> None:
        """The sync read's request and the sync write (its data filled each period), the
        buffers a reply is read and parsed into, and the reply's timeout: the vendor's packet
        timeout for the reply's length (2 x the USB latency timer + 2 ms + the transfer), at
        least ``reply_timeout_s``."""
        from . import kernels  # compiled (or loaded) here, for a bus that is opened

        self._kernels = kernels
        n = len(self.all_ids)  # the cranks, then the surrogate's servo
        address, size = self.table.state_block
        self._request = p.build_packet(
            p.BROADCAST_ID,
            p.SYNC_READ,
            address.to_bytes(2, "little") + size.to_bytes(2, "little") + bytes(self.all_ids),
        )
        goal, goal_size = self.table.goal_current
        params = goal.to_bytes(2, "little") + goal_size.to_bytes(2, "little")
        params += b"".join(bytes([i, 0, 0]) for i in self.all_ids)
        self._sync_write = np.frombuffer(
            p.build_packet(p.BROADCAST_ID, p.SYNC_WRITE, params), dtype=np.uint8
        ).copy()
        address, size = self.table.profile_velocity  # Goal Position follows: 8 bytes a servo
        params = address.to_bytes(2, "little") + (2 * size).to_bytes(2, "little")
        params += b"".join(bytes([i]) + bytes(2 * size) for i in self.ids)
        self._goal_write = np.frombuffer(
            p.build_packet(p.BROADCAST_ID, p.SYNC_WRITE, params), dtype=np.uint8
        ).copy()
        self._crc_table = np.array(p._CRC_TABLE, dtype=np.uint16)
        self._id_array = np.array(self.all_ids, dtype=np.int64)
        for constant in (self._crc_table, self._id_array):
            constant.setflags(write=False)  # as the kernels were compiled for
        self._units = np.zeros(n, dtype=np.int64)
        self._crank_units = self._units[: len(self.ids)]  # a view: the kernels fill it
        self._zero_f = np.asarray(self.zero_counts, dtype=float).copy()
        self._sign_f = np.asarray(self.directions, dtype=float).copy()
        for constant in (self._zero_f, self._sign_f):
            constant.setflags(write=False)
        self._rx = np.zeros(64 * n + 256, dtype=np.uint8)
        self._found, self._raw = np.zeros(n, dtype=bool), np.zeros((n, 3))
        latency_ms = getattr(self._sdk.port_handler, "LATENCY_TIMER", 16)
        sdk_ms = 10_000.0 / self.baud_rate * (11 + size) * n + 2.0 * latency_ms + 2.0
        self._reply_s = max(sdk_ms / 1e3, self.reply_timeout_s or 0.0)
        self._fd = port.ser.fileno()

    def close(self) -> None:
        """Remove the torque (attempted) and close the port. Idempotent."""
        if self._port is not None:
            self.torque_off()
            self._port.closePort()
            self._port = None

    def __enter__(self):
        return self.open()

    def __exit__(self, *exc):
        self.close()

    # --- configuration -----------------------------------------------------------------------

    def configure(self) -> None:
        """Torque off, write ``settings`` and a zero Goal Current to every servo, read the
        settings back.

        Raises:
            ServoConfigMismatchError: a value reads back other than written.
            BusError: a servo does not answer or refuses a write.
        """
        self.torque_off()
        if not self.torque_off_confirmed:
            self._fail("torque off before configuring")
        for i in self.all_ids:
            table = self.table
            if self._read(i, table.bus_watchdog) == p.WATCHDOG_TRIPPED:
                self._write(i, table.bus_watchdog, 0)  # clears a trip left by a previous run
            for item, value in self._settings_of[i].values():
                self._write(i, item, value)
            # A Goal Current left by an earlier run would drive the servo at Torque Enable.
            self._write(i, table.goal_current, 0)
        self.verify_configuration()

    def verify_configuration(self) -> None:
        """Read every setting back. Raises ServoConfigMismatchError (after a torque off)."""
        for i in self.all_ids:
            for name, (item, value) in self._settings_of[i].items():
                read = self._read(i, item)
                if item[1] == 4:  # the Position Limits are signed (the P series' about 0)
                    read = p.to_signed(read, 4)
                if read != value:
                    self.torque_off()
                    raise ServoConfigMismatchError(i, name, value, read)

    def enable_torque(self) -> None:
        """Torque Enable = 1 on every servo (read back). The caller checks the pose first. In
        Position Control Mode each servo's Goal Position is first its present one (no profile),
        so that its own loop holds it where it is.

        Raises:
            BusError: a servo refuses (after a torque off).
        """
        if self.position_gains_raw is not None:
            self._hold_where_they_are()
        for i in self.all_ids:
            self._write(i, self.table.torque_enable, 1)
            if self._read(i, self.table.torque_enable) != 1:
                self._fail(f"servo id {i} did not enable its torque")

    def torque_off(self) -> bool:
        """Torque Enable = 0 on every servo: one broadcast WRITE (reaches every servo that
        listens, answered by none), then each servo's, confirmed. Never raises; returns (and
        keeps in ``torque_off_confirmed``) whether every servo confirmed."""
        # From another thread, wait for a transfer in progress (a reply times out within a
        # second); past that, send anyway: removing the torque comes first.
        locked = self.lock.acquire(timeout=1.0)
        try:
            return self._torque_off()
        finally:
            if locked:
                self.lock.release()

    def _torque_off(self) -> bool:
        if self._port is None:
            return self.torque_off_confirmed
        sdk, ok = self._sdk, True
        self._port.is_using = False  # a failed transfer may leave the SDK's flag set
        try:
            enable = self.table.torque_enable[0]
            self._packets.write1ByteTxOnly(self._port, p.BROADCAST_ID, enable, 0)
            for i in self.all_ids:
                result, error = self._packets.write1ByteTxRx(self._port, i, enable, 0)
                ok &= result == sdk.COMM_SUCCESS and not error & 0x7F
        except Exception:  # the port itself failed: nothing more can be sent
            ok = False
        self.torque_off_confirmed = bool(ok)
        return self.torque_off_confirmed

    def hardware_errors(self) -> dict[int, int]:
        """{id: Hardware Error Status} of the servos that report one (bits: 0 input voltage,
        2 overheating, 3 encoder, 4 electrical shock, 5 overload; e-Manual "Hardware Error
        Status(70)"); such a servo has removed its own torque and needs a REBOOT. The SDK's
        GroupSyncRead drops the status packets' Alert bit, so :meth:`read_state` cannot see it:
        ask between periods.

        Raises:
            BusError: a servo does not answer (torque off first).
        """
        status = {i: self._read(i, self.table.hardware_error_status) for i in self.all_ids}
        return {i: bits for i, bits in status.items() if bits}

    def watchdog_tripped(self) -> list[int]:
        """The ids whose bus watchdog has tripped (Bus Watchdog reads -1): they drive no
        current and refuse Goal Current until :meth:`configure` clears the trip. A sync write
        has no status packet, so this is the way to learn it.

        Raises:
            BusError: a servo does not answer (torque off first).
        """
        watchdog = self.table.bus_watchdog
        return [i for i in self.all_ids if self._read(i, watchdog) == p.WATCHDOG_TRIPPED]

    # --- the control period ------------------------------------------------------------------

    def read_state(self) -> BusState:
        """One sync read of Present Current, Velocity and Position (126..135 on the X series,
        574..583 on the P series), sent again up to ``read_retries`` times after a corrupt
        status packet (each counted in ``reads_retried``); the time it reports is the read
        that answered.

        Raises:
            BusError: a servo does not answer (no status packet within the reply timeout), or
                answers corrupt on the read and each retry; or the port fails (torque off
                first).
        """
        self._require_open()
        for attempt in range(self.read_retries + 1):
            failed = self._sync_read()
            if failed is None:
                break
            if attempt == self.read_retries or failed != self._sdk.COMM_RX_CORRUPT:
                retried = f" (sent {attempt + 1} times)" if attempt else ""
                self._fail(f"sync read: {self._packets.getTxRxResult(failed)}{retried}")
            self.reads_retried["corrupt"] = self.reads_retried.get("corrupt", 0) + 1
        return self._state()

    def _sync_read(self):
        """One sync read into the raw buffer, its round trip kept: None, or the SDK's result
        code of what failed (a reply missing, corrupt, or the request not sent).

        Raises:
            BusError: the port fails (torque off first).
        """
        fd, rx, found = self._fd, self._rx, self._found
        found[:] = False
        received, count = 0, 0
        with self.lock:
            t0 = time.perf_counter()
            try:
                termios.tcflush(fd, termios.TCIFLUSH)  # a reply a failed read left
                sent = os.write(fd, self._request)
                deadline = time.perf_counter() + self._reply_s
                while sent == len(self._request):
                    count = self._kernels.parse_status(
                        self._crc_table, rx, received, self._id_array, found, self._raw
                    )
                    if count == len(found) or count < 0 or received == rx.size:
                        break
                    wait = deadline - time.perf_counter()
                    if wait <= 0 or not select.select([fd], [], [], wait)[0]:
                        break
                    got = os.readv(fd, [rx.data[received:]])
                    if got == 0:
                        raise OSError("the port reports data but returns none")
                    received += got
            except OSError as err:
                self._fail(f"sync read: the port failed ({err})")
            t1 = time.perf_counter()
        if count != len(found):
            sdk = self._sdk
            result = sdk.COMM_RX_TIMEOUT if count >= 0 and not received else sdk.COMM_RX_CORRUPT
            if sent != len(self._request):
                result = sdk.COMM_TX_FAIL
            return result
        self.read_times.append(t1 - t0)
        self._read_t = (t0, t1)
        return None

    def _state(self) -> BusState:
        """The state the last sync read holds (:meth:`read_state`)."""
        t0, t1 = self._read_t
        n = len(self.ids)
        state = np.empty((3, n))
        self._kernels.crank_state(
            self._raw[:n], self._zero_f, self._sign_f, *self._units_per_count, state
        )
        t_mid = 0.5 * (t0 + t1)
        if self.surrogate is None:
            return BusState(state[0], state[1], state[2], t_mid, t1 - t0)
        config, s_spec = self.surrogate, self.surrogate_spec
        current, velocity, counts = self._raw[n]
        sign = config.direction
        return BusState(
            state[0],
            state[1],
            state[2],
            t_mid,
            t1 - t0,
            s=float(config.counts_to_m(counts)),
            s_dot=float(velocity * s_spec.velocity_unit_rad_s * config.metres_per_rad * sign),
            s_tau=float(current * s_spec.amps_per_unit * s_spec.torque_constant_Nm_per_A * sign),
        )

    def write_torques(self, tau, surrogate_tau: float = 0.0) -> np.ndarray:
        """One sync write of Goal Current for crank torques ``tau`` (n,), N m, and, on a bus
        with a surrogate, its servo's torque ``surrogate_tau`` (N m at the horn in the
        carriage's sense; clipped to its Current Limit) in the same packet.

        Returns:
            (n,) the cranks' torques sent, N m: clipped to the Current Limit and rounded to its
            units.
        Raises:
            InvalidConfigError: ``tau`` of another shape, or a torque not finite (nothing sent).
            BusError: the port fails (torque off first).
        """
        tau = np.asarray(tau, dtype=float)
        self._require_open()
        applied = np.empty(len(self.ids))
        if (
            tau.shape != applied.shape
            or not self._kernels.torque_command(
                np.array(tau),  # writable and contiguous, as compiled
                self._sign_f,
                *self._units_per_count[2:],
                self.current_limit_units,
                self._crank_units,
                applied,
            )
        ):
            raise InvalidConfigError(f"tau must be {len(self.ids)} finite torques, got {tau}")
        if self.surrogate is not None:
            self._units[-1] = self.surrogate.goal_current_units(
                self.surrogate_spec, self.surrogate_limit_units, surrogate_tau
            )
        self._kernels.fill_sync_write(self._crc_table, self._sync_write, self._units)
        with self.lock:
            t0 = time.perf_counter()
            try:
                sent = os.write(self._fd, self._sync_write.data)
            except OSError as err:
                self._fail(f"sync write: the port failed ({err})")
            t1 = time.perf_counter()
        if sent != self._sync_write.size:
            self._fail(f"sync write: {self._packets.getTxRxResult(self._sdk.COMM_TX_FAIL)}")
        self.write_times.append(t1 - t0)
        return applied

    def timing(self) -> dict:
        """Round trips kept so far, s: {"read"|"write": {"n", "median", "p99", "max"}}."""
        out = {}
        for name, times in (("read", self.read_times), ("write", self.write_times)):
            t = np.asarray(times)
            out[name] = (
                {
                    "n": len(t),
                    "median": float(np.median(t)),
                    "p99": float(np.percentile(t, 99)),
                    "max": float(t.max()),
                }
                if len(t)
                else {"n": 0}
            )
        return out

    # --- internals ---------------------------------------------------------------------------

    def _require_open(self) -> None:
        if self._port is None:
            raise BusError(f"the bus on {self.port_name} is not open: call open() first")

    def _fail(self, what: str):
        """Torque off (attempted), then raise a BusError naming the port and ``what``."""
        self.torque_off()
        err = BusError(
            f"bus {self.port_name}: {what}; torque off "
            + (
                "confirmed by every servo"
                if self.torque_off_confirmed
                else "NOT confirmed: cut the servos' power"
            )
        )
        err.failure = f"bus {self.port_name}: {what}"
        raise err

    def _write(self, servo_id: int, item, value: int) -> None:
        self._require_open()
        address, size = item
        write = getattr(self._packets, f"write{size}ByteTxRx")  # size: 1, 2 or 4
        with self.lock:
            result, error = write(self._port, servo_id, address, p.to_unsigned(value, size))
        self._check(result, error, f"servo id {servo_id} write of {value} at address {address}")

    def _read(self, servo_id: int, item) -> int:
        self._require_open()
        address, size = item
        read = getattr(self._packets, f"read{size}ByteTxRx")  # size: 1, 2 or 4
        with self.lock:
            value, result, error = read(self._port, servo_id, address)
        self._check(result, error, f"servo id {servo_id} read at address {address}")
        return int(value)

    def _check(self, result: int, error: int, what: str) -> None:
        """:meth:`_fail` unless the transfer succeeded and the status has no error number."""
        if result != self._sdk.COMM_SUCCESS:
            self._fail(f"{what}: {self._packets.getTxRxResult(result)}")
        if error & 0x7F:
            self._fail(f"{what}: {self._packets.getRxPacketError(error)}")
