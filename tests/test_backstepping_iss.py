"""Theorem 3.8 on an ISS toy cascade: the z-loop is ż = Az, the gains are validated, and the
overshoot ε of (3.50) is exact (attained from the worst vertex, never exceeded)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from toy_cascades import ToyIssCascade

from cpbc.backstepping import DesignError, IssClfLaw, OutsideDomainError, companion

LAW = IssClfLaw(ToyIssCascade(0.3), (2.0, 3.0))  # s² + 3s + 2: eigenvalues −1, −2


def _run(x0: float, z0: tuple[float, float], t_end: float = 12.0):
    """Start at x0 with ξ chosen so that z(0) = z0."""
    cas = LAW.cascade
    xi1 = z0[0] - cas.delta * np.tanh(x0)
    xi2 = z0[1] - (cas.z_coordinates((x0,), (xi1, 0.0))[1])
    ts = np.linspace(0, t_end, 1201)

    def rhs(t: float, s: np.ndarray) -> list[float]:
        u = LAW.control((s[0],), (s[1], s[2]))
        return [-s[0] + s[1], s[2], u]

    sol = solve_ivp(rhs, (0, t_end), [x0, xi1, xi2], t_eval=ts, rtol=1e-10, atol=1e-12)
    return sol


def test_z_loop_is_linear() -> None:
    sol = _run(1.5, (0.2, -0.4))
    a = companion(LAW.c)
    z0 = np.array([0.2, -0.4])
    for t, s in zip(sol.t[::100], sol.y.T[::100], strict=True):
        z = LAW.cascade.z_coordinates((s[0],), (s[1], s[2]))
        assert np.allclose(z, expm(a * t) @ z0, atol=1e-7)
    assert np.abs(sol.y[:, -1]).max() < 1e-3


def test_overshoot_bound_is_attained_and_respected() -> None:
    box = (0.2, 1.0)
    eps = LAW.overshoot(box)
    assert eps > 0.05  # a large z2(0) pushes z1 well past b1
    peaks = []
    for signs in itertools.product((-1, 1), repeat=2):
        z0 = (signs[0] * box[0], signs[1] * box[1])
        sol = _run(0.7, z0)
        z1 = np.array([LAW.cascade.z_coordinates((s[0],), (s[1], s[2]))[0] for s in sol.y.T])
        peaks.append(np.abs(z1).max())
        assert np.abs(sol.y[1]).max() <= LAW.xi1_bound(box) + 1e-9  # (3.50)
    assert max(peaks) == pytest.approx(box[0] + eps, rel=1e-4)


def test_control_is_the_printed_law() -> None:
    x, xi = (0.4,), (0.1, -0.2)
    z = LAW.cascade.z_coordinates(x, xi)
    assert LAW.control(x, xi) == pytest.approx(-2.0 * z[0] - 3.0 * z[1] - LAW.cascade.drift(x, xi))


def test_gains_and_box_are_validated() -> None:
    with pytest.raises(DesignError, match="real, negative and distinct"):
        IssClfLaw(ToyIssCascade(), (1.0, 2.0))  # double eigenvalue −1
    with pytest.raises(DesignError, match="real, negative and distinct"):
        IssClfLaw(ToyIssCascade(), (1.0, 1.0))  # complex pair
    with pytest.raises(DesignError, match="2 gains"):
        IssClfLaw(ToyIssCascade(), (1.0,))
    with pytest.raises(OutsideDomainError):
        LAW.check((0.0,), (0.5, 0.0), box=(0.2, 1.0))
    assert LAW.eigenvalues == pytest.approx([-2.0, -1.0])
