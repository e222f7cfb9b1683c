"""Gain scheduling (§4.3.5): the local sups over a region are ≤ the global ones and bound every
sampled |α_i| there; a region's verdict is the checker's with the sups over that region; a small
region near the origin admits constants meeting Theorem 4.12's rules that the whole of D does
not; the switched law applies the constants of the region the state is in; and the CLI's exit
codes (0/1/2, nothing written on bad input)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cpbc.backstepping import ChainGains, DesignError, IntegratorChainController
from cpbc.backstepping.gain_scheduling import (
    NO_GUARANTEE,
    Partition,
    SwitchedLaw,
    coverage,
    schedule,
    simulate_switched,
    single_gain,
)
from cpbc.backstepping.integrator_chain_law import tuning_problem
from cpbc.backstepping.parameter_constraints import WorstCase, check_parameters, worst_case
from cpbc.backstepping.regions import Region
from cpbc.backstepping.tuning import RULES, Resolution
from cpbc.tune import main

LIMITS = (2.5, 12.0, 700.0)
#: Constants built by hand from the proof's structure for |ξ1| ≤ 1, |ξ_i| ≤ 0.03 Ξ_i: K1 well
#: above the region's |z1| ≤ 0.083, so sup|α2| ≪ c2 K1; large later weights for (4.60), (4.78).
WITNESS = ChainGains(c1=0.01, k1=1.0, c2=2.5, k2=2.4, k3=100.0, k4=3.2, c3=3.0, k5=1e3,
                     k6=2.85, c4=1.0, k7=1e4)
SMALL = Region(0.0, 1.0, tuple(0.03 * v for v in LIMITS))


@pytest.fixture(scope="module")
def global_worst() -> WorstCase:
    return worst_case(_law())


def _law(g: ChainGains | None = None):
    return IntegratorChainController(g).law


def _sample_alpha(law, region: Region, count: int, rng: np.random.Generator) -> np.ndarray:
    """max |α_i| over random states of region ∩ D (rejection sampling in plant coordinates)."""
    s = np.array(region.xi_bounds)
    x = rng.uniform(region.x_low, min(region.x_high, 50.0), count) * rng.choice([-1, 1], count)
    xi = rng.uniform(-1.0, 1.0, (3, count)) * s[:, None]
    terms = law.terms([x], list(xi))
    inside = np.all(np.abs(np.array(terms.z)) < np.array(law.bounds)[:, None], axis=0)
    assert inside.sum() > count // 20  # enough of the samples lie in D
    return np.array([np.max(np.abs(a[inside])) for a in terms.alpha])


@pytest.mark.parametrize("region", [Region(0.0, 1.0, (0.75, 3.6, 210.0)),
                                    Region(1.0, 10.0, (2.5, 12.0, 700.0)), SMALL])
def test_local_sups_are_at_most_the_global_ones_and_bound_the_samples(
        region: Region, global_worst: WorstCase) -> None:
    law = _law()
    glob = global_worst
    loc = worst_case(law, region=region)
    for g, s in zip(glob.alpha, loc.alpha, strict=True):
        assert s.value <= g.value
    sampled = _sample_alpha(law, region, 20_000, np.random.default_rng(5))
    for s, a in zip(loc.alpha, sampled, strict=True):
        assert a <= s.value * (1 + 1e-9)
        assert a >= 0.5 * s.value  # and the sup is not wildly above what the region reaches


def test_a_region_without_bounds_is_the_global_search() -> None:
    law = _law()
    # the same grid points (z_j = v_j K_j), up to the rounding of the interval's mapping
    assert ([s.value for s in worst_case(law, 9, 20_000, region=Region()).alpha]
            == pytest.approx([s.value for s in worst_case(law, 9, 20_000).alpha], rel=1e-12))


def test_small_region_meets_the_theorem_where_d_cannot() -> None:
    """The proof (docs/PART1_CH4.md) blocks every gain on D; on the small region it does not."""
    law = _law(WITNESS)
    local = check_parameters(law, LIMITS, (0.95, 0.95), region=SMALL)
    assert local.theorem_holds
    glob = check_parameters(law, LIMITS, (0.95, 0.95))
    assert not glob.theorem_holds and not glob.holds("well-posed")


def test_coverage_is_the_largest_z_over_the_box_and_the_witness_does_not_cover_it() -> None:
    """The witness's D holds the small box in ξ2, ξ3 but not in ξ4 (|ξ4| ≤ 21 against
    K3 = 2.85): a local design can meet the theorem on R ∩ D while R is mostly outside D."""
    law = _law(WITNESS)
    cov = coverage(law, SMALL)
    rng = np.random.default_rng(7)
    x = [rng.uniform(-1.0, 1.0, 5000)]
    xi = list(rng.uniform(-1.0, 1.0, (3, 5000)) * np.array(SMALL.xi_bounds)[:, None])
    sampled = np.max(np.abs(np.array(law.terms(x, xi).z)), axis=1) / np.array(law.bounds)
    assert np.all(sampled <= np.array(cov) * (1 + 1e-9))
    assert cov[0] < 0.1 and cov[1] < 0.5 and cov[2] > 5.0


def test_region_verdicts_are_the_checkers_on_the_region() -> None:
    """The witness held fixed (only the a_i are searched, to keep this fast): the schedule's
    verdict per region and rules is the checker's with the sups over that region."""
    part = Partition(LIMITS, (0.0, 1.0), (0.03, 1.0))

    def fixed(region: Region, rules: str):
        return tuning_problem(WITNESS, LIMITS, rules, free=(), region=region)

    res = Resolution(search=(5, 2000, 0), verdict=(7, 5_000))
    sched = schedule(fixed, part, dict(WITNESS.__dict__), starts=1, maxiter=8, resolution=res,
                     with_coverage=False)
    assert [r.region for r in sched.regions] == list(part.regions())
    for r in sched.regions:
        for t in (r.theorem, r.manual):
            chk = check_parameters(_law(ChainGains(**t.values)), LIMITS, t.a, points=7,
                                   budget=5_000, region=r.region)
            assert t.feasible == chk.holds(*RULES[t.rules])
        # the switched law's constants: the theorem's if found, else the manual ones, else
        # the fallback
        want = (r.theorem.values if r.theorem.feasible else r.manual.values
                if r.manual.feasible else sched.fallback)
        assert r.values == want
    small, whole = sched.regions
    assert small.theorem.feasible and small.used == "theorem"
    assert not whole.theorem.feasible  # the whole box: blocked by the proof
    assert sched.any_theorem_feasible


def test_partition_locates_the_inner_box_first_and_refuses_bad_edges() -> None:
    part = Partition(LIMITS, (0.0, 1.0, 10.0, math.inf), (0.1, 1.0))
    assert part.locate([0.5], [0.1, 0.1, 1.0]) == 0
    assert part.locate([5.0], [0.1, 0.1, 1.0]) == 1
    assert part.locate([50.0], [0.1, 0.1, 1.0]) == 2
    assert part.locate([1.0], [0.1, 6.0, 1.0]) == 4  # |ξ3| > 0.1 Ξ3: the outer box, band 2
    assert part.locate([0.0], [0.0, 0.0, 701.0]) is None
    short = Partition(LIMITS, (0.0, 1.0, 10.0), (1.0,))
    assert short.locate([10.0], [0.0] * 3) == 1 and short.locate([10.5], [0.0] * 3) is None
    for bad in ({"bands": (0.0, 1.0, 1.0)}, {"bands": (1.0, 2.0)}, {"shares": (0.5, 1.5)}):
        with pytest.raises(DesignError) as err:
            Partition(LIMITS, **bad)
        assert err.value.parameter in bad


def test_switched_law_applies_the_gains_of_the_region_it_is_in() -> None:
    part = Partition(LIMITS, (0.0, 1.0, math.inf), (0.1, 1.0))
    laws = [_law(ChainGains(c4=1.0 + i)) for i in range(4)]  # c4 enters u only
    sw = SwitchedLaw(part, laws)
    rng = np.random.default_rng(3)
    for _ in range(40):
        x = [float(rng.choice([-1, 1]) * rng.exponential(2.0))]
        xi = list(rng.uniform(-0.2, 0.2, 3) * np.array(LIMITS))
        idx = part.locate(x, xi)
        assert idx is not None
        assert sw.control(x, xi) == laws[idx].control(x, xi)
        others = {float(la.control(x, xi)) for j, la in enumerate(laws) if j != idx}
        assert sw.control(x, xi) not in others
    assert sw.select([0.0], [0.0, 0.0, 800.0], 3) == 3  # outside every box: keep the active


def test_switched_simulation_counts_switches_and_the_jumps_of_u() -> None:
    """Fig. 4.1's start with one region: the unscheduled law (peaks as the reference run);
    with two regions of different K1: the switch is counted and U jumps there."""
    fig41 = [-10.0, -1.5, -0.05, -2.5]
    one = simulate_switched(single_gain(LIMITS, _law()), fig41, 25.0)
    assert one.switches == 0 and one.u_jumps == () and one.regions == (0,)
    assert one.peaks == pytest.approx((1.5030039, 1.2630645, 2.5), abs=1e-5)
    assert one.settle_time == pytest.approx(21.6, abs=0.05) and not one.crossed
    part = Partition(LIMITS, (0.0, 5.0, math.inf), (1.0,))
    sw = SwitchedLaw(part, [_law(ChainGains(k2=2.2)), _law()])
    two = simulate_switched(sw, fig41, 8.0)
    assert two.regions[:2] == (1, 0) and two.switches == len(two.u_jumps) >= 1
    assert two.u_jumps[0] != 0.0
    assert two.u_rises_at_switches == sum(j > 0 for j in two.u_jumps)


def test_cli_schedule_exit_codes(tmp_path: Path, capsys) -> None:
    out = tmp_path / "s.json"
    assert main(["schedule", "ch4_integrator_chain", "--bands", "0", "1", "0.5",
                 "--json", str(out)]) == 2
    assert "--bands" in capsys.readouterr().err and not out.exists()
    assert main(["schedule", "ch4_integrator_chain", "--shares", "0.5", "2",
                 "--json", str(out)]) == 2
    assert "--shares" in capsys.readouterr().err and not out.exists()
    assert main(["schedule", "ch3_rwp", "--json", str(out)]) == 2 and not out.exists()
    # the whole constraint box: the proof blocks the theorem's rules, so no region meets them
    assert main(["schedule", "ch4_integrator_chain", "--bands", "0", "inf", "--shares", "1",
                 "--maxiter", "2", "--duration", "0.5", "--json", str(out)]) == 1
    text = capsys.readouterr().out
    assert "NO STABILITY GUARANTEE" in text
    doc = json.loads(out.read_text())
    assert doc["warning"] == NO_GUARANTEE and len(doc["regions"]) == 1
    assert not doc["regions"][0]["theorem"]["feasible"]
    assert {s["law"] for s in doc["simulations"]} == {"scheduled", "single-gain manual"}
