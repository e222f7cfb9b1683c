"""§5.2: the longitudinal design model of the Aerosonde's altitude dynamics (5.3).

From Stevens & Lewis's (5.1) under Assumptions 5.1–5.4 (small γ, constant v_T held by a
separate loop, F_T sin α neglected, L = L0 + L_α α, M = M0 + M_α α + M_q q + M_δE δE), with
v_z = v_T γ:

    ḣ   = v_z                                                           (5.3a)
    v̇_z = −g + g v_z²/(2 v_T²) + L0* + Lα* α                            (5.3b)
    α̇   = g/v_T − g v_z²/(2 v_T³) − L0' − Lα' α + q                      (5.3c)
    q̇   = M0' + Mα' α + Mq' q + Mδ' δ_E                                  (5.3d)

(5.3c) as printed reads ``2/(2v_T³)``: read g/(2v_T³) (PART1 Ch. 5 §3.1). The lumped constants
come from the aircraft's coefficients at one flight condition (v_T, ρ, m): the thesis does not
say which ρ and mass it used, so both are parameters here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import positive
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.jets import Coef, Jet, coefficient
from cpbc.backstepping.strict_feedback import Value


@dataclass(frozen=True)
class AltitudeModel:
    """The constants of (5.3) [SI]: L0* = L0/m, Lα* = Lα/m, L0' = L0/(m v_T), …, Mδ' = M_δE/I_yy."""

    airspeed: float  # v_T [m/s]
    l0: float  # L0* [m/s²]
    l_alpha: float  # Lα* [m/s²/rad]
    m0: float  # M0' [rad/s²]
    m_alpha: float  # Mα' [1/s²]
    m_q: float  # Mq' [1/s]
    m_elevator: float  # Mδ' [1/s²]
    g: float = 9.81

    def __post_init__(self) -> None:
        positive("v_T", self.airspeed)
        positive("L_alpha*", self.l_alpha)
        if self.m_elevator == 0.0:
            raise DesignError("M_delta'", 0.0, "must not vanish: the elevator must act on q")

    @classmethod
    def from_coefficients(
        cls, *, airspeed: float, rho: float, mass: float, iyy: float, wing_area: float,
        chord: float, cl0: float, cl_alpha: float, cm0: float, cm_alpha: float, cm_q: float,
        cm_elevator: float, g: float = 9.81,
    ) -> AltitudeModel:
        """The lumped constants of §5.2 from the coefficients at (v_T, ρ, m)."""
        for name, value in (("rho", rho), ("mass", mass), ("Iyy", iyy)):
            positive(name, value)
        qs = 0.5 * rho * airspeed**2 * wing_area  # q̄S
        return cls(
            airspeed=airspeed,
            l0=qs * cl0 / mass,
            l_alpha=qs * cl_alpha / mass,
            m0=qs * chord * cm0 / iyy,
            m_alpha=qs * chord * cm_alpha / iyy,
            m_q=qs * chord * chord * cm_q / (2.0 * airspeed) / iyy,
            m_elevator=qs * chord * cm_elevator / iyy,
            g=g,
        )

    @property
    def l0_prime(self) -> float:
        """L0' = L0*/v_T [rad/s]."""
        return self.l0 / self.airspeed

    @property
    def l_alpha_prime(self) -> float:
        """Lα' = Lα*/v_T [1/s]."""
        return self.l_alpha / self.airspeed

    def climb_acceleration(self, vz: Value, alpha: Value) -> Value:
        """v̇_z of (5.3b)."""
        g, v = self.g, self.airspeed
        return -g + g * vz * vz / (2.0 * v * v) + self.l0 + self.l_alpha * alpha

    def alpha_rate(self, vz: Value, alpha: Value, q: Value) -> Value:
        """α̇ of (5.3c)."""
        g, v = self.g, self.airspeed
        return g / v - g * vz * vz / (2.0 * v**3) - self.l0_prime - self.l_alpha_prime * alpha + q

    def pitch_acceleration(self, alpha: float, q: float, elevator: float) -> float:
        """q̇ of (5.3d)."""
        return self.m0 + self.m_alpha * alpha + self.m_q * q + self.m_elevator * elevator

    def rhs(self, x: Sequence[float], elevator: float) -> tuple[float, float, float, float]:
        """(ḣ, v̇_z, α̇, q̇) of (5.3) at x = (h, v_z, α, q)."""
        _, vz, alpha, q = x
        return (vz, float(self.climb_acceleration(vz, alpha)),
                float(self.alpha_rate(vz, alpha, q)),
                self.pitch_acceleration(alpha, q, elevator))

    def trim(self) -> tuple[float, float]:
        """(α0, δ_E0) of level flight: α0 = (g − L0*)/Lα* (5.26), q̇ = 0 at q = 0."""
        alpha0 = (self.g - self.l0) / self.l_alpha
        return alpha0, -(self.m0 + self.m_alpha * alpha0) / self.m_elevator

    def jets(self, x: Sequence[Coef]) -> tuple[Jet, Jet, Jet]:
        """Taylor jets of h, v_z (order 2) and α (order 1) along (5.3) from x = (h, v_z, α, q).

        These orders are exactly what the laws read: α_ref(h, v_z) to its 2nd derivative
        (α̇_ref enters q_ref, whose derivative enters δ_E) and α to its 1st; q̇, which holds δ_E,
        is never needed (Picard's recursion, as in :func:`nominal_jets`).
        """
        h, vz, alpha, q = x
        a1 = self.alpha_rate(vz, alpha, q)
        v1 = self.climb_acceleration(vz, alpha)
        v2 = coefficient(self.climb_acceleration(Jet([vz, v1]), Jet([alpha, a1])), 1) / 2.0
        return Jet([h, vz, v1 / 2.0]), Jet([vz, v1, v2]), Jet([alpha, a1])
