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


# -- margins in comparable units ------------------------------------------------------------------
def test_margins_become_distances_to_the_bounds_in_each_types_unit() -> None:
    from cpbc.constraints import KineticEnergyLimit, LinearLimit, RateLimit
    from cpbc.constraints.constraint_set import ConstraintSet
    from cpbc.results.margin_types import physical_history, types_of, worst_by_type

    limit = LinearLimit(np.eye(2), [-1.0, -2.0], [3.0, 2.0], ["p1", "p2"])
    rate = RateLimit(np.eye(2), [0.5, 2.0], ["r1", "r2"])
    energy = KineticEnergyLimit.__new__(KineticEnergyLimit)  # no model: values given below
    energy.names, energy.limit = ("ke",), 4.0
    monitor = ConstraintSet(2, [limit], [rate, energy])
    assert types_of(monitor) == ("position", "position", "rate", "rate", "energy")
    x = np.array([[0.0, 1.5], [2.9, -2.5]])  # the second sample is past p2's lower bound
    dx = np.array([[0.1, -1.0], [-0.6, 0.0]])  # … and past r1's bound
    raw = np.column_stack([limit.values_along(x), rate.values_along(x, dx), [3.0, -1.0]])
    m = physical_history(monitor, raw)
    np.testing.assert_allclose(m[:, :2], [[1.0, 0.5], [0.1, -0.5]], atol=1e-12)  # rad
    np.testing.assert_allclose(m[:, 2:4], [[0.4, 1.0], [-0.1, 2.0]], atol=1e-12)  # rad/s
    np.testing.assert_allclose(m[:, 4], [3.0, -1.0])  # J, as they are
    mins = dict(zip(monitor.names, m.min(axis=0).tolist(), strict=True))
    worst = worst_by_type(mins, dict(zip(monitor.names, types_of(monitor), strict=True)))
    assert [(w.type, w.constraint, w.unit) for w in worst] == [
        ("position", "p2", "rad"), ("rate", "r1", "rad/s"), ("energy", "ke", "J")]


def test_obstacle_margin_is_the_distance_to_its_surface() -> None:
    from cpbc.constraints import PointOutsideSphere
    from cpbc.constraints.margins import CLEARANCE

    c = PointOutsideSphere.__new__(PointOutsideSphere)
    c.radius, c.names = 0.5, ("obstacle",)
    d = np.array([[0.2], [0.5], [0.7], [3.0]])  # distances from the centre [m]
    assert c.margin_type is CLEARANCE
    np.testing.assert_allclose(c.margins(d**2 - 0.25), d - 0.5, atol=1e-15)
