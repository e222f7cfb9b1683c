"""cpbc.kernels.slide: the slide's half-spaces, the law's acceleration and its projection in one
call, against the numpy it replaced in Brakes.slide."""

from __future__ import annotations

import numpy as np

from cpbc.controllers.linalg import solve_spd
from cpbc.kernels.sampled_guard import project_halfspaces
from cpbc.kernels.slide import slide_acceleration


def _numpy_slide(grads: np.ndarray, dx: np.ndarray, phi: np.ndarray, end_floor: np.ndarray,
                 mid_floor: np.ndarray, h: float, c: float, inertia: np.ndarray,
                 push: np.ndarray) -> tuple[np.ndarray, ...]:
    """Brakes.slide's numpy before the kernel (cpbc 5153105), as it read."""
    rate = grads @ dx
    end = end_floor + 0.05 * np.abs(end_floor - phi) + 1e-4 * np.abs(end_floor)
    mid = mid_floor + 0.05 * np.abs(mid_floor - phi) + 1e-4 * np.abs(mid_floor)
    need = np.maximum((end - phi - h * rate) / (c * h * h),
                      8.0 * (mid - phi - 0.5 * h * rate) / (h * h))
    law = solve_spd(inertia, push)
    acc = np.empty(len(dx))
    project_halfspaces(grads, need, law, acc)
    return rate, need, law, acc


def _kernel_slide(grads: np.ndarray, dx: np.ndarray, phi: np.ndarray, end_floor: np.ndarray,
                  mid_floor: np.ndarray, h: float, c: float, inertia: np.ndarray,
                  push: np.ndarray) -> tuple[np.ndarray, ...]:
    m, n = grads.shape
    rate, need, law, acc = np.empty(m), np.empty(m), np.empty(n), np.empty(n)
    slide_acceleration(grads, dx, phi, end_floor, mid_floor, h, c, inertia, push,
                       np.empty((n, n)), rate, need, law, acc)
    return rate, need, law, acc


def _case(rng: np.random.Generator, m: int, n: int) -> tuple:
    a = rng.normal(size=(n, n))
    inertia = a @ a.T + 0.1 * np.eye(n)
    phi = rng.uniform(1e-4, 0.2, m)
    end_floor = phi * rng.uniform(0.3, 1.2, m)
    mid_floor = phi * rng.uniform(0.3, 1.2, m)
    return (rng.normal(size=(m, n)), rng.normal(size=n), phi, end_floor, mid_floor,
            rng.choice([1e-3, 2e-3, 1e-2]), rng.choice([0.5, 0.75, 1.0]), inertia,
            rng.normal(scale=30.0, size=n))


def test_the_kernel_is_the_numpy_it_replaced() -> None:
    """200 random cases (m margins, n joints, D SPD, floors above and below the margins):
    the rates, the half-spaces and the law's acceleration to 1e-12 relative (the solve is
    numba's Cholesky, not LAPACK's) and the projected acceleration as numpy's; where the
    margins are joint limits (orthogonal gradients, one projection meets each) it meets
    every half-space."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        m, n = int(rng.integers(1, 12)), int(rng.integers(2, 8))
        case = _case(rng, m, n)
        want, got = _numpy_slide(*case), _kernel_slide(*case)
        for w, g in zip(want, got, strict=True):
            np.testing.assert_allclose(g, w, rtol=1e-10, atol=1e-9)
    for _ in range(50):
        n = int(rng.integers(2, 8))
        m = int(rng.integers(1, n + 1))
        case = _case(rng, m, n)
        rows = rng.permutation(n)[:m]
        grads = np.eye(n)[rows] * rng.choice([-1.0, 1.0], size=(m, 1))
        _, need, _, acc = _kernel_slide(grads, *case[1:])
        assert np.all(grads @ acc >= need - 1e-9 * (1.0 + np.abs(need)))


def test_a_nan_margin_makes_its_half_space_nan_as_numpy_s_maximum() -> None:
    """A NaN margin (counted as −∞ by the guard's floors) gives NaN r_i, as np.maximum did,
    and the projection stops at it (project_halfspaces): the law's acceleration unmoved."""
    rng = np.random.default_rng(3)
    grads, dx, phi, end_floor, mid_floor, h, c, inertia, push = _case(rng, 4, 3)
    phi[2] = np.nan
    _, need, _, acc = _kernel_slide(grads, dx, phi, end_floor, mid_floor, h, c,
                                    inertia, push)
    assert np.isnan(need[2]) and np.isfinite(need[[0, 1, 3]]).all()
    want = _numpy_slide(grads, dx, phi, end_floor, mid_floor, h, c, inertia, push)
    np.testing.assert_allclose(acc, want[3], rtol=1e-10, atol=1e-9)


def test_an_indefinite_inertia_is_solved_by_elimination() -> None:
    """A D that is not numerically positive definite: the law's acceleration by
    elimination (as solve_spd's LAPACK fallback gave it)."""
    inertia = np.array([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3 and −1
    grads = np.array([[1.0, 0.0]])
    case = (grads, np.zeros(2), np.array([0.1]), np.array([0.05]), np.array([0.05]), 1e-3,
            0.5, inertia, np.array([1.0, -1.0]))
    np.testing.assert_allclose(_kernel_slide(*case)[2], np.linalg.solve(inertia, case[-1]),
                               rtol=1e-12)


def test_the_stopping_point_and_its_margins_are_the_numpy_they_replaced() -> None:
    """The slide's stopping point (``stopping_point``: x + hẋ + c h² a + r|v₁|v₁) is
    Brakes.slide's numpy expression before the kernel to the bit, on 2, 6 and 7 joints; and
    on the Panda among its spheres and joint limits (PredictedMargins.stopping_point_margins,
    one compiled call with the chain's placements) its margins are configuration_margins
    at that point to the bit, at the bench's states and accelerations pushed 10 and 1000
    rad/s² off the law's, with a NaN row where the point is not finite."""
    import math

    from cpbc.bench_arms import panda
    from cpbc.controllers.safeguard import Safeguard, SafeguardSettings
    from cpbc.kernels.slide import stopping_point
    from cpbc.model.input_bounds import InputBounds

    rng = np.random.default_rng(11)
    for n in (2, 6, 7):
        for _ in range(300):
            x, dx, acc = rng.normal(size=n), rng.normal(size=n), 100.0 * rng.normal(size=n)
            h, c, r = float(rng.choice([1e-3, 4e-3])), float(rng.choice([0.5, 1.0])), 0.02
            v1 = dx + h * acc
            expected = x + h * dx + (c * h * h) * acc + (r * math.sqrt(float(v1.dot(v1)))) * v1
            out = np.empty(n)
            stopping_point(x, dx, acc, h, c, r, out)
            np.testing.assert_array_equal(out, expected)

    setup = panda()
    guard = Safeguard(setup.controllers["cpbc"], InputBounds(0.001, setup.torque_limit, None),
                      SafeguardSettings())
    along, nc = guard.acceptance.along, guard.guarded.n_configuration
    for x, dx in setup.states[:32]:
        for push in (10.0, 1000.0):
            acc = push * rng.normal(size=7)
            point = np.empty(7)
            stopping_point(x, dx, acc, 1e-3, 1.0, 0.05, point)
            found = along.stopping_point_margins(x, dx, acc, 1e-3, 1.0, 0.05)
            assert found.shape == (nc,)
            np.testing.assert_array_equal(found, along.configuration_margins(point[None])[0])
    bad = np.array([np.nan] + [0.0] * 6)
    assert np.isnan(along.stopping_point_margins(bad, np.zeros(7), np.zeros(7), 1e-3, 1.0,
                                                 0.05)).all()
