"""One emulated servo's control table (:class:`ServoTable`): what the bus emulator's servos hold,
check and answer from (:mod:`.emulator`)."""

import math
import time

from . import protocol as p
from .servos import ServoSpec


class ServoTable:
    """One emulated servo's control table, its watchdog's clock and when its goal was written.

    Args:
        servo_id: its id.  spec: its :class:`~.servos.ServoSpec`.  ambient_C: Present
            Temperature.  return_delay_us: the Return Delay Time its table starts with, us.
    """

    def __init__(self, servo_id: int, spec: ServoSpec, ambient_C: float, return_delay_us=0.0):
        self.id, self.spec = servo_id, spec
        #: The family's addresses (:class:`~.protocol.ControlTable`).
        self.items = t = spec.table
        self.table = bytearray(t.size)
        self.put(p.MODEL_NUMBER, spec.model_number)
        self.put(p.FIRMWARE_VERSION, 48)
        self.put(p.ID, servo_id)
        self.put(
            p.RETURN_DELAY_TIME, min(254, round(return_delay_us * 1e-6 / p.RETURN_DELAY_UNIT_S))
        )
        self.put(t.operating_mode, 3)  # factory: Position Control Mode
        self.put(t.temperature_limit, 80)
        self.put(t.current_limit, spec.current_limit_max)
        self.put(t.min_position_limit, spec.position_range[0])
        self.put(t.max_position_limit, spec.position_range[1])
        self.put(t.present_temperature, int(ambient_C))
        self.last_instruction = time.perf_counter()
        #: When Goal Position or Profile Velocity was last written (perf_counter s), and the
        #: (Goal Position counts, Profile Velocity units) before that write.
        self.goal_written_t = -math.inf
        self.previous_goal: tuple[int, int] = (0, 0)

    def get(self, item) -> int:
        address, size = item
        return int.from_bytes(self.table[address : address + size], "little")

    def put(self, item, value: int) -> None:
        address, size = item
        self.table[address : address + size] = p.to_unsigned(value, size).to_bytes(size, "little")

    def return_delay_s(self) -> float:
        """The Return Delay Time its table holds, s."""
        return self.get(p.RETURN_DELAY_TIME) * p.RETURN_DELAY_UNIT_S

    @property
    def watchdog_tripped(self) -> bool:
        return self.get(self.items.bus_watchdog) == p.WATCHDOG_TRIPPED

    def _driving_in(self, mode: int) -> bool:
        """Its torque on in operating ``mode``, with no watchdog trip and no hardware error."""
        t = self.items
        return (
            self.get(t.torque_enable) == 1
            and not self.watchdog_tripped
            and not self.get(t.hardware_error_status)
            and self.get(t.operating_mode) == mode
        )

    def current_A(self) -> float:
        """What the servo drives: the Goal Current in Current Control Mode with the torque on,
        no watchdog trip and no hardware error; zero otherwise."""
        if not self._driving_in(p.CURRENT_CONTROL_MODE) or self.spec.current_unit_A is None:
            return 0.0
        return p.to_signed(self.get(self.items.goal_current), 2) * self.spec.current_unit_A

    def in_position_mode(self) -> bool:
        """Its own position loop drives it: Position Control Mode, the torque on, no watchdog
        trip and no hardware error."""
        return self._driving_in(p.POSITION_CONTROL_MODE) and bool(self.items.position_gains)

    def position_command(self) -> tuple:
        """(Goal Position counts, Profile Velocity units, the raw (D, I, P, FF1st) Gains)."""
        t = self.items
        return (
            p.to_signed(self.get(t.goal_position), 4),
            self.get(t.profile_velocity),
            tuple(self.get(item) for item in t.position_gains),
        )

    def timed_command(self) -> tuple:
        """(:meth:`position_command`, the (goal, profile) before its last write, the write's
        perf_counter time): what the servo followed before and from that instant."""
        return self.position_command(), self.previous_goal, self.goal_written_t

    def write(self, address: int, data: bytes) -> int:
        """Write ``data`` at ``address``: the status error (0 if written)."""
        t = self.items
        end = address + len(data)
        if end > t.size or not data:
            return p.ERR_DATA_RANGE
        if any(address < stop and end > start for start, stop in t.read_only):
            return p.ERR_ACCESS
        if address < t.eeprom_end and self.get(t.torque_enable):
            return p.ERR_ACCESS
        if self.watchdog_tripped and address < t.goals[1] and end > t.goals[0]:
            return p.ERR_DATA_RANGE
        staged = bytearray(self.table)
        staged[address:end] = data
        goal_at, limit_at = t.goal_current[0], t.current_limit[0]
        if address <= goal_at < end:
            goal = p.to_signed(int.from_bytes(staged[goal_at : goal_at + 2], "little"), 2)
            if abs(goal) > self.get(t.current_limit):
                return p.ERR_DATA_LIMIT
        if address <= limit_at < end:
            if (
                int.from_bytes(staged[limit_at : limit_at + 2], "little")
                > self.spec.current_limit_max
            ):
                return p.ERR_DATA_LIMIT
        goals = t.profile_velocity[0], t.goal_position[0] + t.goal_position[1]
        if t.position_gains and address < goals[1] and end > goals[0]:
            self.previous_goal = (
                p.to_signed(self.get(t.goal_position), 4),
                self.get(t.profile_velocity),
            )
            self.goal_written_t = time.perf_counter()
        self.table[:] = staged
        return 0


__all__ = ["ServoTable"]
