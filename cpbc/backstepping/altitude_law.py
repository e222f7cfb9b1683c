"""Steps 3 and 4 of both altitude controllers of Chapter 5, (5.16)–(5.30) and (5.54)–(5.61).

The traditional law (§5.3) and the constrained law (§5.4) differ only in their first two
steps: the error z2, the virtual control α_ref(h, v_z) and the term by which z2 enters q_ref
(Lα* z2 for the quadratic storage ½z2², k3 Lα* z2/(k2² − z2²) for the log barrier). The last
two steps are common:

    z3 = α − α_ref                                                          (5.16)
    q_ref = −c3 z3 − [z2 coupling] − g/v_T + g v_z²/(2v_T³) + L0' + Lα' α + α̇_ref   (5.22)/(5.54)
    z4 = q − q_ref                                                          (5.23)
    δ_E = (−c4 z4 − z3 − Mq' q − Mα' α − M0' + q̇_ref) / Mδ'                (5.30)/(5.61)

(5.30) prints −z3 twice; (5.31) confirms one (PART1 Ch. 5 §3.2). α̇_ref and q̇_ref are exact
time derivatives along the design model (5.3), from Taylor jets (never finite differences).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

from cpbc.backstepping.altitude_model import AltitudeModel
from cpbc.backstepping.barrier_terms import positive
from cpbc.backstepping.jets import Jet, as_jet

State = tuple[float, ...]


@dataclass(frozen=True)
class OuterSteps:
    """Steps 1–2 on jets: z1, z2, α_ref (order 2 along (5.3)) and z2's term in q_ref."""

    z1: Jet
    z2: Jet
    alpha_ref: Jet
    coupling: Jet


@dataclass(frozen=True)
class AltitudeTerms:
    """The errors, virtual controls and elevator at one state."""

    z: tuple[float, float, float, float]
    alpha_ref: float
    alpha_ref_dot: float
    q_ref: float
    q_ref_dot: float
    elevator: float  # δ_E [rad], unsaturated


class AltitudeLaw(ABC):
    """δ_E = k(x; h_d) for the design state x = (h [m], v_z [m/s], α [rad], q [rad/s], …)
    (components after the 4th are ignored: a plant may carry more).

    Args:
        model: the design model (5.3).
        c3, c4: gains of steps 3 and 4.
    """

    def __init__(self, model: AltitudeModel, c3: float, c4: float) -> None:
        self.model = model
        self.c3 = positive("c3", c3)
        self.c4 = positive("c4", c4)

    @abstractmethod
    def outer(self, h: Jet, vz: Jet, command: float) -> OuterSteps:
        """Steps 1–2 on the jets of h and v_z (order 2)."""

    def command_interval(self, x: Sequence[float]) -> tuple[float, float]:
        """The open interval of altitude commands h_d [m] for which the law is defined at x
        (every command, unless the law has a barrier)."""
        return -math.inf, math.inf

    def admissible(self, x: Sequence[float], command: float) -> bool:
        """Whether the law is defined at x for the altitude command h_d."""
        lo, hi = self.command_interval(x)
        return lo < command < hi

    def terms(self, x: Sequence[float], command: float) -> AltitudeTerms:
        """Every step at x for the command h_d [m]."""
        m = self.model
        h, vz, alpha, q = (float(v) for v in x[:4])
        hj, vzj, aj = m.jets((h, vz, alpha, q))
        outer = self.outer(hj, vzj, command)
        z3 = aj - outer.alpha_ref
        q_ref = (-self.c3 * z3 - outer.coupling - as_jet(m.alpha_rate(vzj, aj, 0.0), 1)
                 + outer.alpha_ref.dot())  # (5.22)/(5.54), order 1
        z4 = q - q_ref.value
        z3v = float(z3.value)
        elevator = (-self.c4 * z4 - z3v - m.m_q * q - m.m_alpha * alpha - m.m0
                    + q_ref.derivative(1)) / m.m_elevator  # (5.30)/(5.61)
        return AltitudeTerms(
            (float(outer.z1.value), float(outer.z2.value), z3v, float(z4)),
            float(outer.alpha_ref.value), float(outer.alpha_ref.derivative(1)),
            float(q_ref.value), float(q_ref.derivative(1)), float(elevator))

    def elevator(self, x: Sequence[float], command: float) -> float:
        """δ_E [rad] at x for h_d = ``command`` [m]."""
        return self.terms(x, command).elevator

    @abstractmethod
    def lyapunov(self, x: Sequence[float], command: float) -> tuple[float, float]:
        """V and its derivative along the closed loop of the design model, −W ≤ 0
        ((5.31)/(5.63)), at x."""
