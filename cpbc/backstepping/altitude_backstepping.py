"""§5.3: the traditional backstepping altitude controller of the Aerosonde (5.4)–(5.30).

    z1 = h − h_d                                                           (5.4)
    z2 = v_z + c1 z1            (v_zref = −c1 z1)                          (5.8), (5.9)
    α_ref = [−c2 z2 − z1 + g − g v_z²/(2v_T²) − L0* − c1 v_z] / Lα*        (5.15)
    then steps 3–4 of :class:`~cpbc.backstepping.altitude_law.AltitudeLaw` with the coupling
    Lα* z2 in q_ref (5.22).

Closed loop on (5.3): ż1 = −c1z1 + z2, ż2 = −c2z2 − z1 + Lα* z3, ż3 = −c3z3 − Lα* z2 + z4,
ż4 = −c4z4 − z3; V = ½Σz_i², V̇ = −Σc_i z_i² (5.31)–(5.32). Nothing bounds v_z or α: the
virtual controls grow with the altitude error, which is what stalls the aircraft in Fig. 5.3.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from cpbc.backstepping.altitude_law import AltitudeLaw, OuterSteps
from cpbc.backstepping.altitude_model import AltitudeModel
from cpbc.backstepping.barrier_terms import positive
from cpbc.backstepping.jets import Jet


@dataclass(frozen=True)
class TraditionalAltitudeGains:
    """c1 … c4 of §5.3.1 (all > 0)."""

    c1: float = 1.5
    c2: float = 10.0
    c3: float = 5.0
    c4: float = 0.1

    def __post_init__(self) -> None:
        for name in ("c1", "c2", "c3", "c4"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))


class TraditionalAltitudeLaw(AltitudeLaw):
    """(5.30) for the design model ``model``."""

    def __init__(self, model: AltitudeModel, gains: TraditionalAltitudeGains | None = None) -> None:
        self.gains = gains or TraditionalAltitudeGains()
        super().__init__(model, self.gains.c3, self.gains.c4)

    def outer(self, h: Jet, vz: Jet, command: float) -> OuterSteps:
        m, c1, c2 = self.model, self.gains.c1, self.gains.c2
        z1 = h - command
        z2 = vz + c1 * z1
        alpha_ref = (-c2 * z2 - z1 - c1 * vz - m.climb_acceleration(vz, 0.0)) / m.l_alpha  # (5.15)
        return OuterSteps(z1, z2, alpha_ref, m.l_alpha * z2)

    def lyapunov(self, x: Sequence[float], command: float) -> tuple[float, float]:
        z = self.terms(x, command).z
        g = self.gains
        c = (g.c1, g.c2, g.c3, g.c4)
        return 0.5 * sum(v * v for v in z), -sum(ci * v * v for ci, v in zip(c, z, strict=True))
