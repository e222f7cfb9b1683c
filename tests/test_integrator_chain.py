"""§4.4: the integrator chain plant (4.92)–(4.93), the H1 reading of the thesis's constants, and
the runs of Figs 4.1 and 4.2 in continuous time (every constrained state below its bound, z in
D, convergence, the ramp)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ode_loop import run_ode

from cpbc.backstepping import ChainGains, IntegratorChainController, OutsideDomainError
from cpbc.errors import CpbcError
from cpbc.systems import IntegratorChain

FIG41 = (-10.0, -1.5, -0.05, -2.5)
FIG42 = (-100.0, 1.5, -4.0, -50.0)
CTRL = IntegratorChainController()
PLANT = IntegratorChain()


def test_plant() -> None:
    assert PLANT.state_names == ("xi1", "xi2", "xi3", "xi4")
    assert [(q.name, q.upper) for q in PLANT.constrained] == [
        ("xi2", 2.5), ("xi3", 12.0), ("xi4", 700.0)]
    assert all(q.lower == -q.upper for q in PLANT.constrained)
    assert PLANT.rhs((1.0, 2.0, 3.0, 4.0), 5.0, 0.0) == (2.0, 3.0, 4.0, 5.0)
    with pytest.raises(CpbcError):
        IntegratorChain((None, -1.0))


def test_first_step_is_the_h1_reading_written_by_hand() -> None:
    """α1 = −c1 arctan ξ1 and α2 = −c2 z1 + α̇1 − (k2² − z1²) V'(ξ1)/k3 with V = k1 ξ1 tanh ξ1."""
    g = ChainGains()
    rng = np.random.default_rng(14)
    for _ in range(20):
        s = rng.uniform(-5, 5, 4)
        a1 = -g.c1 * math.atan(s[0])
        z1 = s[1] - a1
        vp = g.k1 * (math.tanh(s[0]) + s[0] / math.cosh(s[0]) ** 2)
        a2 = -g.c2 * z1 - g.c1 * s[1] / (1 + s[0] ** 2) - (g.k2**2 - z1**2) * vp / g.k3
        t = CTRL.law.terms((s[0],), tuple(s[1:]))
        assert t.alpha[0] == pytest.approx(a1, rel=1e-14)
        assert t.alpha[1] == pytest.approx(a2, rel=1e-12)
        assert t.z[1] == pytest.approx(s[2] - a2, rel=1e-12)


def test_thesis_starts_are_in_the_domain_and_others_refused() -> None:
    assert np.all(np.abs(CTRL.check(FIG41)) < CTRL.law.bounds)
    assert np.all(np.abs(CTRL.check(FIG42)) < CTRL.law.bounds)
    with pytest.raises(OutsideDomainError) as err:
        CTRL((0.0, 0.0, 0.0, 400.0))  # z3 = 400 > k6 = 354.5
    assert err.value.variable == "z3"


@pytest.mark.parametrize("start", [FIG41, FIG42], ids=["fig4.1", "fig4.2"])
def test_figure_runs_keep_every_constrained_state_in_its_bound(start) -> None:
    run = run_ode(PLANT, CTRL, start, 120.0, 0.01, rtol=1e-7, atol=1e-9)
    for q in PLANT.constrained:
        assert run.peak(PLANT, q.name) < q.upper
    z = np.array([CTRL.errors(s) for s in run.x[::10]])
    assert np.all(np.abs(z) < np.array(CTRL.law.bounds))  # z never left D
    assert np.abs(run.x[-1]).max() < 1e-6  # asymptotic stabilisation
    if start == FIG42:  # the ramp: ξ2 holds a plateau near z1* + c1π/2 = 1 + 0.25 while far away
        ramp = run.x[(run.t > 20) & (run.t < 60), 1]
        assert ramp.min() > 1.2 and ramp.max() < 1.25
        assert np.ptp(ramp) < 0.03
