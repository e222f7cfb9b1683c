"""How a measurement was made: the command, the date, the code and the machine's load.

The benchmark and the verification campaign put this record into the documents they write,
so that a table rendered from a document can say where its numbers came from.
"""

from __future__ import annotations

import os
import platform
import subprocess
import time
from pathlib import Path

from cpbc import __version__

REPOSITORY = Path(__file__).resolve().parents[1]


def commit() -> str | None:
    """``git describe --always --dirty`` of the checkout cpbc runs from, or None outside one."""
    try:
        done = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=REPOSITORY,
                              capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return (done.stdout.strip() or None) if done.returncode == 0 else None


def load_average() -> list[float] | None:
    """The 1, 5 and 15 minute load averages (as ``uptime`` prints them), where the OS has them."""
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def provenance(command: str) -> dict[str, object]:
    """The record: command, UTC date, cpbc version and commit, Python, cores, load average."""
    return {"command": command, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "cpbc": __version__, "commit": commit(), "python": platform.python_version(),
            "cores": os.cpu_count(), "load_average": load_average()}
