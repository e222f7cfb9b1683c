"""Headless Chromium driven over the DevTools protocol on a pipe: open a page, wait, screenshot.

Used to check the viewer as a person would see it (the tests) and to take the README's
screenshot. No extra dependency: Chromium's ``--remote-debugging-pipe`` reads JSON commands
on file descriptor 3 and writes replies and events on 4, each message ended by a NUL byte.
WebGL runs on SwiftShader (software), so no GPU or display is needed.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cpbc.errors import CpbcError

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--mute-audio",
)


class BrowserError(CpbcError):
    """Chromium is missing, died, or a page did not get ready in time."""


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome executable on PATH, or None."""
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


@dataclass
class PageLog:
    """What a page reported while it was open.

    Attributes:
        errors: uncaught exceptions, ``console.error``/``assert`` calls and browser log
            entries of level error (failed loads, WebGL errors), as text.
        messages: every other console call and log entry, as text.
        requests: the URL of every request the page made.
    """

    errors: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)


_TRAMPOLINE = (
    "import os, sys; a, b = int(sys.argv[1]), int(sys.argv[2]); os.dup2(a, 3); os.dup2(b, 4); "
    "os.close(a); os.close(b); os.execv(sys.argv[3], sys.argv[3:])"
)


def _above_four(fd: int) -> int:
    """The same pipe end on a descriptor number above 4 (the original is closed)."""
    high = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
    os.close(fd)
    return high


def _console_text(params: dict[str, Any]) -> str:
    parts = [
        str(a.get("value", a.get("description", a.get("type")))) for a in params.get("args", [])
    ]
    return " ".join(parts)


class HeadlessChromium:
    """One headless Chromium with one page; use as a context manager.

    Args:
        executable: the browser; :func:`find_chromium` when omitted.
        width, height: viewport [px].
        timeout: default seconds to wait for a reply.
    """

    def __init__(
        self,
        executable: str | None = None,
        width: int = 1280,
        height: int = 800,
        timeout: float = 60.0,
    ) -> None:
        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError(f"no Chromium found on PATH (looked for {', '.join(CANDIDATES)})")
        self.executable = exe
        self.width, self.height, self.timeout = width, height, timeout
        self.log = PageLog()
        self._buffer = b""
        self._next_id = 0
        self._session: str | None = None
        self._events: list[dict[str, Any]] = []

    # -- process -----------------------------------------------------------------------------
    def __enter__(self) -> HeadlessChromium:
        self._profile = tempfile.mkdtemp(prefix="cpbc-chromium-")
        self._stderr = tempfile.TemporaryFile()
        to_child, self._write = os.pipe()
        self._read, from_child = os.pipe()
        # Above 4, so that placing them on 3 and 4 in the child cannot overwrite one another.
        to_child, from_child = _above_four(to_child), _above_four(from_child)
        args = [
            *FLAGS,
            f"--user-data-dir={self._profile}",
            f"--window-size={self.width},{self.height}",
            "--remote-debugging-pipe",
            "about:blank",
        ]
        # The protocol needs the pipes on descriptors 3 and 4 exactly: a two-line Python
        # trampoline places them (a shell cannot portably name descriptors above 9).
        self._proc = subprocess.Popen(
            [sys.executable, "-c", _TRAMPOLINE, str(to_child), str(from_child),
             self.executable, *args],
            pass_fds=(to_child, from_child), stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=self._stderr,
        )
        os.close(to_child)
        os.close(from_child)
        try:
            target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
            self._session = self.call(
                "Target.attachToTarget", {"targetId": target, "flatten": True}
            )["sessionId"]
            for domain in ("Page", "Runtime", "Log", "Network"):
                self.call(f"{domain}.enable")
            self.call(
                "Emulation.setDeviceMetricsOverride",
                {
                    "width": self.width,
                    "height": self.height,
                    "deviceScaleFactor": 1,
                    "mobile": False,
                },
            )
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the browser and remove its profile."""
        proc = getattr(self, "_proc", None)
        if proc is not None and proc.poll() is None:
            try:
                self._send("Browser.close", {}, session=False)
                proc.wait(timeout=10)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait(timeout=10)
        for fd in ("_read", "_write"):
            if hasattr(self, fd):
                try:
                    os.close(getattr(self, fd))
                except OSError:
                    pass
                delattr(self, fd)
        if hasattr(self, "_stderr"):
            self._stderr.close()
        if hasattr(self, "_profile"):
            shutil.rmtree(self._profile, ignore_errors=True)

    def _stderr_tail(self) -> str:
        try:
            self._stderr.seek(0)
            lines = self._stderr.read().decode(errors="replace").splitlines()
        except (OSError, ValueError):
            return ""
        return "\n".join(lines[-15:])

    # -- protocol ----------------------------------------------------------------------------
    def _send(self, method: str, params: dict[str, Any], session: bool = True) -> int:
        self._next_id += 1
        msg: dict[str, Any] = {"id": self._next_id, "method": method, "params": params}
        if session and self._session is not None:
            msg["sessionId"] = self._session
        os.write(self._write, json.dumps(msg).encode() + b"\0")
        return self._next_id

    def _receive(self, deadline: float) -> dict[str, Any] | None:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([self._read], [], [], left)
            if ready:
                chunk = os.read(self._read, 1 << 20)
                if not chunk:
                    raise BrowserError(f"Chromium exited; its last output:\n{self._stderr_tail()}")
                self._buffer += chunk
        raw, self._buffer = self._buffer.split(b"\0", 1)
        msg = json.loads(raw)
        if "method" in msg:
            self._note(msg)
        return msg

    def _note(self, event: dict[str, Any]) -> None:
        method, params = event["method"], event.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = params.get("exceptionDetails", {})
            text = d.get("exception", {}).get("description") or d.get("text", "exception")
            self.log.errors.append(f"uncaught: {text}")
        elif method == "Runtime.consoleAPICalled":
            text = f"console.{params.get('type')}: {_console_text(params)}"
            (
                self.log.errors if params.get("type") in ("error", "assert") else self.log.messages
            ).append(text)
        elif method == "Network.requestWillBeSent":
            self.log.requests.append(str(params.get("request", {}).get("url", "")))
        elif method == "Log.entryAdded":
            e = params.get("entry", {})
            text = f"{e.get('source')} {e.get('level')}: {e.get('text')} {e.get('url', '')}".strip()
            (self.log.errors if e.get("level") == "error" else self.log.messages).append(text)

    def call(
        self, method: str, params: dict[str, Any] | None = None, timeout: float | None = None
    ) -> dict[str, Any]:
        """Send one DevTools command and wait for its reply."""
        i = self._send(method, params or {})
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            msg = self._receive(deadline)
            if msg is None:
                raise BrowserError(f"no reply to {method} within {timeout or self.timeout} s")
            if msg.get("id") == i:
                if "error" in msg:
                    raise BrowserError(f"{method} failed: {msg['error']}")
                return msg.get("result", {})

    def pump(self, seconds: float) -> None:
        """Let the page run for a while, collecting its log."""
        deadline = time.monotonic() + seconds
        while self._receive(deadline) is not None:
            pass

    # -- page --------------------------------------------------------------------------------
    def evaluate(self, expression: str, timeout: float | None = None) -> Any:
        """Evaluate JavaScript in the page (promises awaited); returns the value."""
        r = self.call(
            "Runtime.evaluate",
            {
                "expression": expression,
                "returnByValue": True,
                "awaitPromise": True,
            },
            timeout,
        )
        if "exceptionDetails" in r:
            raise BrowserError(
                f"page script failed: {r['exceptionDetails'].get('text')}: {expression}"
            )
        return r.get("result", {}).get("value")

    def open(self, url: str, ready: str, timeout: float | None = None) -> None:
        """Navigate to ``url`` and wait until the JavaScript expression ``ready`` is truthy."""
        self.call("Page.navigate", {"url": url})
        self.wait_until(ready, timeout, what=url)

    def wait_until(self, condition: str, timeout: float | None = None, what: str = "page"
                   ) -> None:
        """Let the page run until the JavaScript expression ``condition`` is truthy."""
        deadline = time.monotonic() + (timeout or self.timeout)
        probe = f"(() => {{ try {{ return !!({condition}); }} catch (e) {{ return false; }} }})()"
        while not self.evaluate(probe):
            if time.monotonic() > deadline:
                raise BrowserError(
                    f"{what} was not ready ({condition}) within {timeout or self.timeout} s"
                )
            self.pump(0.2)

    def next_frames(self, count: int = 2) -> None:
        """Wait until the page has drawn ``count`` more animation frames."""
        self.evaluate(
            "new Promise(r => { let n = " + str(int(count)) + "; const f = () => (--n > 0 ? "
            "requestAnimationFrame(f) : r(true)); requestAnimationFrame(f); })"
        )

    def screenshot(self, path: Path | None = None) -> bytes:
        """A PNG of the viewport (also written to ``path`` when given)."""
        data = base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])
        if path is not None:
            Path(path).write_bytes(data)
        return data
