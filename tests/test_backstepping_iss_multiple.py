"""Theorem 4.4 on a toy system with an ISS x-subsystem (m = 3): the coordinates (4.8) are the
successive derivatives of z1, the z-loop is ż = Az (4.14), and the bounds (4.18)/(4.19) hold
from every vertex of the box and are attained by one."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from toy_chains import Stable

from cpbc.backstepping import IssClfLaw, companion
from cpbc.backstepping.iss_multiple import StrictFeedbackIss, iss_bounds

CASCADE = StrictFeedbackIss(Stable(3, delta=0.3))
LAW = IssClfLaw(CASCADE, (6.0, 11.0, 6.0))  # poles −1, −2, −3


def _rhs(t: float, s: np.ndarray) -> list[float]:
    x, xi = (float(s[0]),), tuple(float(v) for v in s[1:])
    dx, dxi = CASCADE.system.dynamics(x, xi, LAW.control(x, xi))
    return [*dx, *dxi]


def _start(x0: float, z0) -> np.ndarray:
    return np.array([x0, *CASCADE.state_from_coordinates((x0,), z0)], dtype=float)


def test_coordinates_are_successive_derivatives() -> None:
    rng = np.random.default_rng(9)
    h = 1e-6
    for _ in range(10):
        s = _start(float(rng.uniform(-3, 3)), tuple(rng.uniform(-1, 1, 3)))
        sdot = np.array(_rhs(0.0, s))
        z = CASCADE.z_coordinates((s[0],), tuple(s[1:]))

        def zi(p: np.ndarray, i: int) -> float:
            return float(CASCADE.z_coordinates((p[0],), tuple(p[1:]))[i])

        rates = [(zi(s + h * sdot, i) - zi(s - h * sdot, i)) / (2 * h) for i in range(3)]
        assert rates[:2] == pytest.approx(list(z[1:]), rel=1e-6, abs=1e-7)
        u = LAW.control((s[0],), tuple(s[1:]))
        assert rates[2] == pytest.approx(u + CASCADE.drift((s[0],), tuple(s[1:])), rel=1e-6)
        assert rates[2] == pytest.approx(-6 * z[0] - 11 * z[1] - 6 * z[2], rel=1e-6, abs=1e-7)


def test_z_loop_is_linear_and_bounds_hold() -> None:
    box = (0.2, 0.5, 1.0)
    bounds = iss_bounds(LAW, box)
    a = companion(LAW.c)
    peaks_z = np.zeros(3)
    for signs in itertools.product((-1, 1), repeat=3):
        z0 = np.array(signs) * box
        for x0 in (-2.0 * signs[0],):
            sol = solve_ivp(_rhs, (0, 12), _start(x0, tuple(z0)), rtol=1e-9, atol=1e-11,
                            t_eval=np.linspace(0, 12, 2401))
            zs = np.array([CASCADE.z_coordinates((s[0],), tuple(s[1:])) for s in sol.y.T])
            for k in (0, 700, 2400):
                assert np.allclose(zs[k], expm(a * sol.t[k]) @ z0, atol=1e-7)
            peaks_z = np.maximum(peaks_z, np.abs(zs).max(0))
            xi_peaks = np.abs(sol.y[1:]).max(1)
            assert np.all(xi_peaks <= np.array(bounds.state_bounds) + 1e-9)  # (4.19)
    assert np.all(peaks_z <= np.array(bounds.error_bounds) + 1e-9)  # (4.18)
    assert peaks_z == pytest.approx(bounds.error_bounds, rel=2e-3)  # attained at a vertex
    assert bounds.remainders[0].value == pytest.approx(0.3, rel=1e-5)  # sup |α1| = Δ
