"""A meshcat server on the loopback interface only, run in a child process.

The child is :mod:`cpbc.viewer.loopback` (meshcat's bridge with its web server bound to
127.0.0.1); it stops when asked and whenever the process that started it ends.
"""

from __future__ import annotations

import contextlib
import io
import os
import select
import subprocess
import sys
import tempfile
import time

import meshcat

from cpbc.errors import CpbcError


class MeshcatServer:
    """A loopback meshcat server in a child process; use as a context manager.

    Args:
        timeout: seconds to wait for the server to announce itself.
    """

    def __init__(self, timeout: float = 30.0) -> None:
        self.timeout = timeout
        self.zmq_url = ""
        self.web_url = ""
        self._proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> MeshcatServer:
        self._log = tempfile.TemporaryFile()
        self._proc = subprocess.Popen(
            [sys.executable, "-u", "-m", "cpbc.viewer.loopback"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._log,
        )
        assert self._proc.stdout is not None
        fd = self._proc.stdout.fileno()
        deadline = time.monotonic() + self.timeout
        buffer = b""
        while not (self.zmq_url and self.web_url):
            left = deadline - time.monotonic()
            ready = select.select([fd], [], [], max(left, 0.0))[0] if left > 0 else []
            chunk = os.read(fd, 4096) if ready else b""
            if not chunk:
                self.close()
                raise CpbcError(f"the meshcat server did not start:\n{self._log_text()}")
            buffer += chunk
            for line in buffer.decode(errors="replace").splitlines():
                if line.startswith("zmq_url="):
                    self.zmq_url = line.split("=", 1)[1].strip()
                elif line.startswith("web_url="):
                    self.web_url = line.split("=", 1)[1].strip()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _log_text(self) -> str:
        try:
            self._log.seek(0)
            return self._log.read().decode(errors="replace")[-2000:]
        except (OSError, ValueError):
            return ""

    @property
    def pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    def visualizer(self) -> meshcat.Visualizer:
        """A Visualizer connected to this server (meshcat's URL banner suppressed)."""
        with contextlib.redirect_stdout(io.StringIO()):
            return meshcat.Visualizer(zmq_url=self.zmq_url)

    def close(self) -> None:
        """Stop the server process (only the one this object started)."""
        proc, self._proc = self._proc, None
        if proc is not None:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(timeout=10)
            if proc.stdout is not None:
                proc.stdout.close()
        if hasattr(self, "_log"):
            self._log.close()
            del self._log
