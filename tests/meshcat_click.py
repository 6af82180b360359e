"""Click a Meshcat button as a browser does: one websocket message to the live server.

A minimal websocket client (RFC 6455 handshake, one masked binary frame) and msgpack of the one
message Drake's Meshcat takes for a click, so the tests need no websocket or msgpack package.
"""

import base64
import os
import socket
import time
from urllib.parse import urlparse

from conftest import HANG_S


def _str(text: str) -> bytes:
    data = text.encode()
    assert len(data) < 256
    return (bytes([0xA0 | len(data)]) if len(data) < 32 else bytes([0xD9, len(data)])) + data


def send_click(ws_url: str, name: str, until, timeout_s: float = HANG_S) -> None:
    """Send one click of button ``name`` to the Meshcat server at ``ws_url`` (any thread:
    no Meshcat call, which Drake allows only from the thread that made the Meshcat), and keep
    the connection open until ``until()`` is true (the click seen: the server has read the
    frame, however slow; no fixed wait). ``timeout_s`` guards against a hang.

    Raises:
        TimeoutError: ``until()`` still false after ``timeout_s``.
    """
    url = urlparse(ws_url)
    message = b"\x82" + _str("type") + _str("button") + _str("name") + _str(name)
    with socket.create_connection((url.hostname, url.port), timeout=timeout_s) as sock:
        key = base64.b64encode(os.urandom(16)).decode()
        sock.sendall(
            f"GET / HTTP/1.1\r\nHost: {url.hostname}:{url.port}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            f"Sec-WebSocket-Version: 13\r\n\r\n".encode()
        )
        reply = b""
        while b"\r\n\r\n" not in reply:
            chunk = sock.recv(4096)
            assert chunk, "Meshcat closed the websocket during the handshake"
            reply += chunk
        assert reply.startswith(b"HTTP/1.1 101"), reply[:80]
        mask = os.urandom(4)
        assert len(message) < 126
        frame = bytes([0x82, 0x80 | len(message)]) + mask
        frame += bytes(b ^ mask[i % 4] for i, b in enumerate(message))
        sock.sendall(frame)
        deadline = time.monotonic() + timeout_s
        while not until():
            if time.monotonic() > deadline:
                raise TimeoutError(f"the click of {name!r} was not seen")
            time.sleep(0.01)


def click(meshcat, name: str, timeout_s: float = HANG_S) -> int:
    """Click button ``name`` of ``meshcat`` once (:func:`send_click`); returns its click count
    once Meshcat has it (the connection kept open until then, however slow the server).

    Raises:
        TimeoutError: Meshcat did not count the click within ``timeout_s`` (a hang).
    """
    before = meshcat.GetButtonClicks(name)
    counted = lambda: meshcat.GetButtonClicks(name) != before  # noqa: E731
    send_click(meshcat.ws_url(), name, counted, timeout_s)
    return meshcat.GetButtonClicks(name)
