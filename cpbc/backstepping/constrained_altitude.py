"""§5.4: the constrained altitude controller of the Aerosonde, |v_z| < B (5.33)–(5.61).

    z1 = h − h_d,  Φ(z1) = tanh z1 + z1(1 − tanh² z1),  V1 = k1 z1 tanh z1            (5.35)
    z2 = v_z + c1 tanh z1            (v_zref = −c1 tanh z1, |v_zref| ≤ c1)            (5.37), (5.38)
    V2 = V1 + ½k3 log(k2²/(k2² − z2²)),   domain |z2| < k2                          (5.44), (5.45)
    α_ref = {−c2 z2 + g − g v_z²/(2v_T²) − L0* − c1 v_z (1 − tanh² z1)
             − (k1/k3)(k2² − z2²)Φ(z1)} / Lα*                                      (5.47)
    then steps 3–4 of :class:`~cpbc.backstepping.altitude_law.AltitudeLaw` with the coupling
    k3 Lα* z2/(k2² − z2²) in q_ref (5.54).

V = V2 + ½z3² + ½z4², V̇ = −k1c1 Φ tanh z1 − k3c2 z2²/(k2² − z2²) − c3z3² − c4z4² (5.63), so
|z2| < k2 and |v_z| < k2 + c1 (5.68); Theorem 5.5 asks c1 + k2 ≤ B and k2 > c1. (5.43) prints
g v_z²/v_T²: read g v_z²/(2v_T²) as in (5.47).

Theorem 5.5 assumes |v_z(0)| < B; the barrier needs |z2(0)| < k2, and every new command h_d
re-initialises z1. :meth:`ConstrainedAltitudeLaw.admissible` is that check (PART1 Ch. 5 §3.3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from scipy.optimize import brentq

from cpbc.backstepping.altitude_law import AltitudeLaw, OuterSteps
from cpbc.backstepping.altitude_model import AltitudeModel
from cpbc.backstepping.barrier_terms import positive
from cpbc.backstepping.design_errors import DesignError, OutsideDomainError
from cpbc.backstepping.jets import Jet, log, tanh


@dataclass(frozen=True)
class ConstrainedAltitudeGains:
    """c1 … c4, k1 … k3 of §5.4.3 (all > 0, k2 > c1)."""

    c1: float = 1.5
    c2: float = 1.0
    c3: float = 5.0
    c4: float = 10.0
    k1: float = 1.5
    k2: float = 2.0
    k3: float = 0.5

    def __post_init__(self) -> None:
        for name in ("c1", "c2", "c3", "c4", "k1", "k2", "k3"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))
        if not self.k2 > self.c1:
            raise DesignError("k2", self.k2, f"Theorem 5.5 needs k2 > c1 = {self.c1:g}")

    @property
    def climb_rate_bound(self) -> float:
        """k2 + c1, the bound on |v_z| (5.68)."""
        return self.k2 + self.c1


def _atanh(v: float) -> float:
    return math.copysign(math.inf, v) if abs(v) >= 1.0 else math.atanh(v)


class ConstrainedAltitudeLaw(AltitudeLaw):
    """(5.61) for the design model ``model``; raises :class:`OutsideDomainError` at |z2| ≥ k2."""

    def __init__(self, model: AltitudeModel,
                 gains: ConstrainedAltitudeGains | None = None) -> None:
        self.gains = gains or ConstrainedAltitudeGains()
        super().__init__(model, self.gains.c3, self.gains.c4)

    def command_interval(self, x: Sequence[float]) -> tuple[float, float]:
        """The h_d with |v_z + c1 tanh(h − h_d)| < k2 at x: tanh(h − h_d) must lie in
        ((−k2 − v_z)/c1, (k2 − v_z)/c1) ∩ (−1, 1); empty (+∞, −∞) once |v_z| ≥ k2 + c1."""
        g = self.gains
        h, vz = float(x[0]), float(x[1])
        lo, hi = max(-1.0, (-g.k2 - vz) / g.c1), min(1.0, (g.k2 - vz) / g.c1)
        if lo >= hi:
            return math.inf, -math.inf
        return h - _atanh(hi), h - _atanh(lo)

    def outer(self, h: Jet, vz: Jet, command: float) -> OuterSteps:
        m, g = self.model, self.gains
        z1 = h - command
        t = tanh(z1)
        z2 = vz + g.c1 * t
        if not abs(z2.value) < g.k2:
            raise OutsideDomainError("z2", float(z2.value), -g.k2, g.k2,
                                     "the log barrier (5.44) of the climb-rate error")
        room = g.k2 * g.k2 - z2 * z2  # k2² − z2² > 0
        phi = t + z1 * (1.0 - t * t)
        alpha_ref = (-g.c2 * z2 - (g.k1 / g.k3) * room * phi - g.c1 * vz * (1.0 - t * t)
                     - m.climb_acceleration(vz, 0.0)) / m.l_alpha  # (5.47)
        return OuterSteps(z1, z2, alpha_ref, g.k3 * m.l_alpha * z2 / room)

    def climb_plateau(self) -> float:
        """The climb rate [m/s] the closed loop of (5.3) holds far below the command.

        For h − h_d → −∞, tanh z1 → −1 and Φ → −1, so v_zref = c1 and the (z2, z3, z4) loop
        has a quasi-steady point while z1 drifts: ż4 = 0 gives z4 = −z3/c4, ż3 = 0 gives
        z3 = −κ z2/(c3 + 1/c4) with κ = k3 Lα*/(k2² − z2²), and ż2 = 0 leaves

            −c2 z2 + (k1/k3)(k2² − z2²) − Lα* κ z2/(c3 + 1/c4) = 0,

        decreasing in z2 on [0, k2) from (k1/k3)k2² > 0 to −∞: one root, and v_z = c1 + z2.
        The plateau sits near the bound k2 + c1 only when the barrier's pull (k1/k3)k2²
        outweighs the α-loop's coupling Lα*² k3/(k2²(c3 + 1/c4)), i.e. for a small k3.
        (The descent is the mirror image: −c1 − z2.)
        """
        g, la = self.gains, self.model.l_alpha
        k22 = g.k2 * g.k2

        def balance(z2: float) -> float:
            room = k22 - z2 * z2
            return (-g.c2 * z2 + (g.k1 / g.k3) * room
                    - la * la * g.k3 * z2 / (room * (g.c3 + 1.0 / g.c4)))

        return g.c1 + float(brentq(balance, 0.0, g.k2 * (1.0 - 1e-12), xtol=1e-14))

    def lyapunov(self, x: Sequence[float], command: float) -> tuple[float, float]:
        g = self.gains
        z1, z2, z3, z4 = self.terms(x, command).z
        t = float(tanh(z1))
        phi = t + z1 * (1.0 - t * t)
        room = g.k2 * g.k2 - z2 * z2
        v = (g.k1 * z1 * t + 0.5 * g.k3 * float(log(g.k2 * g.k2 / room))
             + 0.5 * (z3 * z3 + z4 * z4))  # (5.62)
        w = g.k1 * g.c1 * phi * t + g.k3 * g.c2 * z2 * z2 / room + g.c3 * z3 * z3 + g.c4 * z4 * z4
        return v, -w  # (5.63)
