"""The thesis's experiments (Sections 6.4 and 7.3), checked claim by claim.

Where the simulation disagrees with the thesis, the test asserts what the simulation shows
and says so (README, "Reproducing the thesis").
"""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_all


def assert_lyapunov_never_increases(result) -> None:
    """V[k+1] ≤ V[k] up to its rounding: V = exp(log L − log s(ΦΨ)) is good to a few ulps,
    and starting from rest its true decrease over the first period is O(h³), below that."""
    v0 = float(result.trajectory.lyapunov[0])
    assert result.summary.max_lyapunov_increase <= 8 * np.finfo(float).eps * v0


def run(name: str, backend: str | None = None, controllers: list[str] | None = None):
    scenario, file = load_scenario(name)
    setup = build(scenario, file)
    if controllers is not None:
        setup.controllers = [c for c in setup.controllers if c.name in controllers]
    return {(r.case, r.controller): r for r in run_all(setup, backend)}


@pytest.fixture(scope="module")
def ch6():
    return run("thesis_ch6")


@pytest.fixture(scope="module")
def ch7():
    return run("thesis_ch7")


def test_ch6_pd_peak_rates_and_obstacle(ch6) -> None:
    s = ch6["rest", "PD"].summary
    np.testing.assert_allclose(s.peak_joint_rates, [0.585, 0.39], atol=0.005)  # Fig. 6.3
    assert s.status == "converged"
    assert s.min_margins["obstacle"] < -0.2  # the end point passes through the obstacle
    assert {"obstacle", "rate[theta1]", "rate[theta2]"} <= set(s.crossed_constraints)


def test_ch6_cpbc_holds_every_constraint(ch6) -> None:
    s = ch6["rest", "CPBC"].summary
    assert all(v > 0 for v in s.min_margins.values())
    assert s.peak_joint_rates[0] < 0.3 and s.peak_joint_rates[1] < 0.2
    assert_lyapunov_never_increases(ch6["rest", "CPBC"])


def test_ch6_cpbc_stalls_where_the_thesis_claims_convergence(ch6) -> None:
    """Thesis: converges to (π, 2π/3). Here: a spurious equilibrium in front of the obstacle."""
    r = ch6["rest", "CPBC"]
    assert r.summary.status == "stalled"
    np.testing.assert_allclose(r.trajectory.position[-1], [1.564, 0.712], atol=5e-3)
    assert r.summary.final_error > 1.5


def test_ch6_cpbc_stall_is_not_a_sampling_artefact() -> None:
    r = run("thesis_ch6", "reference", ["CPBC"])["rest", "CPBC"]
    assert r.summary.status == "stalled"
    np.testing.assert_allclose(r.trajectory.position[-1], [1.564, 0.712], atol=5e-3)


def test_ch6_flatter_shaping_gets_past_the_obstacle(ch6) -> None:
    s = ch6["rest", "CPBC-alpha0.05"].summary
    assert s.status == "converged"
    assert all(v > 0 for v in s.min_margins.values())
    assert s.min_margins["obstacle"] < 1e-3  # it grazes the obstacle…
    assert s.peak_torque_norm > 100  # …with unbounded torque (Remark 6.13)


@pytest.mark.parametrize(("case", "torque"), [("rest", 31.5), ("moving", 33.4)])
def test_ch7_pd_peaks(ch7, case: str, torque: float) -> None:
    s = ch7[case, "PD"].summary
    np.testing.assert_allclose(s.peak_joint_rates, [1.2, 1.4], atol=0.05)  # Figs. 7.2, 7.5
    assert max(s.peak_torques) == pytest.approx(torque, abs=0.1)  # Figs. 7.3, 7.6
    assert s.status == "converged"


@pytest.mark.parametrize("case", ["rest", "moving"])
def test_ch7_bpbc_rates_bound_and_convergence(ch7, case: str) -> None:
    s = ch7[case, "BPBC"].summary
    assert s.peak_joint_rates[0] < 0.3 and s.peak_joint_rates[1] < 0.2
    assert s.torque_bound == pytest.approx(30.065, abs=1e-3)  # eq. 7.42
    assert s.peak_torque_norm < s.torque_bound / 10  # Remark 7.11: far below the bound
    assert s.status == "converged"
    assert_lyapunov_never_increases(ch7[case, "BPBC"])
