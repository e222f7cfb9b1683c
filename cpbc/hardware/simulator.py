"""franky-sim as a robot to drive: the simulator started as a process of its own (in the
same process as pylibfranka its server thread never answers: libfranka's blocking connect
holds the interpreter) on a loopback address, and stopped by its PID."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

from cpbc.errors import CpbcError
from cpbc.model.arms import FRANKA_EXTRA

#: What franky-sim prints once it accepts connections.
READY = "Connect to the server"


def loopback_address(salt: int = 0) -> str:
    """A loopback address of this process's own (another run on the machine may hold
    127.0.0.1's port 1337)."""
    pid = os.getpid() + salt
    return f"127.{pid % 200 + 20}.{(pid // 200) % 250 + 1}.1"


class FrankySim:
    """A running franky-sim (MuJoCo) at ``host``, the FR3 at its start posture, at rest;
    ``cpus``: the cores it may run on (all by default).

    Raises:
        CpbcError: franky-sim is not installed, or did not start within ``timeout`` [s]
            (its output is in the message).
    """

    def __init__(self, host: str, timeout: float = 60.0,
                 cpus: frozenset[int] | None = None) -> None:
        self.host = host
        self.lines: list[str] = []
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}

        def pinned() -> None:  # in the child: the server runs on ``cpus`` only
            if cpus is not None:
                os.sched_setaffinity(0, cpus)

        try:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "franky_sim.run_server", "--simulator", "mujoco",
                 "--hostname", host],
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                preexec_fn=pinned)
        except OSError as exc:
            raise CpbcError(f"cannot start franky-sim: {exc} ({FRANKA_EXTRA})") from None
        ready = threading.Event()

        def watch() -> None:
            assert self.process.stdout is not None
            for line in self.process.stdout:
                self.lines.append(line)
                if READY in line:
                    ready.set()
            ready.set()  # it ended: stop waiting

        threading.Thread(target=watch, daemon=True).start()
        if not ready.wait(timeout) or self.process.poll() is not None:
            self.stop()
            raise CpbcError(f"franky-sim did not start within {timeout:g} s: "
                            f"{''.join(self.lines).strip() or 'no output'}")

    def stop(self) -> None:
        """Kill the simulator by its PID and wait for it (idempotent)."""
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(timeout=10)

    def __enter__(self) -> FrankySim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
