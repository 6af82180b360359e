"""How long a packet takes on a real bus, for the bus emulator (:mod:`.emulator`), whose
pseudo-terminal moves bytes at memory speed: :class:`BusTiming`.

An instruction reaches the servos after its bytes' time on the wire (10 bits a byte at the baud
rate: start, 8 data, stop) and the host's scheduling; a status packet leaves a servo its Return
Delay Time after the instruction (or, in a sync read, after the previous servo's status: the
servos answer in turn), takes its bytes' time, and reaches the host through the USB adapter,
which forwards what fills its 62-byte packets at once and holds the rest until its latency timer
runs out (FTDI's AN232B-04, "Data Throughput, Latency and Handshaking"): a reply's last bytes
wait up to the timer. Each packet also meets the host's and the adapter's scheduling, uniform in
``[0, jitter]``. A share of the status packets is sent corrupt (one byte changed: the CRC fails)
or not at all (a timeout), at the given rates, from a seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: The USB adapter's packet to the host: 64 bytes, 2 of them its status.
USB_PAYLOAD_BYTES = 62


@dataclass
class BusTiming:
    """A bus's timing (module docstring).

    Attributes:
        baud_rate: bps.  latency_timer_ms: the USB adapter's.  jitter_us: the host's and the
            adapter's scheduling, each packet, uniform in [0, it].
        crc_error_rate, timeout_rate: the share of status packets sent corrupt, or not sent.
        seed: the jitter's and the errors' draw.
    """

    baud_rate: int
    latency_timer_ms: float = 1.0
    jitter_us: float = 100.0
    crc_error_rate: float = 0.0
    timeout_rate: float = 0.0
    seed: int = 0
    _rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self):
        self._rng = np.random.default_rng([self.seed, 2])

    def wire_s(self, n_bytes: int) -> float:
        """The time ``n_bytes`` take on the wire, s (10 bits a byte)."""
        return 10.0 * n_bytes / self.baud_rate

    def jitter_s(self) -> float:
        """One packet's scheduling delay, s."""
        return float(self._rng.uniform(0.0, self.jitter_us * 1e-6)) if self.jitter_us else 0.0

    def instruction_s(self, n_bytes: int) -> float:
        """From the host's write of an instruction of ``n_bytes`` to its last byte at the
        servos, s."""
        return self.jitter_s() + self.wire_s(n_bytes)

    def reply_s(self, statuses: list[tuple[int, float]]) -> float:
        """From the instruction at the servos to the reply's last byte at the host, s, for
        ``statuses`` [(bytes, the servo's return delay s)] in the order the servos answer."""
        on_wire = sum(delay + self.wire_s(n) for n, delay in statuses)
        total = sum(n for n, _ in statuses)
        held = 0.0
        if total % USB_PAYLOAD_BYTES and self.latency_timer_ms:
            held = float(self._rng.uniform(0.0, self.latency_timer_ms * 1e-3))
        return on_wire + held + self.jitter_s()

    def fate(self) -> str:
        """What happens to one status packet: "sent", "corrupt" or "lost"."""
        if not (self.crc_error_rate or self.timeout_rate):
            return "sent"
        u = float(self._rng.uniform())
        if u < self.timeout_rate:
            return "lost"
        if u < self.timeout_rate + self.crc_error_rate:
            return "corrupt"
        return "sent"
