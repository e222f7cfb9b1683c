"""Theorem 3.6 / Proposition 3.2 on a non-affine toy cascade: exact rates, U̇ as the theorem
states it, the bound on ξ1, and the refusal of states outside D."""

from __future__ import annotations

import numpy as np
import pytest
from part1_checks import assert_rates, closed_loop, numeric_rate, split
from scipy.integrate import solve_ivp
from toy_cascades import ToyCascade

from cpbc.backstepping import (
    DesignError,
    LogBarrier,
    NonStrictClfLaw,
    OutsideDomainError,
    RationalBarrier,
    virtual_control,
)


def _law(m: int, barrier=None) -> NonStrictClfLaw:
    barrier = barrier or RationalBarrier(0.5, 0.8, 0.3)
    if m == 1:
        return NonStrictClfLaw(ToyCascade(1), barrier, c1=2.0)
    return NonStrictClfLaw(ToyCascade(2), barrier, c1=2.0, c2=3.0, k2=0.7)


def _states(
    law: NonStrictClfLaw, rng: np.random.Generator, n: int = 25
) -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
    """Random (x, ξ) with z1 well inside the barrier's interval."""
    b = law.barrier
    out: list[tuple[tuple[float, ...], tuple[float, ...]]] = []
    while len(out) < n:
        x = (float(rng.uniform(-2, 2)),)
        z1 = float(rng.uniform(0.9 * b.lower, 0.9 * b.upper))
        xi1 = z1 + law.cascade.first_step(x, 0.0).alpha1
        xi = (xi1,) if law.cascade.m == 1 else (xi1, float(rng.uniform(-1, 1)))
        out.append((x, xi))
    return out


def test_first_step_rates_match_finite_differences() -> None:
    rng = np.random.default_rng(1)
    cas = ToyCascade(2)
    for _ in range(20):
        assert_rates(cas, (float(rng.uniform(-2, 2)),), float(rng.uniform(-1, 1)),
                     float(rng.uniform(-2, 2)))


def test_alpha2_rate_matches_finite_difference_along_the_nominal_flow() -> None:
    law = _law(2)
    rng = np.random.default_rng(2)
    for x, xi in _states(law, rng):
        s = np.array([*x, *xi])
        sdot = closed_loop(law, 1)(0.0, s)  # any ξ̇2 works: α2 depends on (x, ξ1) only

        def a2(p: np.ndarray) -> float:
            xx, xxi = split(p, 1)
            return virtual_control(law.cascade.first_step(xx, xxi[0]), law.barrier, law.c1,
                                   xxi[0]).alpha2

        vc = virtual_control(law.cascade.first_step(x, xi[0]), law.barrier, law.c1, xi[0])
        assert vc.rate(float(sdot[1])) == pytest.approx(numeric_rate(a2, s, sdot), rel=1e-6,
                                                         abs=1e-8)


@pytest.mark.parametrize("m", [1, 2])
@pytest.mark.parametrize("barrier", [RationalBarrier(0.5, 0.8, 0.3), LogBarrier(0.6, 0.2)],
                         ids=["rational", "log"])
def test_lyapunov_rate_is_the_theorems(m: int, barrier) -> None:
    """d/dt U along the closed loop equals −W − c1 z1²/Γ(z1) − c2 k2 z2² (3.18), (3.39)."""
    law = _law(m, barrier)
    rng = np.random.default_rng(3)
    rhs = closed_loop(law, 1)
    for x, xi in _states(law, rng):
        s = np.array([*x, *xi])
        got = numeric_rate(lambda p: law.lyapunov(*split(p, 1)), s, rhs(0.0, s), h=1e-7)
        want = law.lyapunov_rate(x, xi)
        assert want <= 0.0
        assert got == pytest.approx(want, rel=1e-5, abs=1e-8)


def test_closed_loop_keeps_xi1_in_its_bound_and_converges() -> None:
    """From z1(0) near its upper end, ξ1 stays in (−(a1 + Δ), b1 + Δ) (3.26) and → 0."""
    law = _law(2)
    lo, hi = law.xi1_bounds()
    x0 = (-1.5,)
    xi0 = (0.79 + law.cascade.first_step(x0, 0.0).alpha1, 2.0)
    sol = solve_ivp(closed_loop(law, 1), (0, 20), [*x0, *xi0], method="LSODA", rtol=1e-9,
                    atol=1e-11, dense_output=True)
    z1 = [law.errors((s[0],), (s[1], s[2]))[0] for s in sol.y.T]
    assert max(z1) < law.barrier.upper and min(z1) > law.barrier.lower
    assert lo < sol.y[1].min() and sol.y[1].max() < hi
    assert np.abs(sol.y[:, -1]).max() < 1e-3
    u = [law.lyapunov((s[0],), (s[1], s[2])) for s in sol.y.T]
    assert np.all(np.diff(u) <= 1e-9)


def test_state_outside_the_domain_is_refused() -> None:
    law = _law(2)
    x = (0.5,)
    a1 = law.cascade.first_step(x, 0.0).alpha1
    with pytest.raises(OutsideDomainError, match="outside the controller's domain") as err:
        law.control(x, (a1 + 0.8, 0.0))  # z1 = b1 exactly
    assert err.value.variable == "z1" and err.value.upper == pytest.approx(0.8)
    law.control(x, (a1 + 0.79, 0.0))


def test_design_constants_are_validated() -> None:
    with pytest.raises(DesignError, match="c1"):
        NonStrictClfLaw(ToyCascade(1), RationalBarrier(1, 1, 1), c1=-1.0)
    with pytest.raises(DesignError, match="k2"):
        NonStrictClfLaw(ToyCascade(2), RationalBarrier(1, 1, 1), c1=1.0, c2=1.0)
    with pytest.raises(DesignError, match="m = 1"):
        NonStrictClfLaw(ToyCascade(3), RationalBarrier(1, 1, 1), c1=1.0)
    assert _law(1).zero_start_admissible  # a1 = 0.5, b1 = 0.8 > Δ = 0.4
    narrow = NonStrictClfLaw(ToyCascade(1), RationalBarrier(0.3, 1, 1), c1=1.0)
    assert not narrow.zero_start_admissible  # a1 = 0.3 < Δ
