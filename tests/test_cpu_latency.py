"""cpbc.hardware.cpu_latency: the kernel's CPU latency request held for a block, through
Linux's own device where this machine lets the process write it."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from cpbc.errors import ParameterError
from cpbc.hardware.cpu_latency import DEVICE, cpu_latency, current_target
from cpbc.hardware.motion import MotionSettings

WRITABLE = os.access(DEVICE, os.W_OK)


def _open_here(device: str) -> int:
    """How many of this process's file descriptors are open on ``device``."""
    target = os.path.realpath(device)
    found = 0
    for fd in os.listdir("/proc/self/fd"):
        try:
            found += os.readlink(f"/proc/self/fd/{fd}") == target
        except OSError:  # the listing's own descriptor, closed by now
            continue
    return found


@pytest.mark.skipif(not WRITABLE, reason=f"{DEVICE} is not writable by this user")
def test_a_request_is_held_for_the_block_and_ends_with_it() -> None:
    before = _open_here(DEVICE)
    with cpu_latency(3) as request:
        assert request.held and request.target_us == 3 and request.reason == ""
        # the kernel's target is the least over every request held (other processes too)
        assert current_target() <= 3
        assert _open_here(DEVICE) == before + 1
    assert _open_here(DEVICE) == before  # closed: the request is gone


def test_a_device_that_cannot_be_opened_leaves_the_request_not_held(tmp_path: Path) -> None:
    ran = []
    for device, why in ((tmp_path / "none", "No such file"), (tmp_path, "Is a directory")):
        with cpu_latency(0, str(device)) as request:
            ran.append(device)
            assert not request.held
            assert str(device) in request.reason and why in request.reason, request.reason
    assert len(ran) == 2  # the block ran all the same


@pytest.mark.parametrize("target", [-1, 1.5, math.nan, math.inf, 2**31])
def test_a_target_that_is_no_whole_number_of_us_is_refused(target: float) -> None:
    with pytest.raises(ParameterError, match="target_us") as found:
        with cpu_latency(target, "/nonexistent"):
            pytest.fail("the block must not run")
    assert found.value.parameter == "target_us"
    with pytest.raises(ParameterError, match="cpu_latency"):
        MotionSettings(1.0, cpu_latency=target)  # type: ignore[arg-type]


def test_none_asks_for_no_request() -> None:
    before = _open_here(DEVICE) if os.path.exists(DEVICE) else 0
    with cpu_latency(None) as request:
        assert request is None
        assert (_open_here(DEVICE) if os.path.exists(DEVICE) else 0) == before
