"""§3.5: the RWP law against the thesis's printed forms, its exact derivatives, the a-priori
bounds (3.148), (3.157)–(3.159), and the closed-loop runs of Figs 3.9 and 3.11 in MuJoCo at
1 kHz (the thesis's loop is continuous-time)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from part1_checks import assert_rates, closed_loop, numeric_rate, peak, split

from cpbc.backstepping import OutsideDomainError, ReactionWheelController
from cpbc.simulation import run_system_mujoco
from cpbc.systems import ReactionWheelPendulum

CTRL = ReactionWheelController()
G = CTRL.gains
K = CTRL.constants
A, B, C = K.abc


def _printed_tau(x: tuple[float, ...]) -> float:
    """(3.143), (3.150), (3.153) transcribed term by term."""
    q1, dq1, dq2 = x
    e1, e2, xi = K.d11 * dq1 + K.d12 * dq2, q1, dq1
    n, q = 1 + e1**2, 2 - math.cos(e2)
    a1 = -G.c1 * math.sin(e2) - G.k1 * K.d0 * e1 * q / (G.k2 * n)
    z = xi - a1
    a1dot = (
        -G.c1 * math.cos(e2) * xi
        - G.k1 * K.d0 * e1 * math.sin(e2) * xi / (G.k2 * n)
        - G.k1 * K.d0**2 * q * math.sin(e2) * (1 - e1**2) / (G.k2 * n**2)
    )
    return (1 / B) * (G.c2 * z + (A + C) * math.sin(e2) - a1dot
                      + G.k2 * (G.k4**2 - z**2) * math.sin(e2) / (G.k3 * q))


def _random_states(n: int = 30) -> list[tuple[float, ...]]:
    rng = np.random.default_rng(11)
    out: list[tuple[float, ...]] = []
    while len(out) < n:
        x = (float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(-1, 1)),
             float(rng.uniform(-3e4, 3e4)))
        if abs(CTRL.errors(x)[0]) < 0.95 * G.k4:
            out.append(x)
    return out


def test_law_is_the_printed_law() -> None:
    assert A == pytest.approx(78.53, abs=0.01) and B == pytest.approx(208.42, abs=0.01)
    for x in _random_states():
        assert CTRL.control(x) == pytest.approx(_printed_tau(x), rel=1e-10, abs=1e-12)


def test_rates_and_lyapunov_rate() -> None:
    """Exact rates (FD) and U̇ = −W − k3c2z²/(k4² − z²) (3.154) along the closed loop."""
    rhs = closed_loop(CTRL.law, 2)
    for x in _random_states(15):
        eta, xi = CTRL.coordinates(x)
        assert_rates(CTRL.cascade, eta, xi[0], 0.37)
        s = np.array([*eta, *xi])
        got = numeric_rate(lambda p: CTRL.law.lyapunov(*split(p, 2)), s, rhs(0.0, s), h=1e-7)
        (z,) = CTRL.law.errors(eta, xi)
        w = CTRL.cascade.lyapunov(eta)[1]
        want = -w - G.k3 * G.c2 * z**2 / (G.k4**2 - z**2)
        assert got == pytest.approx(want, rel=1e-5, abs=1e-9)


def test_bounds_printed_and_corrected() -> None:
    """(3.148), (3.157)–(3.159) evaluated; the rate bound is ≈ 1.01, not the 1 rad/s wanted."""
    b = CTRL.bounds()
    assert b.alpha1 == pytest.approx((0.50980, 0.51470), abs=1e-5)
    assert b.rate == pytest.approx((1.0108, 1.0157), abs=1e-4)
    assert b.alpha1_dot == pytest.approx((0.51779, 0.52102), abs=1e-5)
    assert b.torque == pytest.approx((0.39491, 0.39492), abs=1e-5)
    assert b.torque[1] < 0.4 < b.rate[0]
    grid = np.linspace(-np.pi, np.pi, 721)
    etas = np.linspace(-5, 5, 401)
    sup_a1 = max(abs(CTRL.cascade.first_step((e1, e2), 0.0).alpha1) for e1 in etas[::4]
                 for e2 in grid[::4])
    assert sup_a1 < b.alpha1[1]  # the corrected bound holds on a grid


def test_domain_and_equilibrium() -> None:
    with pytest.raises(OutsideDomainError):
        CTRL.check((0.0, 0.6, 0.0))  # z = q̇1 = 0.6 > k4 at the origin of η
    CTRL.check((np.pi / 2, 0.0, 0.0))  # z(0) = 0.5 < k4 = 0.501
    assert CTRL.errors((np.pi / 2, 0.0, 0.0))[0] == pytest.approx(0.5)
    assert CTRL.at_downward_equilibrium((np.pi, 0.0, 0.0))
    assert abs(CTRL.control((np.pi, 0.0, 0.0))) < 1e-12
    assert not CTRL.at_downward_equilibrium((3.14, 0.0, 0.0))


def _wrapped(q: np.ndarray) -> np.ndarray:
    return (q + np.pi) % (2 * np.pi) - np.pi


def test_fig_3_9_from_half_pi() -> None:
    """|q̇1| < 1 rad/s, |τ| < 0.4 N m, and (q1, q̇1) → 0 (Figs 3.9/3.10)."""
    plant = ReactionWheelPendulum()
    run = run_system_mujoco(plant, CTRL, (np.pi / 2, 0.0, 0.0), duration=30.0)
    lo, hi = peak(run, plant, "dq1")
    assert -1.0 < lo and hi < 1.0
    tlo, thi = peak(run, plant, "tau")
    assert -0.4 < tlo and thi < 0.4
    late = run.time >= 20.0
    assert np.abs(_wrapped(run.state[late, 0])).max() < 5e-3  # a lean of ≈ −1.6 mrad remains
    assert np.abs(run.state[late, 1]).max() < 1e-3


def test_fig_3_11_from_near_pi() -> None:
    """From q1 = 3.14 the pendulum leaves the bottom slowly (the ≈ 6 s of the text), then
    converges, inside both limits (Figs 3.11/3.12)."""
    plant = ReactionWheelPendulum()
    run = run_system_mujoco(plant, CTRL, (3.14, 0.0, 0.0), duration=30.0)
    lo, hi = peak(run, plant, "dq1")
    tlo, thi = peak(run, plant, "tau")
    assert -1.0 < lo and hi < 1.0 and -0.4 < tlo and thi < 0.4
    early = run.time <= 4.0
    assert np.abs(_wrapped(run.state[early, 0])).min() > 3.0  # still near the bottom at 4 s
    late = run.time >= 25.0
    assert np.abs(_wrapped(run.state[late, 0])).max() < 5e-3
    assert np.abs(run.state[late, 1]).max() < 1e-3


def test_exact_pi_start_stays_down() -> None:
    """(π, 0, 0) is a closed-loop equilibrium: "stabilisation from (π, 0, 0)" cannot happen."""
    plant = ReactionWheelPendulum()
    run = run_system_mujoco(plant, CTRL, (np.pi, 0.0, 0.0), duration=10.0)
    assert np.abs(run.state[:, 0] - np.pi).max() < 1e-9
