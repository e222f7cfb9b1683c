"""The §4.3 parameter conditions: the generator against the printed list for m = 3, domination
⇒ U̇ ≤ 0 on D, the worst-case sups against sampled α_i, and the invariance test against
simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cpbc.backstepping import (
    ChainSystem,
    IntegratorChainController,
    LogBarrier,
    MultipleConstraintLaw,
)
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.integrator_chain_law import thesis_symbols
from cpbc.backstepping.parameter_constraints import (
    check_parameters,
    domination,
    invariance,
    worst_case,
)

SYSTEM = ChainSystem(0.5 / math.pi, 1.0)
# c1 > K2²/K1² + ½ and ½c2 > K3²/K2² + ½; the weights chosen so that (4.60), (4.78) can hold
DOMINATED = MultipleConstraintLaw(
    SYSTEM, (2.0, 4.0, 1.0), (LogBarrier(2.0, 1.0), LogBarrier(2.0, 2.0), LogBarrier(2.0, 6.0)))


def test_generator_reproduces_the_printed_conditions_for_m3() -> None:
    a1, a2 = 0.9, 0.8
    law = DOMINATED
    (c1, c2, c3), (k2, k4, k6), (k1, k3, k5) = law.c, law.bounds, law.weights
    got = {c.label: c for c in domination(law, (a1, a2))}
    assert set(got) == {"(4.55)", "(4.60)", "(4.77)", "(4.78)"}
    assert (got["(4.55)"].lhs, got["(4.55)"].rhs) == pytest.approx(
        (c1, k4**2 / (k2 * a1) ** 2 + 0.5))
    assert got["(4.60)"].lhs == pytest.approx(k3 * c2 / k4**2)
    assert got["(4.60)"].rhs == pytest.approx(k1 / (k2**2 - (k2 * a1) ** 2))
    # (4.77) with half of c2 (the other half went to (4.60)); printed: c2 ≥ … + ½
    assert (got["(4.77)"].lhs, got["(4.77)"].rhs) == pytest.approx(
        (0.5 * c2, k6**2 / (k4 * a2) ** 2 + 0.5))
    # (4.78): k5 c3/k6² ≥ k3/(2(k4² − (k4 a2)²)), both sides doubled
    assert got["(4.78)"].lhs / 2 == pytest.approx(k5 * c3 / k6**2)
    assert got["(4.78)"].rhs / 2 == pytest.approx(k3 / (2 * (k4**2 - (k4 * a2) ** 2)))
    with pytest.raises(DesignError, match="a1"):
        domination(law, (1.2, 0.5))


def test_domination_makes_udot_non_positive_on_d() -> None:
    assert all(c.holds for c in domination(DOMINATED))
    rng = np.random.default_rng(11)
    n = 4000
    x = [rng.standard_normal(n) * 3.0]
    z = [rng.uniform(-0.999, 0.999, n) * k for k in DOMINATED.bounds]
    xi = DOMINATED.state_from_errors(x, z)
    for k in range(0, n, 20):
        r = DOMINATED.lyapunov_rate((float(x[0][k]),), tuple(float(v[k]) for v in xi))
        assert r <= 0.0


def test_thesis_gains_fail_domination_and_udot_is_positive_somewhere() -> None:
    law = IntegratorChainController().law
    assert not any(c.holds for c in domination(law) if c.label in ("(4.55)", "(4.77)"))
    x, xi = IntegratorChainController.coordinates((-10.0, -1.5, -0.05, -2.5))
    assert law.lyapunov_rate(x, xi) > 0.5  # Fig. 4.1's start: U rises at first


def test_worst_case_bounds_every_sampled_alpha() -> None:
    law = IntegratorChainController().law
    wc = worst_case(law)
    rng = np.random.default_rng(12)
    n = 20000
    x = [np.tan(rng.uniform(-1.57, 1.57, n))]
    z = [rng.uniform(-1, 1, n) * k for k in law.bounds]
    alpha = law.terms(x, law.state_from_errors(x, z)).alpha
    for i in range(3):
        sampled = float(np.abs(alpha[i]).max())
        assert sampled <= wc.alpha[i].value * (1 + 1e-9)
        assert sampled >= 0.9 * wc.alpha[i].value  # the search is not wildly loose
    assert wc.alpha[0].value == pytest.approx(0.25, rel=1e-6)  # c1 π/2


def test_check_reports_each_condition_for_the_thesis_gains() -> None:
    chk = check_parameters(IntegratorChainController().law, (2.5, 12.0, 700.0))
    assert chk.holds("well-posed", "state bound")  # manual tuning (§4.3.6) is met
    assert not chk.theorem_holds
    assert {c.label for c in chk.failed("domination")} >= {"(4.55)", "(4.77)"}
    assert chk.worst.state_bounds[2] < 700.0 < chk.worst.state_bounds[2] + 50.0
    assert "k6 > sup_D |α3|" in chk.table(thesis_symbols)
    with pytest.raises(DesignError, match="limits"):
        check_parameters(IntegratorChainController().law, (2.5, 12.0))


def test_invariance_conditions_keep_every_start_in_d() -> None:
    """With c1 K1 ≥ reach of z2 and no overshoot of the tail, starts on D's edge stay in D."""
    law = MultipleConstraintLaw(SYSTEM, (3.0, 6.0, 4.0),
                                (LogBarrier(2.0, 1.0), LogBarrier(1.5, 1.0), LogBarrier(1.0, 1.0)))
    assert all(c.holds for c in invariance(law))
    rng = np.random.default_rng(13)

    def rhs(t: float, s: np.ndarray) -> list[float]:
        dx, dxi = SYSTEM.dynamics((s[0],), tuple(s[1:]), float(law.control((s[0],), tuple(s[1:]))))
        return [*dx, *dxi]

    for _ in range(4):
        x0 = float(rng.uniform(-20, 20))
        z0 = rng.choice([-1, 1], 3) * 0.999 * np.array(law.bounds)
        s0 = [x0, *law.state_from_errors((x0,), tuple(z0))]
        sol = solve_ivp(rhs, (0, 6), s0, rtol=1e-8, atol=1e-10, t_eval=np.linspace(0, 6, 601))
        z = np.array([law.errors((s[0],), tuple(s[1:])) for s in sol.y.T])
        assert np.all(np.abs(z) < np.array(law.bounds))
