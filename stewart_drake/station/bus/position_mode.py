"""The servos' own position loop on the bus: its settings in a scenario, the gains it writes and
the bus's part in it.

:class:`ServoPositionLoop` is a scenario's ``bus.position_loop``: the servos run their firmware's
Position Control Mode (operating mode 3) with gains placed here on the catalogue's servo, and the
host streams goal positions each period (the controller
:class:`~stewart_drake.control.servo.goal_stream.CrankGoalStreamer`) instead of closing a current
loop itself. :class:`PositionMode` is :class:`~.driver.DynamixelBus`'s part: the mode and gains
among the settings written with the torque off, each servo's goal set to where it is before its
torque goes on, and the goals' one sync write a period.

Why the servo's own loop: its 1 ms on its own encoder sees the crank's motion ten times as often
as a host loop at 10 ms over the bus, and a loop-gain error of the catalogue's inertia or torque
constant moves its bandwidth rather than its stability (docs/robot.md, "The servo's own loop").

This module must not use ``from __future__ import annotations``: Drake's YAML loader reads
:class:`ServoPositionLoop`'s field types.
"""

import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...base.checks import as_number
from ...base.errors import InvalidConfigError
from ...robot.motor_catalogue import catalogue_motor
from . import protocol as p

#: The names of the raw gains, in the control table's order (and ``position_gains_raw``'s).
GAIN_NAMES = ("Position D Gain", "Position I Gain", "Position P Gain", "Feedforward 1st Gain")


@dataclass
class ServoPositionLoop:
    """The servos' own position loop, a scenario's ``bus.position_loop`` (None: the servos in
    Current Control Mode and the host's current loop).

    Gains that make each crank a second-order system of ``bandwidth_hz`` and ``damping`` on the
    inertia its servo drives, by the catalogue's torque constant, winding and supply
    (:func:`~.servo_firmware.position_gains`; the servos as built depart from it, and the loop's
    bandwidth with them), converted to the control table's units by the X series' e-Manual
    (:func:`~.servo_firmware.raw_position_gains`).

    Attributes:
        bandwidth_hz: the loop's natural frequency, Hz (up to a quarter of the firmware's 1 ms
            loop's Nyquist frequency).
        damping: its damping ratio (0, 10].
        integral_ratio: the integral's corner sits at ``bandwidth_hz / integral_ratio`` (>= 1).
    """

    bandwidth_hz: float = 30.0
    damping: float = 1.4
    integral_ratio: float = 4.0

    def validate(self, spec, prefix: str = "bus.position_loop.") -> "ServoPositionLoop":
        """Check the fields (named with ``prefix``) for servos ``spec`` (a
        :class:`~.servos.ServoSpec`); returns self.

        Raises:
            InvalidConfigError: a field out of range, or a model without a position loop.
        """
        from .servo_firmware import position_gains

        as_number(f"{prefix}bandwidth_hz", self.bandwidth_hz, 0.0, 1e3, lo_open=True)
        as_number(f"{prefix}damping", self.damping, 0.0, 10.0, lo_open=True)
        as_number(f"{prefix}integral_ratio", self.integral_ratio, 1.0, 1e6)
        if not spec.table.position_gains:
            raise InvalidConfigError(f"{prefix[:-1]}: {spec.name}'s table has no position gains")
        try:
            position_gains(1.0, 1.0, 1.0, 1.0, self.bandwidth_hz, self.damping)
        except InvalidConfigError as err:
            raise InvalidConfigError(f"{prefix}bandwidth_hz: {err}") from None
        return self

    def raw_gains(self, spec, inertia_kg_m2: float) -> tuple[int, int, int, int]:
        """The control table's (Position D, I, P, Feedforward 1st) Gains for servos ``spec``
        (a :class:`~.servos.ServoSpec`) each driving ``inertia_kg_m2`` (:func:`crank_inertia`).

        Raises:
            InvalidConfigError: a gain past the table's range (a slower loop is needed).
        """
        from .servo_firmware import position_gains, raw_position_gains

        supply = p.SUPPLY_V[spec.table.family]
        gains = position_gains(
            inertia_kg_m2,
            spec.torque_constant_Nm_per_A,
            supply / spec.stall_current_A,
            supply,
            self.bandwidth_hz,
            self.damping,
            self.integral_ratio,
        )
        try:
            return raw_position_gains(gains, spec)
        except InvalidConfigError as err:
            raise InvalidConfigError(f"bus.position_loop.bandwidth_hz: {err}") from None


def crank_inertia(geometry, model: str) -> float:
    """The inertia one servo's loop drives, kg m^2: its rotor reflected through its gears (the
    motor catalogue's) and its crank's share of the platform and of its rod, taken at the crank's
    tip (a sixth of the platform's mass and the rod's whole mass at ``crank_length``)."""
    share = (geometry.platform_mass / 6 + geometry.rod_mass) * geometry.crank_length**2
    return float(catalogue_motor(model).servo.reflected_inertia + share)


class PositionMode:
    """:class:`~.driver.DynamixelBus`'s servos in Position Control Mode (``position_gains_raw``
    given): their settings, torque on where they are, the goals' sync write."""

    # The bus's own (DynamixelBus.__init__ sets them): what this part reads.
    ids: list
    spec: Any
    table: Any
    settings: dict
    position_gains_raw: tuple | None
    zero_counts: np.ndarray
    directions: np.ndarray
    write_times: Any
    lock: Any
    _sdk: Any
    _port: Any
    _packets: Any
    _fd: int
    _kernels: Any
    _crc_table: np.ndarray
    _goal_write: np.ndarray  # the goals' sync write, its data filled each period
    surrogate: Any
    surrogate_spec: Any
    surrogate_limit_units: int

    def _read(self, servo_id: int, item) -> int:
        raise NotImplementedError

    def _write(self, servo_id: int, item, value: int) -> None:
        raise NotImplementedError

    def _require_open(self) -> None:
        raise NotImplementedError

    def _fail(self, what: str):
        raise NotImplementedError

    def _position_settings(self) -> None:
        """Position Control Mode and the raw gains among the settings written (and read back)."""
        table = self.table
        self.settings["Operating Mode"] = (table.operating_mode, p.POSITION_CONTROL_MODE)
        for name, item, value in zip(
            GAIN_NAMES,
            table.position_gains,
            self.position_gains_raw or (),
            strict=True,
        ):
            self.settings[name] = (item, value)

    def _hold_where_they_are(self) -> None:
        """Each servo's Goal Position its present one, no profile: its loop holds it there when
        its torque goes on."""
        table = self.table
        for i in self.ids:
            here = p.to_signed(self._read(i, table.present_position), 4)
            self._write(i, table.profile_velocity, 0)
            self._write(i, table.goal_position, here)

    def write_goals(self, q_rad, profile_rad_s=None) -> np.ndarray:
        """One sync write of each crank's Profile Velocity and Goal Position (contiguous: 8
        bytes a servo) in Position Control Mode: the cranks' goal angles ``q_rad`` (n,), rad,
        each reached at ``profile_rad_s`` (n,), rad/s (its size; less than one unit is sent as
        one, for 0 is no profile); None: no profile, each goal at once.

        Returns:
            (n,) the goal angles sent, rad (whole counts).
        Raises:
            InvalidConfigError: a bus in Current Control Mode, or angles or rates of another
                shape or not finite (nothing sent).
            BusError: the port fails (torque off first).
        """
        if self.position_gains_raw is None:
            raise InvalidConfigError(
                "write_goals: the bus runs Current Control Mode (give position_gains_raw)"
            )
        q = np.asarray(q_rad, dtype=float)
        n = len(self.ids)
        v = np.abs(np.asarray(np.zeros(n) if profile_rad_s is None else profile_rad_s, float))
        if (
            q.shape != (n,)
            or v.shape != (n,)
            or not (np.all(np.isfinite(q)) and np.all(np.isfinite(v)))
        ):
            raise InvalidConfigError(f"write_goals needs {n} finite angles and rates")
        self._require_open()
        spec = self.spec
        zero, sign = self.zero_counts, self.directions
        counts = p.rad_to_counts(q, zero, sign, spec.counts_per_rev)
        units = np.rint(v / spec.velocity_unit_rad_s)
        if profile_rad_s is not None:
            units = np.maximum(units, 1)
        packet = self._goal_write
        if not self._kernels.fill_goal_write(
            self._crc_table, packet, units.astype(np.int64), counts
        ):
            packet = np.frombuffer(  # stuffed: a goal far outside any servo's range
                p.build_packet(p.BROADCAST_ID, p.SYNC_WRITE, packet[8:-2].tobytes()), np.uint8
            )
        with self.lock:
            t0 = time.perf_counter()
            try:
                sent = os.write(self._fd, packet.data)
            except OSError as err:
                self._fail(f"sync write of goals: the port failed ({err})")
            t1 = time.perf_counter()
        if sent != packet.size:
            self._fail(
                f"sync write of goals: {self._packets.getTxRxResult(self._sdk.COMM_TX_FAIL)}"
            )
        self.write_times.append(t1 - t0)
        return p.counts_to_rad(counts, zero, sign, spec.counts_per_rev)

    def write_surrogate_torque(self, tau_Nm: float) -> None:
        """One sync write of the surrogate servo's Goal Current alone (it keeps Current Control
        Mode beside cranks in their own position loop): ``tau_Nm`` at its horn in the
        carriage's sense, clipped to its Current Limit. Sent before the period's goals: the
        goals are the period's command (an emulator on the loop's clock moves on them).

        Raises:
            InvalidConfigError: no surrogate on the bus, or a torque not finite (nothing sent).
            BusError: the port fails (torque off first).
        """
        if self.surrogate is None:
            raise InvalidConfigError("write_surrogate_torque: no surrogate on this bus")
        units = self.surrogate.goal_current_units(
            self.surrogate_spec, self.surrogate_limit_units, tau_Nm
        )
        self._require_open()
        group = self._sdk.GroupSyncWrite(self._port, self._packets, self.table.goal_current[0], 2)
        group.addParam(int(self.surrogate.id), list(p.to_unsigned(units, 2).to_bytes(2, "little")))
        with self.lock:
            t0 = time.perf_counter()
            result = group.txPacket()
            t1 = time.perf_counter()
        if result != self._sdk.COMM_SUCCESS:
            self._fail(
                f"sync write of the surrogate's current: {self._packets.getTxRxResult(result)}"
            )
        self.write_times.append(t1 - t0)


def checked_gains(raw, spec, surrogate=None) -> tuple[int, int, int, int] | None:
    """``raw`` (Position D, I, P, Feedforward 1st Gains) checked for ``spec``'s table (a
    surrogate on the bus keeps Current Control Mode: its own settings).

    Raises:
        InvalidConfigError: four integers within the table's range are not given.
    """
    if raw is None:
        return None
    from .servo_firmware import GAIN_MAX

    top = GAIN_MAX[spec.table.family]
    values = tuple(raw)
    if len(values) != 4 or not all(isinstance(v, int) and 0 <= v <= top for v in values):
        raise InvalidConfigError(
            f"position_gains_raw must be 4 integers (Position D, I, P, Feedforward 1st) in "
            f"0..{top} for {spec.name}, got {raw!r}"
        )
    return values


__all__ = ["GAIN_NAMES", "ServoPositionLoop", "crank_inertia", "PositionMode", "checked_gains"]
