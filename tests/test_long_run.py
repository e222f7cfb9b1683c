"""Long runs keep memory bounded: the log never holds more than ``max_log_samples`` samples,
decimating itself on a uniform grid, so its size does not grow with the duration. (The full
10-minute, 1 kHz run is in tools/reliability_report.py; here short runs show the scaling.)"""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints import ConstraintSet, joint_rate_limit
from cpbc.controllers import BPBC, Power
from cpbc.errors import CpbcError
from cpbc.model import RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings, run_mujoco
from cpbc.simulation.trajectory import TrajectoryLog


def fill(log: TrajectoryLog, count: int, n: int = 2) -> None:
    row = np.zeros(n)
    for k in range(count):
        log.record(k * 0.001, float(k), row + k, row, row, row, force=(k == count - 1))


@pytest.mark.parametrize("count", [50, 1_000, 20_000])
def test_bounded_log_holds_at_most_its_limit_on_a_uniform_grid(count: int) -> None:
    log = TrajectoryLog(2, count, every=1, limit=100)
    fill(log, count)
    t, x, _, _, _, v = log.arrays()
    assert len(t) <= 100
    assert t[0] == 0.0 and t[-1] == pytest.approx((count - 1) * 0.001)  # first and last kept
    spacing = np.diff(t[:-1])
    np.testing.assert_allclose(spacing, spacing[0])  # a uniform grid (the last is forced)
    np.testing.assert_array_equal(v, x[:, 0])  # rows stay together
    assert log.every == max(1, round(spacing[0] / 0.001))


def test_log_memory_does_not_grow_with_the_run() -> None:
    sizes = []
    for count in (1_000, 10_000, 100_000):
        log = TrajectoryLog(7, count, limit=500)
        fill(log, count, n=7)
        sizes.append(log.nbytes)
    assert sizes[0] == sizes[1] == sizes[2]
    assert sizes[0] <= 500 * (4 * 7 + 2) * 8


def test_unbounded_log_grows_as_before() -> None:
    log = TrajectoryLog(2, 10)
    fill(log, 1_000)
    assert len(log.arrays()[0]) == 1_000


def test_ten_minutes_at_1_khz_fit_the_default_cap() -> None:
    """600 001 samples of a 7-joint arm would take 144 MB; the default cap keeps ≤ 24 MB."""
    steps = 600_001
    settings = LoopSettings(600.0, InputBounds(0.001))
    log = TrajectoryLog(7, steps, settings.log_every, settings.max_log_samples)
    assert log.nbytes <= settings.max_log_samples * (4 * 7 + 2) * 8 <= 25e6


def test_max_log_samples_is_checked() -> None:
    with pytest.raises(CpbcError, match="max_log_samples"):
        LoopSettings(1.0, InputBounds(0.001), max_log_samples=1)


def test_closed_loop_log_size_is_independent_of_duration(absolute_model: RobotModel,
                                                         planar_path) -> None:
    rates = ConstraintSet(2, velocity=[joint_rate_limit([0.3, 0.2], ["t1", "t2"])])
    law = BPBC(absolute_model, np.array([np.pi, np.pi]), rates, [2, 10], [4, 20], 1, 1,
               Power(0.2))
    plant = MujocoPlant.from_file(planar_path, PlantSettings(0.001, "Euler"))
    out = {}
    for duration in (1.0, 4.0):
        traj = run_mujoco(plant, law, absolute_model.coordinates, np.zeros(2), np.zeros(2),
                          LoopSettings(duration, InputBounds(0.001), max_log_samples=256))
        assert traj.outcome == "completed"
        assert traj.control_steps == round(duration / 0.001) + 1
        assert traj.time[-1] == pytest.approx(duration)
        out[duration] = traj
    a, b = out[1.0], out[4.0]
    assert len(a.time) <= 256 and len(b.time) <= 256
    assert a.position.nbytes == b.position.nbytes or abs(len(a.time) - len(b.time)) <= 1
    # the coarser grid of the long run samples the same trajectory
    common = np.intersect1d(np.round(a.time, 9), np.round(b.time, 9))
    assert common.size > 10
    ia = np.searchsorted(np.round(a.time, 9), common)
    ib = np.searchsorted(np.round(b.time, 9), common)
    np.testing.assert_allclose(a.position[ia], b.position[ib], atol=1e-12)
