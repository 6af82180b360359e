"""Drive a headless Chromium over the DevTools protocol on a pipe (no extra package).

    with HeadlessChromium("http://localhost:7000") as browser:
        browser.evaluate("1 + 1")                       # -> 2
        browser.screenshot("shot.png")

Chromium is started with ``--remote-debugging-pipe`` (it reads commands on its fd 3 and writes
answers on its fd 4, each a JSON text ended by a NUL byte), headless, with a fresh profile in a
temporary folder, and software WebGL (SwiftShader), so it needs no display and no GPU. Every wait
is bounded: a command that gets no answer within its timeout raises TimeoutError, and the
browser is killed when the block ends.
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import select
import signal
import subprocess
import tempfile
import time
from pathlib import Path

from stewart_drake.viz.visualize import find_chromium

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--remote-debugging-pipe",
)


class HeadlessChromium:
    """A headless Chromium showing ``url``, driven by DevTools commands (module docstring).

    Args:
        url: the page to open. size: window (width, height) in pixels.
        chromium: the browser's path (default the first on PATH).
        timeout_s: default bound of every wait, s.
    Raises:
        FileNotFoundError: no Chromium on PATH.
    """

    def __init__(
        self, url: str, size=(1280, 800), chromium: str | None = None, timeout_s: float = 60.0
    ):
        self.url, self.size, self.timeout_s = url, size, timeout_s
        self.exe = chromium or find_chromium()
        if self.exe is None:
            raise FileNotFoundError("no Chromium on PATH (Debian: `apt-get install chromium`)")
        self._ids = itertools.count(1)
        self._buffer = b""
        self._session = None

    def __enter__(self) -> HeadlessChromium:
        self._profile = tempfile.TemporaryDirectory(
            prefix="chromium-profile-", ignore_cleanup_errors=True
        )
        self._log = tempfile.TemporaryFile()
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        # bash puts the two pipe ends on the browser's fds 3 and 4 (no preexec_fn: this
        # process may run threads, e.g. Meshcat's server).
        args = [
            *FLAGS,
            f"--user-data-dir={self._profile.name}",
            f"--window-size={self.size[0]},{self.size[1]}",
            self.url,
        ]
        self.process = subprocess.Popen(
            [
                "bash",
                "-c",
                f'exec "$0" "$@" 3<&{to_browser_r} 4>&{from_browser_w}',
                self.exe,
                *args,
            ],
            pass_fds=(to_browser_r, from_browser_w),
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=self._log,
            start_new_session=True,
        )  # its own group: ended with its children
        os.close(to_browser_r)
        os.close(from_browser_w)
        try:
            self._attach()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc) -> None:
        try:
            try:
                os.killpg(self.process.pid, signal.SIGKILL)  # the browser and its helpers
            except ProcessLookupError:
                pass
            self.process.wait(timeout=30)
        finally:
            for fd in (self._to_browser, self._from_browser):
                try:
                    os.close(fd)
                except OSError:
                    pass
            self._log.close()
            self._profile.cleanup()

    def log_tail(self, n: int = 2000) -> str:
        """The end of the browser's own output (for error messages)."""
        self._log.seek(0)
        return self._log.read().decode(errors="replace")[-n:]

    def send(
        self,
        method: str,
        params: dict | None = None,
        session: bool = True,
        timeout_s: float | None = None,
    ) -> dict:
        """Send one DevTools command and return its ``result``.

        Raises:
            TimeoutError: no answer within the timeout. RuntimeError: the browser answered with
            an error, or exited.
        """
        message = {"id": next(self._ids), "method": method, "params": params or {}}
        if session and self._session is not None:
            message["sessionId"] = self._session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + (timeout_s or self.timeout_s)
        while True:
            for answer in self._read(deadline):
                if answer.get("id") == message["id"]:
                    if "error" in answer:
                        raise RuntimeError(f"{method}: {answer['error']}")
                    return answer.get("result", {})

    def _read(self, deadline: float):
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no answer from Chromium in time; its log:\n{self.log_tail()}")
            ready, _, _ = select.select([self._from_browser], [], [], min(left, 1.0))
            if ready:
                chunk = os.read(self._from_browser, 1 << 20)
                if not chunk:
                    raise RuntimeError(f"Chromium exited; its log:\n{self.log_tail()}")
                self._buffer += chunk
        *messages, self._buffer = self._buffer.split(b"\0")
        return [json.loads(m) for m in messages if m]

    def _attach(self) -> None:
        deadline = time.monotonic() + self.timeout_s
        while True:
            pages = [
                t
                for t in self.send("Target.getTargets", session=False)["targetInfos"]
                if t["type"] == "page"
            ]
            if pages:
                break
            if time.monotonic() > deadline:
                raise TimeoutError("Chromium opened no page")
            time.sleep(0.2)
        self._session = self.send(
            "Target.attachToTarget",
            {"targetId": pages[0]["targetId"], "flatten": True},
            session=False,
        )["sessionId"]

    def evaluate(self, expression: str, timeout_s: float | None = None):
        """The value of a JavaScript expression in the page (promises are awaited)."""
        result = self.send(
            "Runtime.evaluate",
            {"expression": expression, "awaitPromise": True, "returnByValue": True},
            timeout_s=timeout_s,
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"JavaScript failed: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float | None = None, poll_s: float = 0.2):
        """Evaluate ``expression`` until it is truthy; its value. Raises TimeoutError."""
        deadline = time.monotonic() + (timeout_s or self.timeout_s)
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"{expression!r} stayed false")
            time.sleep(poll_s)

    def screenshot(self, png: str | Path) -> Path:
        """Write what the page shows now to ``png``; returns its path."""
        data = self.send("Page.captureScreenshot", {"format": "png"})["data"]
        png = Path(png)
        png.parent.mkdir(parents=True, exist_ok=True)
        png.write_bytes(base64.b64decode(data))
        return png
