"""§4.3.3–§4.3.6 as tools: the optimisation under the manual rules finds constants whose
full-resolution check holds and pushes X_i to Ξ_i; under the theorem's rules the §4.4 chain is
infeasible (and must be: well-posedness and the outer domination exclude each other whenever
sup_D|α_{i+1}| ≥ c_i K_i, which holds for the chain at every gain); the §4.3.4 relaxation finds
the factor where one exists and says when none does; the admissible starts by simulation agree
with the product's DOP853 run; and the CLI reports each."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cpbc.backstepping import ChainGains, ChainSystem, IntegratorChainController, LogBarrier
from cpbc.backstepping.admissible_starts import simulate_starts
from cpbc.backstepping.integrator_chain_law import tuning_problem
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.parameter_constraints import worst_case
from cpbc.backstepping.tuning import Resolution, TuningProblem, conflicts, optimise, relax
from cpbc.tune import main

LIMITS = (2.5, 12.0, 700.0)


def test_manual_rules_push_the_worst_case_bounds_to_the_limits() -> None:
    r = optimise(tuning_problem(rules="manual"), "manual", starts=2)
    assert r.feasible and r.check.holds("well-posed", "state bound")
    assert r.start_utility == pytest.approx(0.5036, abs=1e-3)  # the thesis's gains
    assert r.utility < 0.01  # S (4.91): X_i within 0.4 % of every Ξ_i
    for x, lim in zip(r.check.worst.state_bounds, LIMITS, strict=True):
        assert 0.99 * lim < x <= lim
    assert r.values["c4"] == 1.0 and r.values["k7"] == 10.0  # not in the manual rules


def test_the_chain_has_no_constants_meeting_theorem_4_12() -> None:
    """The ratio ρ1 = sup_D|α2|/(c1 K1) ≥ 1 at any gains (at x = 0, z1 = K1:
    |α2| = (c2 + c1)K1 in H1's names), so the tool must report infeasibility."""
    rng = np.random.default_rng(16)
    system = ChainSystem(0.3, 1.0)
    for _ in range(10):
        c = np.exp(rng.uniform(-3, 3, 3))
        k = np.exp(rng.uniform(-3, 5, 3))
        w = np.exp(rng.uniform(-3, 3, 3))
        law = MultipleConstraintLaw(system, tuple(c), tuple(LogBarrier(a, b)
                                                             for a, b in zip(k, w, strict=True)))
        assert all(cf.excludes for cf in conflicts(law, worst_case(law, 7, 4000, refine=0))[:1])
    r = optimise(tuning_problem(rules="theorem"), "theorem", starts=1, maxiter=10)
    assert not r.feasible
    assert r.message().startswith("INFEASIBLE (theorem rules)")
    labels = {c.label for c in r.failed}
    assert labels & {"(4.55)", "(4.66)"} and r.violation > 0
    assert r.conflicts[0].excludes


def _one_step(limit: float) -> TuningProblem:
    """A double integrator (x = ξ1, constrained ξ2): one step, no domination pair."""
    def build(v: dict[str, float]) -> MultipleConstraintLaw:
        return MultipleConstraintLaw(ChainSystem(v["c1"], v["k1"], m=1), (v["c2"],),
                                     (LogBarrier(v["k2"], v["k3"]),))
    names = ("c1", "k1", "c2", "k2", "k3")
    return TuningProblem(names, (0.2, 1.0, 1.0, 0.5, 1.0), names, build, (limit,))


def test_theorem_rules_can_be_met_where_there_is_no_pair() -> None:
    r = optimise(_one_step(2.5), "theorem", starts=1)
    assert r.feasible and r.check.theorem_holds
    assert 0.99 * 2.5 < r.check.worst.state_bounds[0] <= 2.5


def test_relaxation_finds_the_factor_on_the_limits() -> None:
    """The thesis's gains held fixed with Ξ3 = 7: X3 = 7.929 > 7; the least factor is
    7.929/7 = 1.1327, bracketed by the bisection."""
    problem = tuning_problem(limits=(2.5, 7.0, 700.0), rules="manual", free=())
    assert not optimise(problem, "manual").feasible
    rel = relax(problem, "manual", cap=1.25, steps=5, resolution=Resolution(verdict=(9, 20_000)))
    assert rel.factor is not None and 7.9288 / 7 <= rel.factor < 7.9288 / 7 * 1.01
    assert "feasible with every Ξ_i multiplied by" in rel.message()


def test_relaxation_says_when_the_limits_are_not_the_conflict() -> None:
    rel = relax(tuning_problem(rules="theorem"), "theorem", cap=4.0, steps=2, starts=1,
                maxiter=5)
    assert rel.factor is None and rel.result is None and rel.tried == ((4.0, False),)
    assert "no relaxation" in rel.message()


def test_admissible_starts_agree_with_the_reference_run() -> None:
    """Fig. 4.1's start under fixed-step RK4 (h = 0.005 s) for 25 s: converged, peaks as the
    DOP853 run of the product (1.50300, 1.26306, 2.5), and U rises (no domination)."""
    law = IntegratorChainController().law
    starts = np.array([[-10, -1.5, -0.05, -2.5], [0, 0, 0, 400.0]])
    res = simulate_starts(law, LIMITS, starts, 25.0)
    fig41, outside = res.outcomes
    assert fig41.verdict == "converged" and outside.verdict == "outside D"
    assert fig41.peaks == pytest.approx((1.5030039, 1.2630645, 2.5), abs=1e-5)
    assert fig41.u_rise > 0.01 and math.isnan(outside.u_rise)
    assert res.counts()["converged"] == 1 and len(res.admissible) == 1


def test_cli_check_optimise_and_refusal(tmp_path: Path, capsys) -> None:
    assert main(["check", "ch4_integrator_chain"]) == 0
    assert "domination fails: stability not guaranteed" in capsys.readouterr().out
    out = tmp_path / "manual.json"
    assert main(["optimise", "ch4_integrator_chain", "--rules", "manual", "--starts", "1",
                 "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["feasible"] and doc["utility"] < 0.01
    assert "gains for the scenario file" in capsys.readouterr().out
    assert main(["check", "ch3_rwp"]) == 2
    assert "system.type" in capsys.readouterr().err
    assert ChainGains(**doc["values"]).k4 == pytest.approx(doc["values"]["k4"])
