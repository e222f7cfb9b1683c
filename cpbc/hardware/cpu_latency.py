"""The kernel's CPU latency request held while a motion runs (Linux's PM QoS,
``/dev/cpu_dma_latency``), as cyclictest holds it while it measures.

Between the robot's states the control loop blocks for most of a cycle. An idle core may
drop into a deep idle state, or, on a virtual machine, halt the virtual CPU; waking from
there costs the next cycle tens of microseconds before the controller runs, and the cycle
itself runs slower on caches gone cold. A request of 0 µs keeps every core in its shallowest
idle state (polling) for as long as the request is held. On this project's 2-core virtual
machine it took the lock-step reach past the ball, sleeping 0.8 ms before each read as a
blocking read does, from a p99.9 of 259–266 µs to 181–211 µs, and the franky-sim
campaign's cycles from a p99.9 of 303–361 µs to 243–278 µs (docs/hardware.md, "The campaign
on franky-sim"). The price
there: a host sometimes deschedules a virtual CPU that polls, for a few milliseconds, and
franky-sim's states queue meanwhile (2–3 lost, in a few motions of a campaign; none without
the request). On the robot's own computer, with no hypervisor, 0 µs is the usual real-time
setting.

The request is the kernel's, not the process's scheduling: it needs write access to the
device (root, or a udev rule granting it to the robot's user). Without it the motion runs
all the same, and the run says why the request was not held.
"""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from cpbc.errors import ParameterError

#: Linux's device for a process's CPU latency request (Documentation/power/pm_qos_interface).
DEVICE = "/dev/cpu_dma_latency"


@dataclass(frozen=True)
class LatencyRequest:
    """What became of a request: ``held`` with the target in µs, or not, and why."""

    target_us: int
    held: bool
    reason: str = ""


@contextmanager
def cpu_latency(target_us: float | None,
                device: str = DEVICE) -> Iterator[LatencyRequest | None]:
    """Hold a CPU latency request of ``target_us`` microseconds for the block: the device
    stays open, the kernel keeps every core within that wake-up latency, and the request ends
    when the block does. A device that cannot be opened leaves the request not held, its
    reason given; nothing else fails. None asks for no request (the block gets None). A
    ParameterError names a target that is not a whole number of µs ≥ 0 that fits the
    kernel's 32 bits (:func:`latency_target`)."""
    if target_us is None:
        yield None
        return
    target = latency_target(target_us, "target_us")
    fd, reason = _request(device, target)
    try:
        yield LatencyRequest(target, fd is not None, reason)
    finally:
        if fd is not None:
            os.close(fd)  # the request ends with the file


def latency_target(value: float, name: str) -> int:
    """``value`` as the kernel takes a request: a whole number of µs ≥ 0 in 32 bits; else a
    ParameterError naming ``name``."""
    if not (math.isfinite(value) and 0 <= value < 2**31 and value == int(value)):
        raise ParameterError(name, f"{name}: the CPU latency request is a whole number of "
                             f"µs from 0 to 2³¹ − 1, got {value}")
    return int(value)


def _request(device: str, target: int) -> tuple[int | None, str]:
    """The device open with ``target`` written to it, or None and why not."""
    try:
        fd = os.open(device, os.O_WRONLY)
    except OSError as exc:
        fix = (" (run as root, or grant the robot's user write access to it with a udev "
               "rule)" if isinstance(exc, PermissionError) else "")
        return None, f"cannot open {device}: {exc.strerror}{fix}"
    try:
        os.write(fd, struct.pack("i", target))
    except OSError as exc:
        os.close(fd)
        return None, f"{device} refused {target} µs: {exc.strerror}"
    return fd, ""


def current_target(device: str = DEVICE) -> int:
    """The kernel's CPU latency target now, over every request held [µs]."""
    with open(device, "rb") as f:
        return int(struct.unpack("i", f.read(4))[0])
