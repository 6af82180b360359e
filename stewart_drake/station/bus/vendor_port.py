"""The vendor's library (``dynamixel_sdk``, extra ``robot``), imported on first use, and its port
as the driver (:mod:`.driver`) opens it: a receive loop that sleeps while it waits for a reply,
and a least time to wait for one."""

from __future__ import annotations

import select

from ...base.errors import (
    MissingExtraError,
)


def dynamixel_sdk():
    """The vendor's module, imported on first use.

    Raises:
        MissingExtraError: not installed (says which extra to install).
    """
    try:
        import dynamixel_sdk as sdk
    except ImportError:
        raise MissingExtraError(
            "the servo driver needs ROBOTIS's dynamixel-sdk: pip install 'stewart-drake[robot]'"
        ) from None
    return sdk


def port_handler(sdk, port: str, reply_timeout_s: float | None):
    """The SDK's PortHandler on ``port``, with two changes.

    Its receive loop polls the port without waiting (``timeout=0``): one core at 100 % while a
    reply is awaited, and in one process with the emulator's thread, a GIL held most of the
    time. Here a read of an empty port first waits up to 0.5 ms for a byte (``select``), so
    the loop sleeps instead. And ``reply_timeout_s`` (None: the SDK's own, 2 x 16 ms of USB
    latency timer + 2 ms + the transfer) is the least time to wait for a status packet.
    """

    class PortHandler(sdk.PortHandler):
        def readPort(self, length):
            if self.ser.in_waiting == 0:
                select.select([self.ser.fileno()], [], [], 5e-4)
            return super().readPort(length)

        def setPacketTimeout(self, packet_length):
            super().setPacketTimeout(packet_length)
            if reply_timeout_s is not None:
                self.packet_timeout = max(self.packet_timeout, 1e3 * reply_timeout_s)

    return PortHandler(port)


__all__ = [
    "dynamixel_sdk",
    "port_handler",
]
