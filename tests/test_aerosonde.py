"""Chapter 5: the Aerosonde plant (AeroSim data, trim, stall clip, thrust), the design model
(5.3), both altitude laws (exact derivatives against finite differences, V̇ of (5.31)/(5.63),
the closed-loop error dynamics), the climb-rate plateau and the command admissibility check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cpbc.backstepping import DesignError, OutsideDomainError
from cpbc.backstepping.altitude_backstepping import (
    TraditionalAltitudeGains,
    TraditionalAltitudeLaw,
)
from cpbc.backstepping.altitude_command import AltitudeCommand, TrackingLaw
from cpbc.backstepping.constrained_altitude import (
    ConstrainedAltitudeGains,
    ConstrainedAltitudeLaw,
)
from cpbc.simulation import run_system_reference
from cpbc.systems.aerosim import AerosondeParameters, aero_forces, full_throttle_thrust, isa_density
from cpbc.systems.aerosonde import AerosondePlant

PLANT = AerosondePlant()
MODEL = PLANT.design_model()
LAWS = [TraditionalAltitudeLaw(MODEL), ConstrainedAltitudeLaw(MODEL)]
RNG = np.random.default_rng(5)


def states(n: int) -> list[np.ndarray]:
    """Design states (h, v_z, α, q) near a climb, inside the constrained law's domain for
    h_d = 130 m."""
    out = []
    while len(out) < n:
        x = np.array([RNG.uniform(100, 160), RNG.uniform(-3, 3), RNG.uniform(-0.05, 0.25),
                      RNG.uniform(-0.3, 0.3)])
        if LAWS[1].admissible(x, 130.0):
            out.append(x)
    return out


def test_design_constants_at_the_aerosim_trim_condition() -> None:
    """PART1 Ch. 5 §3.4's table: ρ_ISA(100 m), 13.5 kg, 1.135 kg m², 23 m/s."""
    assert isa_density(100.0) == pytest.approx(1.21328, abs=1e-5)
    m = MODEL
    for got, want in ((m.l0, 3.00708), (m.l_alpha, 73.3544), (m.l0_prime, 0.130742),
                      (m.l_alpha_prime, 3.18932), (m.m0, 3.98756), (m.m_alpha, -80.9238),
                      (m.m_q, -4.65987), (m.m_elevator, -29.2953)):
        assert got == pytest.approx(want, rel=2e-5)
    alpha0, elevator0 = m.trim()
    assert math.degrees(alpha0) == pytest.approx(5.314, abs=1e-3)
    assert math.degrees(elevator0) == pytest.approx(-6.879, abs=1e-3)


def test_plant_trim_and_full_throttle_thrust() -> None:
    alpha, elevator, thrust = PLANT.trim
    assert math.degrees(alpha) == pytest.approx(5.43, abs=0.005)
    assert math.degrees(elevator) == pytest.approx(-7.20, abs=0.005)
    assert thrust == pytest.approx(9.31, abs=0.005)
    x0 = PLANT.initial_state(100.0)
    assert np.allclose(PLANT.rhs(x0, elevator, 0.0), (0, 0, 0, 0, 23.0, 0, 0), atol=1e-9)
    rho = isa_density(100.0)
    p = AerosondeParameters()
    assert full_throttle_thrust(p, rho, 23.0) == pytest.approx(34.1, abs=0.05)
    assert full_throttle_thrust(p, rho, 20.0) == pytest.approx(37.0, abs=0.05)


def test_stall_is_the_clip_of_alpha_at_0_3_rad() -> None:
    p, rho = AerosondeParameters(), 1.2
    at = aero_forces(p, rho, 23.0, 0.3, 0.0, 0.0, 0.0)
    past = aero_forces(p, rho, 23.0, 0.45, 0.0, 0.0, 0.0)
    below = aero_forces(p, rho, 23.0, 0.25, 0.0, 0.0, 0.0)
    assert past == at and below.lift < at.lift


def test_plant_alpha_rate_solves_its_implicit_equation() -> None:
    """α̇ = q − γ̇ with γ̇ from the accelerations the forces at that α̇ give."""
    x = (120.0, 2.0, 0.12, 0.2, 0.0, 22.5, 1.0)
    _, az, alpha_dot, _, _, ax, _ = PLANT.rhs(x, -0.2, 0.0)
    vz, vx, q = x[1], x[5], x[3]
    assert alpha_dot == pytest.approx(q - (vx * az - vz * ax) / (vx * vx + vz * vz), abs=1e-12)
    # and the α̇ terms matter: without them the pitch acceleration differs
    assert abs(alpha_dot) > 0.01


@pytest.mark.parametrize("law", LAWS, ids=["traditional", "constrained"])
def test_virtual_control_derivatives_match_finite_differences(law) -> None:
    """α̇_ref and q̇_ref along (5.3) against central differences of α_ref, q_ref."""
    eps = 1e-6
    for x in states(5):
        u = law.elevator(x, 130.0)
        f = np.array(MODEL.rhs(x, u))
        t, tp, tm = (law.terms(y, 130.0) for y in (x, x + eps * f, x - eps * f))
        assert t.alpha_ref_dot == pytest.approx((tp.alpha_ref - tm.alpha_ref) / (2 * eps),
                                                rel=1e-6, abs=1e-7)
        assert t.q_ref_dot == pytest.approx((tp.q_ref - tm.q_ref) / (2 * eps),
                                            rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("law", LAWS, ids=["traditional", "constrained"])
def test_lyapunov_derivative_is_the_theorems(law) -> None:
    """V̇ of (5.31)/(5.63) against the finite difference of V along (5.3) under the law."""
    eps = 1e-6
    for x in states(5):
        f = np.array(MODEL.rhs(x, law.elevator(x, 130.0)))
        v, vdot = law.lyapunov(x, 130.0)
        vp, vm = law.lyapunov(x + eps * f, 130.0)[0], law.lyapunov(x - eps * f, 130.0)[0]
        assert vdot < 0 < v
        assert vdot == pytest.approx((vp - vm) / (2 * eps), rel=1e-6)


def test_constrained_closed_loop_errors() -> None:
    """ż of §5.4: ż1 = −c1 tanh z1 + z2, ż2 = −c2z2 − (k1/k3)(k2²−z2²)Φ + Lα*z3,
    ż3 = −c3z3 − k3Lα*z2/(k2²−z2²) + z4, ż4 = −c4z4 − z3 (a single −z3, not (5.30)'s two)."""
    law, g, la, eps = LAWS[1], LAWS[1].gains, MODEL.l_alpha, 1e-6
    for x in states(3):
        f = np.array(MODEL.rhs(x, law.elevator(x, 130.0)))
        z1, z2, z3, z4 = law.terms(x, 130.0).z
        zp = np.array(law.terms(x + eps * f, 130.0).z)
        zm = np.array(law.terms(x - eps * f, 130.0).z)
        zdot = (zp - zm) / (2 * eps)
        t = math.tanh(z1)
        phi = t + z1 * (1 - t * t)
        room = g.k2**2 - z2**2
        want = (-g.c1 * t + z2, -g.c2 * z2 - g.k1 / g.k3 * room * phi + la * z3,
                -g.c3 * z3 - g.k3 * la * z2 / room + z4, -g.c4 * z4 - z3)
        assert zdot == pytest.approx(want, rel=1e-6, abs=1e-6)


def test_gains_are_checked() -> None:
    with pytest.raises(DesignError, match="k2"):
        ConstrainedAltitudeGains(k2=1.0)  # k2 > c1 = 1.5 fails
    with pytest.raises(DesignError, match="c4"):
        TraditionalAltitudeGains(c4=0.0)
    assert ConstrainedAltitudeGains().climb_rate_bound == 3.5


def test_the_barrier_law_refuses_states_outside_its_domain() -> None:
    with pytest.raises(OutsideDomainError) as err:
        LAWS[1].elevator((200.0, 3.4, 0.1, 0.0), 100.0)  # z2 = 3.4 + 1.5 tanh(100) = 4.9
    assert err.value.variable == "z2" and err.value.value == pytest.approx(4.9)


def test_an_inadmissible_command_is_refused_naming_h_d() -> None:
    """PART1's example: climbing at 3.4 m/s towards 300 m (z2 = 1.9, inside) when the
    command drops to 50 m: z2 would jump to 3.4 + 1.5 tanh(100) = 4.9 > k2."""
    x = (150.0, 3.4, 0.1, 0.0)
    law = TrackingLaw(LAWS[1], AltitudeCommand(100.0, ((5.0, 300.0), (10.0, 50.0))))
    law(x, 9.0)  # the climb itself is inside the domain
    lo, hi = LAWS[1].command_interval(x)
    assert lo == pytest.approx(150.0 - math.atanh(-1.4 / 1.5)) and hi == math.inf
    with pytest.raises(OutsideDomainError) as err:
        law(x, 10.0)
    assert err.value.variable == "h_d" and "inadmissible" in str(err.value)
    with pytest.raises(OutsideDomainError) as err:
        law(x, 10.5)  # after its arrival, the same state is a barrier crossing of the flight
    assert err.value.variable == "z2"
    # in level flight every command is admissible (|v_z| < k2 − c1 = 0.5 m/s)
    assert LAWS[1].command_interval((150.0, 0.4, 0.1, 0.0)) == (-math.inf, math.inf)
    # the traditional law takes any command
    assert TrackingLaw(LAWS[0], law.command)(x, 10.0) == LAWS[0].elevator(x, 50.0)


def test_command_schedule() -> None:
    c = AltitudeCommand(100.0, ((10.0, 150.0), (100.0, 130.0)))
    assert [c.at(t) for t in (0.0, 9.99, 10.0, 99.0, 100.0, 1e4)] == [100, 100, 150, 150, 130, 130]
    with pytest.raises(ValueError):
        AltitudeCommand(100.0, ((10.0, 150.0), (10.0, 130.0)))


def test_constrained_climb_holds_the_predicted_plateau_within_the_bound() -> None:
    """+100 m at 10 s (Fig. 5.5), 40 s of flight on the AeroSim plant: the climb rate rises
    to the plateau the design model predicts (c1 + z2* = 1.59 m/s for k3 = 0.5), far below
    B = 3.5 m/s, and a smaller k3 lifts it towards B (3.03 m/s for k3 = 0.05)."""
    plant = AerosondePlant(command_times=(10.0,))
    for k3, plateau in ((0.5, 1.590), (0.05, 3.028)):
        law = ConstrainedAltitudeLaw(MODEL, ConstrainedAltitudeGains(k3=k3))
        assert law.climb_plateau() == pytest.approx(plateau, abs=1e-3)
        k = TrackingLaw(law, AltitudeCommand(100.0, ((10.0, 200.0),)))
        tr = run_system_reference(plant, k, plant.initial_state(100.0), 40.0, 0.1, rtol=1e-8,
                                  atol=1e-10)
        vz = tr.state[:, 1]
        assert tr.outcome == "completed" and vz.max() < 3.5
        assert vz[tr.time >= 30.0] == pytest.approx(plateau, abs=0.06)


def test_traditional_climb_peaks_early_and_stalls_for_a_large_step() -> None:
    """Fig. 5.1's +50 m: the climb rate peaks at ≈ 3.6 m/s ≈ 1.8 s after the step (thesis:
    4 m/s at 12 s), with α below the stall; +200 m stalls (α past 0.3 rad) on the same
    plant, +100 m peaks 0.2° short of it."""
    plant = AerosondePlant(command_times=(10.0,))
    peaks = {}
    for target in (150.0, 200.0, 300.0):
        k = TrackingLaw(LAWS[0], AltitudeCommand(100.0, ((10.0, target),)))
        tr = run_system_reference(plant, k, plant.initial_state(100.0), 16.0, 0.02,
                                  rtol=1e-8, atol=1e-10)
        peaks[target] = tr
    fig51 = peaks[150.0]
    i = int(np.argmax(fig51.state[:, 1]))
    assert 3.4 < fig51.state[i, 1] < 4.0 and 11.5 < fig51.time[i] < 12.2
    assert fig51.state[:, 2].max() < 0.3
    assert 0.29 < peaks[200.0].state[:, 2].max() < 0.3
    assert peaks[300.0].state[:, 2].max() > 0.3
