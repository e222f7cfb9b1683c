"""Proposition 3.11 and Theorem 3.13 on the toy cascade: U̇ as stated, both states and the
virtual control inside their a-priori bounds, and the refusal of z2 outside (−a2, b2)."""

from __future__ import annotations

import numpy as np
import pytest
from part1_checks import closed_loop, numeric_rate, split
from scipy.integrate import solve_ivp
from toy_cascades import ToyCascade, phi

from cpbc.backstepping import (
    DesignError,
    Growth,
    OutsideDomainError,
    RationalBarrier,
    TwoConstraintLaw,
    virtual_control,
)

DELTA = 0.4
B1 = RationalBarrier(0.5, 0.8, 0.3)


def _growth() -> Growth:
    """Ψ1, Ψ2, Ω of the toy over −(a1+Δ) < ξ1 < b1+Δ (sech² ≤ 1, |tanh| ≤ 1)."""
    xm = max(B1.a, B1.b) + DELTA
    return Growth(psi1=DELTA * phi(xm), psi2=1.0 + 0.5 * (xm * xm + xm * DELTA + DELTA**2),
                  omega=0.5)


def _law(m: int, a2: float | None = None) -> TwoConstraintLaw:
    if m == 1:
        return TwoConstraintLaw(ToyCascade(1, DELTA), B1, c1=2.0, growth=_growth())
    bar = _law(1).alpha2_bound  # the first step is the same for m = 1 and 2
    a2 = a2 if a2 is not None else 1.05 * bar
    return TwoConstraintLaw(ToyCascade(2, DELTA), B1, c1=2.0, growth=_growth(),
                            barrier2=RationalBarrier(a2, a2, 0.5), c2=3.0)


def test_alpha2_bound_is_the_printed_formula() -> None:
    g = _growth()
    y_v = 0.25 * (B1.a + B1.b) ** 3 / (B1.a + B1.b + 2 * np.sqrt(B1.a * B1.b))
    assert _law(1).alpha2_bound == pytest.approx(
        2.0 * max(B1.a, B1.b) + g.omega + g.psi1 + y_v * g.psi2 / B1.k, rel=1e-12
    )


def test_lyapunov_rate_is_the_theorems() -> None:
    """d/dt U (3.106) along the closed loop equals −W − c1z1²/Γ1 − c2z2²/Γ2 (3.121)."""
    law = _law(2)
    rhs = closed_loop(law, 1)
    rng = np.random.default_rng(4)
    b2 = law.barrier2
    assert b2 is not None
    for _ in range(25):
        x = (float(rng.uniform(-2, 2)),)
        xi1 = float(rng.uniform(-0.45, 0.75)) + law.cascade.first_step(x, 0.0).alpha1
        a2 = virtual_control(law.cascade.first_step(x, xi1), B1, 2.0, xi1).alpha2
        xi = (xi1, a2 + float(rng.uniform(0.9 * b2.lower, 0.9 * b2.upper)))
        s = np.array([*x, *xi])
        got = numeric_rate(lambda p: law.lyapunov(*split(p, 1)), s, rhs(0.0, s), h=1e-7)
        assert got == pytest.approx(law.lyapunov_rate(x, xi), rel=1e-5, abs=1e-8)
        assert law.lyapunov_rate(x, xi) <= 0.0


@pytest.mark.parametrize("xi0", [(0.75, 0.0), (-0.45, 1.0), (0.7, -1.0)])
def test_both_states_stay_in_their_bounds(xi0: tuple[float, float]) -> None:
    law = _law(2)
    assert law.conditions_hold
    x0 = (1.2,)
    s0 = [*x0, xi0[0] + law.cascade.first_step(x0, 0.0).alpha1, xi0[1]]
    sol = solve_ivp(closed_loop(law, 1), (0, 25), s0, method="LSODA", rtol=1e-9, atol=1e-11)
    (lo1, hi1), (lo2, hi2) = law.xi_bounds()
    assert lo1 < sol.y[1].min() and sol.y[1].max() < hi1
    assert lo2 < sol.y[2].min() and sol.y[2].max() < hi2
    assert np.abs(sol.y[:, -1]).max() < 1e-3


def test_virtual_control_of_prop_3_11_is_bounded() -> None:
    """m = 1: |v| < ᾱ2 along a run from the edge of D (3.105)."""
    law = _law(1)
    x0 = (-2.0,)
    s0 = [*x0, 0.79 + law.cascade.first_step(x0, 0.0).alpha1]
    sol = solve_ivp(closed_loop(law, 1), (0, 20), s0, method="LSODA", rtol=1e-9, atol=1e-11)
    v = np.array([law.control((s[0],), (s[1],)) for s in sol.y.T])
    assert np.abs(v).max() < law.alpha2_bound
    assert np.abs(sol.y[:, -1]).max() < 1e-3


def test_z2_outside_its_interval_is_refused() -> None:
    law = _law(2)
    x = (0.3,)
    xi1 = law.cascade.first_step(x, 0.0).alpha1
    a2 = virtual_control(law.cascade.first_step(x, xi1), B1, 2.0, xi1).alpha2
    assert law.barrier2 is not None
    with pytest.raises(OutsideDomainError) as err:
        law.control(x, (xi1, a2 + law.barrier2.upper + 1e-9))
    assert err.value.variable == "z2"


def test_conditions_and_constants() -> None:
    bar = _law(1).alpha2_bound
    assert not _law(2, a2=0.5 * bar).conditions_hold  # a2 < ᾱ2 breaks (3.129)
    with pytest.raises(DesignError, match="psi1"):
        Growth(psi1=-1.0, psi2=0.0, omega=0.0)
    with pytest.raises(DesignError, match="barrier2"):
        TwoConstraintLaw(ToyCascade(2), B1, c1=1.0, growth=_growth())
