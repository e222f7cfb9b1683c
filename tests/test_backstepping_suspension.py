"""§3.3: the suspension law against the thesis's printed forms, its exact derivatives, and the
closed-loop runs of Figs 3.4–3.7 in MuJoCo at 10 kHz (the thesis's loop is continuous-time)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from part1_checks import assert_rates, closed_loop, numeric_rate, peak, split

from cpbc.backstepping import (
    DesignError,
    OutsideDomainError,
    SuspensionController,
    SuspensionGains,
)
from cpbc.simulation import run_system_mujoco
from cpbc.systems import HaversineBump, QuarterCar

CTRL = SuspensionController()
G = CTRL.gains
A, B, C, D, E = CTRL.cascade.a, CTRL.cascade.b, CTRL.cascade.c, CTRL.cascade.d, CTRL.cascade.e


def _printed_u(x: tuple[float, ...]) -> float:
    """(3.80), (3.89), (3.88) transcribed term by term (½ storage, d ≡ 0)."""
    (e1, e2), (s1, s2) = CTRL.coordinates(x)
    th = math.tanh(G.k1 * e2)
    sech2 = 1 - th**2
    e2dot = -A * e1 + B * s1
    z1 = s1 + G.c1 * th
    z1dot = s2 + G.c1 * G.k1 * sech2 * e2dot  # (3.73)
    a2 = -G.c2 * z1 - G.c1 * G.k1 * sech2 * e2dot - (G.k2**2 - z1**2) * B * e2 / G.k3
    z2 = s2 - a2
    a2dot = (
        -G.c2 * z1dot
        + 2 * G.c1 * G.k1**2 * th * sech2 * e2dot**2
        - G.c1 * G.k1 * sech2 * (-A * e2 + B * s2)
        + 2 * B / G.k3 * z1 * z1dot * e2
        - (G.k2**2 - z1**2) / G.k3 * B * e2dot
    )
    return -(1 / E) * (-G.c3 * z2 - C * e1 + D * s1 + a2dot
                       - G.k3 * z1 / (G.k4 * (G.k2**2 - z1**2)))


def _random_states(n: int = 30) -> list[tuple[float, ...]]:
    rng = np.random.default_rng(7)
    out: list[tuple[float, ...]] = []
    while len(out) < n:
        x = tuple(float(v) for v in rng.normal(0, [0.02, 0.5, 0.02, 0.5]))
        if abs(CTRL.errors(x)[0]) < 0.95 * G.k2:
            out.append(x)
    return out


def test_law_is_the_printed_law() -> None:
    for x in _random_states():
        assert CTRL.control(x) == pytest.approx(_printed_u(x), rel=1e-10, abs=1e-9)


def _component(i: int) -> Callable[[np.ndarray], float]:
    """The i-th of (η1, η2, ξ1, ξ2) as a function of x."""

    def f(p: np.ndarray) -> float:
        eta, xi = CTRL.coordinates(tuple(float(v) for v in p))
        return (*eta, *xi)[i]

    return f


def test_coordinates_give_the_cascade_3_64() -> None:
    """d/dt of (η, ξ) under (3.62) with d = 0 is (η2, −Aη1 + Bξ1, ξ2, Cη1 − Dξ1 − Eu)."""
    plant = QuarterCar()
    for x in _random_states(10):
        u = 3.0
        xdot = np.array(plant.rhs(x, u, 0.0))
        got = [numeric_rate(_component(i), np.array(x), xdot) for i in range(4)]
        (e1, e2), (s1, s2) = CTRL.coordinates(x)
        want = [e2, -A * e1 + B * s1, s2, C * e1 - D * s1 - E * u]
        assert got == pytest.approx(want, rel=1e-6, abs=1e-6)


def test_rates_and_lyapunov_rate() -> None:
    """Exact rates (FD) and U̇ = −W − c2k3z1²/(k2² − z1²) − c3k4z2² (3.90)."""
    rhs = closed_loop(CTRL.law, 2)
    for x in _random_states(15):
        eta, xi = CTRL.coordinates(x)
        assert_rates(CTRL.cascade, eta, xi[0], xi[1] + 0.3)
        s = np.array([*eta, *xi])
        got = numeric_rate(lambda p: CTRL.law.lyapunov(*split(p, 2)), s, rhs(0.0, s), h=1e-9)
        z1, z2 = CTRL.law.errors(eta, xi)
        w = CTRL.cascade.lyapunov(eta)[1]
        want = -w - G.c2 * G.k3 * z1**2 / (G.k2**2 - z1**2) - G.c3 * G.k4 * z2**2
        assert CTRL.law.lyapunov_rate(eta, xi) == pytest.approx(want, rel=1e-12)
        assert got == pytest.approx(want, rel=1e-4, abs=1e-6)


def test_literal_fig_3_7_start_is_refused() -> None:
    """x3(0) = −0.05, x2(0) = −20 gives z1(0) = −0.0990, outside (−k2, k2) = (−0.051, 0.051)."""
    with pytest.raises(OutsideDomainError) as err:
        CTRL.check((0.0, -20.0, -0.05, 0.0))
    assert err.value.value == pytest.approx(-0.0990, abs=5e-5)
    assert err.value.upper == pytest.approx(0.051)
    CTRL.check((0.0, 20.0, -0.05, 0.0))  # the resolved start: z1(0) = −0.0010


def test_gains_are_validated() -> None:
    with pytest.raises(DesignError, match="k3"):
        SuspensionGains(k3=0.0)
    assert CTRL.travel_bound == pytest.approx(0.1)


CASES = {
    "fig3.4": (0.015, (0.0, 0.0, 0.0, 0.0)),
    "fig3.5": (0.075, (0.0, 0.0, 0.0, 0.0)),
    "fig3.6": (0.11, (0.0, 0.0, 0.0, 0.0)),
    "fig3.7-resolved": (0.11, (0.0, 20.0, -0.05, 0.0)),
}


@pytest.mark.parametrize("case", CASES)
def test_thesis_case_in_mujoco(case: str) -> None:
    """|x3| < Ξ = 0.1 m throughout ((3.84), "never bottoms out"), and the state settles: the
    thesis's claims that do not need Karlsson's controller."""
    height, x0 = CASES[case]
    plant = QuarterCar(HaversineBump(height))
    run = run_system_mujoco(plant, CTRL, x0, duration=2.0)  # PART1 §4.4: T = 2 s
    lo, hi = peak(run, plant, "x3")
    assert -0.1 < lo and hi < 0.1
    z1 = np.array([CTRL.errors(tuple(x))[0] for x in run.state[::10]])
    assert np.abs(z1).max() < G.k2
    late = np.abs(run.state[run.time >= 1.0]).max(axis=0)
    assert late[2] < 0.01 * max(abs(lo), hi)  # travel within 1 % of its peak after 1 s
    assert np.abs(run.state[-1]).max() < 1e-4
