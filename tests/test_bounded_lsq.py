"""The compiled bounded least squares of the brakes (cpbc.kernels.bounded_lsq) against SciPy's
BVLS and against its own optimality conditions, on random problems of the brakes' sizes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from cpbc.kernels.bounded_lsq import bounded_least_squares


def _problem(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    n = int(rng.integers(1, 8))
    m = n + int(rng.integers(0, 2))  # the aimed brake adds one row
    a = rng.normal(size=(m, n)) * rng.uniform(0.1, 10.0, size=n)
    target = rng.normal(size=m) * 10.0
    limit = rng.uniform(0.1, 5.0, size=n)
    lower, upper = -limit, limit.copy()
    if rng.random() < 0.2:
        lower[0] = -np.inf  # a joint without a limit
    if rng.random() < 0.2:
        lower[-1] = upper[-1] - 0.3 * limit[-1]  # a box narrowed by a rate limit
    return a, target, lower, upper


def test_it_finds_scipys_minimum_inside_the_box() -> None:
    rng = np.random.default_rng(7)
    for _ in range(500):
        a, target, lower, upper = _problem(rng)
        z = np.empty(a.shape[1])
        freed = bounded_least_squares(a, target, lower, upper, z)
        assert freed >= 0  # ended on its optimality test, not its cap
        assert np.all(z >= lower) and np.all(z <= upper)
        ref = lsq_linear(a, target, bounds=(lower, upper), method="bvls", tol=1e-14).x
        assert np.linalg.norm(a @ z - target) <= np.linalg.norm(a @ ref - target) + 1e-9


def test_its_answer_meets_the_optimality_conditions() -> None:
    rng = np.random.default_rng(8)
    for _ in range(300):
        a, target, lower, upper = _problem(rng)
        z = np.empty(a.shape[1])
        bounded_least_squares(a, target, lower, upper, z)
        downhill = a.T @ (target - a @ z)  # minus the gradient of ½‖a z − t‖²
        scale = 1e-8 * (1.0 + np.abs(a.T @ target).max())
        inside = (z > lower) & (z < upper)
        assert np.all(np.abs(downhill[inside]) <= scale)
        assert np.all(downhill[z <= lower] <= scale)  # moving up would not help
        assert np.all(downhill[z >= upper] >= -scale)  # moving down would not help


@pytest.mark.parametrize("inside", [True, False])
def test_an_unconstrained_minimum_is_returned_as_it_is(inside: bool) -> None:
    a = np.array([[2.0, 0.0], [0.0, 4.0]])
    target = np.array([1.0, -2.0])
    z = np.empty(2)
    bound = 10.0 if inside else 0.25
    bounded_least_squares(a, target, np.full(2, -bound), np.full(2, bound), z)
    expected = np.array([0.5, -0.5]) if inside else np.array([0.25, -0.25])
    assert np.allclose(z, expected, atol=1e-14)
