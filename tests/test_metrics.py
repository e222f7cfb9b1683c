"""Status judged from data: converged, stalled, not_settled."""

from __future__ import annotations

import numpy as np

from cpbc.results.metrics import SettleCriteria, judge_status
from cpbc.simulation.trajectory import Trajectory


def trajectory(position: np.ndarray, velocity: np.ndarray, outcome: str = "completed"):
    t = np.linspace(0, 10, len(position))
    z = np.zeros_like(position)
    return Trajectory(t, position, velocity, z, z, np.zeros(len(t)), outcome, 10.0, None, 1.0,
                      len(t), 0, 0, "mujoco")


TARGET = np.array([1.0, 1.0])
CRITERIA = SettleCriteria(position_tolerance=0.01, velocity_tolerance=0.005)


def test_converged_with_settle_time() -> None:
    s = np.linspace(0, 1, 1001)[:, None]
    pos = TARGET * np.minimum(1.0, 2 * s)  # reaches the target at t = 5 s
    vel = np.where(s < 0.5, 0.2, 0.0) * np.ones((1, 2))
    status, settle = judge_status(trajectory(pos, vel), TARGET, CRITERIA)
    assert status == "converged"
    assert 4.9 < settle <= 5.0


def test_stalled_away_from_target() -> None:
    s = np.linspace(0, 1, 1001)[:, None]
    pos = 0.5 * TARGET * np.minimum(1.0, 3 * s)
    vel = np.where(s < 1 / 3, 0.15, 0.0) * np.ones((1, 2))
    status, settle = judge_status(trajectory(pos, vel), TARGET, CRITERIA)
    assert (status, settle) == ("stalled", None)


def test_slow_progress_is_not_a_stall() -> None:
    s = np.linspace(0, 1, 1001)[:, None]
    pos = TARGET * (0.2 + 0.6 * s)  # creeping towards the target at 0.06 rad/s
    vel = np.full_like(pos, 0.004)  # below the rest band, yet the error keeps shrinking
    status, _ = judge_status(trajectory(pos, vel), TARGET, CRITERIA)
    assert status == "not_settled"


def test_moving_at_the_end_is_not_settled() -> None:
    s = np.linspace(0, 1, 1001)[:, None]
    pos = TARGET + 0.001 * np.sin(40 * s)
    vel = 0.04 * np.cos(40 * s) * np.ones((1, 2))
    status, _ = judge_status(trajectory(pos, vel), TARGET, CRITERIA)
    assert status == "not_settled"


def test_outcome_of_the_loop_wins() -> None:
    pos = np.tile(TARGET, (10, 1))
    status, _ = judge_status(trajectory(pos, np.zeros_like(pos), "diverged"), TARGET, CRITERIA)
    assert status == "diverged"
