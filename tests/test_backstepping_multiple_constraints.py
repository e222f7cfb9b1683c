"""Theorem 4.12 on toy systems of class (4.1): the jets' α̇_i against finite differences along
the closed loop, the closed-loop z-dynamics (4.32)/(4.51)/(4.75), U̇ against the identity behind
(4.52)/(4.76), and the domain check (4.83)."""

from __future__ import annotations

import numpy as np
import pytest
from toy_chains import NonAffine, Planar

from cpbc.backstepping import LogBarrier, OutsideDomainError
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.strict_feedback import StrictFeedback, nominal_jets

State = tuple[float, ...]


def _law(system: StrictFeedback) -> MultipleConstraintLaw:
    m = system.m
    c = (2.0, 3.0, 1.5, 2.5)[:m]
    barriers = tuple(LogBarrier(b, w) for b, w in
                     ((0.8, 0.5), (2.5, 1.3), (9.0, 0.7), (30.0, 2.0))[:m])
    return MultipleConstraintLaw(system, c, barriers)


SYSTEMS = [NonAffine(2), NonAffine(3), NonAffine(4), Planar(3)]
IDS = ["nonaffine-m2", "nonaffine-m3", "nonaffine-m4", "planar-m3"]


def _states(law: MultipleConstraintLaw, rng: np.random.Generator, n: int = 12):
    """Random (x, ξ) with every z_i at most 80 % of its bound."""
    out = []
    for _ in range(n):
        x = tuple(float(v) for v in rng.uniform(-2, 2, law.system.n))
        z = tuple(float(rng.uniform(-0.8, 0.8)) * k for k in law.bounds)
        out.append((x, tuple(float(v) for v in law.state_from_errors(x, z))))
    return out


def _rhs(law: MultipleConstraintLaw):
    n = law.system.n

    def rhs(s: np.ndarray) -> np.ndarray:
        x, xi = tuple(s[:n]), tuple(s[n:])
        dx, dxi = law.system.dynamics(x, xi, float(law.control(x, xi)))
        return np.array([*dx, *dxi])

    return rhs


def _rate(fun, s: np.ndarray, sdot: np.ndarray, h: float = 1e-6) -> float:
    return (fun(s + h * sdot) - fun(s - h * sdot)) / (2 * h)


@pytest.mark.parametrize("system", SYSTEMS, ids=IDS)
def test_each_alpha_rate_is_exact_along_the_closed_loop(system: StrictFeedback) -> None:
    """α_{i+1} = −c_i z_i − f_i + α̇_i (− the barrier term (4.30) for i = 1), so the law's α̇_i
    must be d/dt α_i along the closed loop."""
    law = _law(system)
    n, m = system.n, system.m
    rng = np.random.default_rng(4)
    for x, xi in _states(law, rng):
        s = np.array([*x, *xi])
        sdot = _rhs(law)(s)
        t = law.terms(x, xi)
        f = system.drifts(x, xi)
        alpha_next = [*t.alpha[1:], t.u]
        k1, w1 = law.bounds[0], law.weights[0]
        alpha_next[0] += (k1**2 - t.z[0] ** 2) * system.t_over_z(x, xi[0]) / w1
        for i in range(m):
            want = _rate(lambda p, i=i: float(law.terms(p[:n], p[n:]).alpha[i]), s, sdot)
            got = alpha_next[i] + law.c[i] * t.z[i] + f[i]
            assert got == pytest.approx(want, rel=1e-6, abs=1e-6 * (1 + abs(want))), (i, got, want)


@pytest.mark.parametrize("system", SYSTEMS, ids=IDS)
def test_closed_loop_error_dynamics(system: StrictFeedback) -> None:
    """ż1 = −c1 z1 − (K1² − z1²)(T/z1)/κ1 + z2, ż_i = −c_i z_i + z_{i+1}, ż_m = −c_m z_m."""
    law = _law(system)
    n, m = system.n, system.m
    rng = np.random.default_rng(5)
    for x, xi in _states(law, rng):
        s = np.array([*x, *xi])
        sdot = _rhs(law)(s)
        z = law.errors(x, xi)
        k1, w1 = law.bounds[0], law.weights[0]
        want = [-law.c[0] * z[0] - (k1**2 - z[0] ** 2) * system.t_over_z(x, xi[0]) / w1]
        want += [-law.c[i] * z[i] for i in range(1, m)]
        for i in range(m - 1):
            want[i] += z[i + 1]
        for i in range(m):
            got = _rate(lambda p, i=i: float(law.errors(p[:n], p[n:])[i]), s, sdot)
            assert got == pytest.approx(want[i], rel=1e-6, abs=1e-6 * (1 + abs(want[i])))


@pytest.mark.parametrize("system", SYSTEMS, ids=IDS)
def test_lyapunov_rate_is_the_identity_of_the_proof(system: StrictFeedback) -> None:
    law = _law(system)
    n = system.n
    rng = np.random.default_rng(6)
    for x, xi in _states(law, rng):
        s = np.array([*x, *xi])
        got = _rate(lambda p: law.lyapunov(tuple(p[:n]), tuple(p[n:])), s, _rhs(law)(s), h=1e-7)
        want = law.lyapunov_rate(x, xi)
        assert got == pytest.approx(want, rel=1e-5, abs=1e-7)


def test_nominal_jets_are_successive_derivatives() -> None:
    """With u = 0 the jets' coefficients are the time derivatives of (x, ξ) along (4.1)."""
    system = Planar(3)
    rng = np.random.default_rng(7)
    x, xi = tuple(rng.uniform(-1, 1, 2)), tuple(rng.uniform(-1, 1, 3))
    xj, yj = nominal_jets(system, x, xi, 3)

    def rhs(s: np.ndarray) -> np.ndarray:
        dx, dxi = system.dynamics(tuple(s[:2]), tuple(s[2:]), 0.0)
        return np.array([*dx, *dxi])

    s = np.array([*x, *xi])
    for k in range(1, 3):  # d/dt of the k-th derivative is the (k+1)-th
        for j, jet in enumerate((*xj, *yj)):
            def kth(p: np.ndarray, j: int = j, k: int = k) -> float:
                a, b = nominal_jets(system, tuple(p[:2]), tuple(p[2:]), 3)
                return float((*a, *b)[j].derivative(k))

            assert jet.derivative(k + 1) == pytest.approx(_rate(kth, s, rhs(s)), rel=1e-6,
                                                            abs=1e-7)


def test_domain_check_and_inverse_map() -> None:
    law = _law(NonAffine(3))
    x = (0.7,)
    z = (0.3, -1.0, 4.0)
    xi = law.state_from_errors(x, z)
    assert law.check(x, xi).z == pytest.approx(z, abs=1e-12)
    bad = law.state_from_errors(x, (0.3, -2.5, 4.0))  # |z2| = K2
    with pytest.raises(OutsideDomainError) as err:
        law.check(x, bad)
    assert err.value.variable == "z2"
    assert np.isfinite(law.control(x, bad))  # the law itself has no pole there
    assert law.lyapunov(x, bad) == np.inf
    with pytest.raises(DesignError, match="m = 3"):
        MultipleConstraintLaw(NonAffine(3), (1.0, 1.0), law.barriers[:2])


def test_grid_evaluation_matches_pointwise() -> None:
    law = _law(NonAffine(3))
    rng = np.random.default_rng(8)
    xs = rng.uniform(-3, 3, 50)
    xis = [rng.uniform(-0.5, 0.5, 50) for _ in range(3)]
    grid = law.terms([xs], xis)
    for k in range(50):
        one = law.terms([float(xs[k])], [float(v[k]) for v in xis])
        assert grid.u[k] == pytest.approx(one.u, rel=1e-12)
        assert np.allclose([a[k] for a in grid.alpha], one.alpha, rtol=1e-12)
